// examples/cli_device.hpp — the OpenCL commands of the raykit command line.
//
// Include from the CLI's single translation unit when it is built with the
// raykit::cl target (e.g. `#if __has_include(<CL/opencl.hpp>)` or a
// RAYKIT_HAVE_CL definition set by CMake). All functions throw on errors:
// raykit::cl::NoDeviceError (no OpenCL platform/device; the message says what
// to install), raykit::cl::Error (an OpenCL call failed, named with its
// CL_... code), std::invalid_argument for bad arguments.
//
//   void raykit_cli_print_devices();
//       Every platform and device (index "P:D", type, versions, compute units,
//       memory, fp64), then the device raykit picks and why (RAYKIT_CL_DEVICE,
//       first GPU, or PoCL's CPU device). Throws NoDeviceError when there is
//       none, after printing what it found.
//
//   std::vector<raykit::Hit> raykit_cli_trace_device(mesh, bvh, rays, any_hit);
//       Traces on the chosen device (raykit::cl::MeshTracer). Closest hit: the
//       same Hit as raykit::intersect_closest (inst 0 on a hit). Any hit: one
//       Hit per ray whose `prim` is 1 (occluded) or 0 (free); t = inf,
//       u = v = 0, inst = kInvalidIndex.
//
//   int raykit_cli_animate_test(mesh, frames);
//       A dynamic copy of the mesh moved each frame by the built-in "wave"
//       vertex hook (raykit::cl::WaveHook), one instance, 512x512 camera rays.
//       Per frame, on the device and on the CPU twin (all hardware threads):
//       vertex ms, refit ms (device: one-pass), TLAS ms, trace Mrays/s, and
//       how many rays the two agree on (same triangle, or both miss; the
//       hook's sin/cos differ by an ulp or so between OpenCL and libm, so a
//       few rays at silhouettes may differ). Returns 0.
#pragma once

#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/cl.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/scene.hpp"

inline void raykit_cli_print_devices() {
    namespace rcl = raykit::cl;
    std::vector<rcl::DeviceInfo> devices;
    try {
        devices = rcl::list_devices();
    } catch (const rcl::NoDeviceError& e) {
        std::printf("no OpenCL platform\n");
        throw;
    }
    unsigned last_platform = ~0u;
    for (const rcl::DeviceInfo& d : devices) {
        if (d.platform_index != last_platform) {
            std::printf("platform %u: %s (%s)\n", d.platform_index, d.platform_name.c_str(), d.platform_version.c_str());
            last_platform = d.platform_index;
        }
        std::printf("  device %u:%u  %s  [%s]\n", d.platform_index, d.device_index, d.name.c_str(), d.type_name());
        std::printf("      vendor %s, %s, %s, %u compute units, %.1f GiB, fp64 %s, correctly rounded divide/sqrt %s\n",
                    d.vendor.c_str(), d.version.c_str(), d.opencl_c_version.c_str(), d.compute_units,
                    double(d.global_memory) / double(1ull << 30), d.fp64 ? "yes" : "no",
                    d.correctly_rounded_divide_sqrt ? "yes" : "no");
    }
    const char* env = std::getenv("RAYKIT_CL_DEVICE");
    std::printf("RAYKIT_CL_DEVICE=%s\n", env && *env ? env : "(not set)");
    const rcl::DeviceChoice c = rcl::choose_device(devices, "");
    std::printf("chosen: %s\n  because: %s\n", c.info.label().c_str(), c.reason.c_str());
}

inline std::vector<raykit::Hit> raykit_cli_trace_device(const raykit::Mesh& mesh, const raykit::Bvh& bvh,
                                                        const std::vector<raykit::Ray>& rays, bool any_hit) {
    namespace rcl = raykit::cl;
    rcl::MeshTracer tracer(rcl::Device::shared(), mesh, bvh);
    if (!any_hit) return tracer.closest(rays);
    const std::vector<std::uint32_t> occ = tracer.any(rays);
    std::vector<raykit::Hit> out(rays.size());
    for (std::size_t i = 0; i < rays.size(); ++i) out[i].prim = occ[i] ? 1u : 0u;
    return out;
}

inline int raykit_cli_animate_test(const raykit::Mesh& mesh, int frames) {
    namespace rcl = raykit::cl;
    using clock = std::chrono::steady_clock;
    auto ms_since = [](clock::time_point t0) { return std::chrono::duration<double, std::milli>(clock::now() - t0).count(); };
    if (frames < 1) throw std::invalid_argument("animate test: frames must be at least 1");
    if (mesh.triangles.empty()) throw std::invalid_argument("animate test: the mesh has no triangles");

    rcl::Device& dev = rcl::Device::shared();
    std::printf("device: %s (%s)\n", dev.info().label().c_str(), dev.reason().c_str());

    // the same scene twice: one for the device, one for the CPU twin
    raykit::Scene dscene, cscene;
    for (raykit::Scene* s : {&dscene, &cscene}) {
        s->add_object(mesh, raykit::ObjectKind::dynamic);
        s->add_instance(0);
        s->update_top_level();
    }
    raykit::AABB box = dscene.world_box(0);
    const float diag = glm::length(box.max - box.min);
    rcl::WaveHook::Params p;
    p.amplitude = 0.02f * diag;
    p.frequency = 4.0f * 3.14159265f / std::max(diag, 1e-20f);
    box.grow(box.max + raykit::vec3(p.amplitude));
    box.grow(box.min - raykit::vec3(p.amplitude));
    const raykit::Camera cam = raykit::camera_looking_at(box, 512, 512);
    const raykit::CameraFrame cf = cam.frame();
    const std::size_t nrays = std::size_t(cf.width) * cf.height;

    auto t0 = clock::now();
    rcl::DeviceScene<rcl::WaveHook> ds(dev, dscene);
    ds.set_hook<rcl::WaveHook>(0, p);
    ds.update();
    std::printf("setup: upload + program %.1f ms (clBuildProgram %.1f ms%s)\n", ms_since(t0), ds.program().build_ms(),
                ds.program().cached() ? ", cached" : "");
    rcl::Buffer<raykit::Ray> rays(dev, nrays);
    rcl::Buffer<raykit::Hit> hits(dev, nrays);
    ds.camera_rays(cf, rays);  // first launches compile the kernels (PoCL): keep them out of frame 0
    ds.closest(rays, hits, nrays);
    dev.finish();

    std::vector<raykit::Hit> chits(nrays);
    std::printf("%zu triangles, %zu camera rays per frame\n", mesh.triangles.size(), nrays);
    for (int f = 0; f < frames; ++f) {
        p.time = 0.25f * float(f);
        // device
        ds.set_hook<rcl::WaveHook>(0, p);
        const rcl::FrameTimes ft = ds.update(rcl::RefitMethod::one_pass);
        t0 = clock::now();
        ds.camera_rays(cf, rays);
        ds.closest(rays, hits, nrays);
        dev.finish();
        const double dtrace = ms_since(t0);
        const std::vector<raykit::Hit> dh = hits.read(dev);
        // CPU twin
        t0 = clock::now();
        cscene.move_vertices(0, [&](const raykit::Vertex& v, std::uint32_t i) { return rcl::WaveHook::apply(v, i, p); });
        const double cmove = ms_since(t0);
        t0 = clock::now();
        cscene.refit_object(0);  // once more, alone, to time the refit part of move_vertices
        const double crefit = ms_since(t0);
        t0 = clock::now();
        cscene.update_top_level();
        const double ctlas = ms_since(t0);
        t0 = clock::now();
        raykit::parallel_for(nrays, 0, [&](std::size_t i) {
            chits[i] = cscene.intersect_closest(cf.ray(std::uint32_t(i % cf.width), std::uint32_t(i / cf.width)));
        });
        const double ctrace = ms_since(t0);
        std::size_t agree = 0;
        for (std::size_t i = 0; i < nrays; ++i) agree += dh[i].prim == chits[i].prim && dh[i].inst == chits[i].inst;
        std::printf("frame %d: device vertex %.2f ms, refit %.2f ms, TLAS %.2f ms, trace %.2f Mrays/s | cpu vertex "
                    "%.2f ms, refit %.2f ms, TLAS %.2f ms, trace %.2f Mrays/s | same answer on %zu of %zu rays\n",
                    f, ft.vertex_ms, ft.refit_ms, ft.top_level_ms, double(nrays) * 1e-3 / dtrace,
                    std::max(0.0, cmove - crefit), crefit, ctlas, double(nrays) * 1e-3 / ctrace, agree, nrays);
    }
    const rcl::LaunchCounts& lc = ds.launches();
    std::printf("device launches: vertex %zu, refit %zu, top level %zu, camera %zu, trace %zu\n", lc.vertex, lc.refit,
                lc.top_level, lc.camera, lc.trace);
    return 0;
}
