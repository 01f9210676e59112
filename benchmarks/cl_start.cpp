// benchmarks/cl_start.cpp — how long a new process takes to its first traced ray and its first
// rendered frame on the OpenCL device (a short-lived tool pays this once per run).
//
//   build/release/benchmarks/cl_start                          # PoCL's kernel cache as it is
//   POCL_CACHE_DIR=$(mktemp -d) build/release/benchmarks/cl_start   # cold: nothing cached
//
// Prints the stages since main() started: device (platform and context), trace (the mesh
// tracer's program build and the first launch of one ray), render (the renderer's programs and
// a 64 x 48 Whitted frame), and the total. raykit caches programs per process
// (cl/program.hpp); across processes PoCL's own on-disk cache (POCL_KERNEL_CACHE, on by
// default) keeps the compiled kernels, keyed by source and options, which raykit keeps
// identical from run to run.
#include <chrono>
#include <cstdio>
#include <vector>

#include "raykit/cl.hpp"

int main() {
    using namespace raykit;
    using Clock = std::chrono::steady_clock;
    const auto t0 = Clock::now();
    const auto ms = [&] { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); };
    const Mesh mesh = make_icosphere(2);
    const Bvh bvh = build_bvh(mesh);
    RenderScene rs = prepare_render_scene(mesh);
    const Camera cam = frame_scene(rs.bounds(), 64, 48);
    rs.lights.push_back(default_key_light(cam));
    const double t_setup = ms();
    try {
        raykit::cl::Device& dev = raykit::cl::Device::shared();
        const double t_dev = ms();
        raykit::cl::MeshTracer tracer(dev, mesh, bvh);
        const std::vector<Ray> one{Ray{{0.01f, 0.02f, -5.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, kInf}};
        const std::vector<Hit> hit = tracer.closest(one);
        const double t_ray = ms();
        raykit::cl::DeviceRenderer renderer(dev, rs.view());
        const Image img = renderer.render(cam, RenderSettings{});
        const double t_frame = ms();
        std::printf("setup %.0f ms, device %.0f ms, first ray %.0f ms (prim %u), first frame %.0f ms (%ux%u); "
                    "total to first ray %.0f ms, to first frame %.0f ms\n",
                    t_setup, t_dev - t_setup, t_ray - t_dev, hit[0].prim, t_frame - t_ray, img.width, img.height,
                    t_ray, t_frame);
    } catch (const std::exception& e) {
        std::printf("no OpenCL device: %s\n", e.what());
    }
}
