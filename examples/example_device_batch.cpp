// example_device_batch: trace a batch of rays on the OpenCL device.
//
//   example_device_batch [MESH.obj]
//
// raykit::cl::MeshTracer uploads a mesh's tree in the device's form (the 8-wide tree over
// 4-triangle blocks the CPU walks too) and traces batches of rays, one work item per ray:
// closest hits and any hits of rays made on the host, and camera rays made on the device that
// never leave it. The CPU is the oracle: on a device with doubles (cl_khr_fp64; PoCL is one) the
// device runs the CPU's arithmetic in the CPU's order, so every hit must equal the CPU's bit
// for bit (t, u, v, triangle). Exits 1 when one differs, 77 when there is no OpenCL device.
#include <bit>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include <raykit.hpp>
#include <raykit/cl.hpp>

int main(int argc, char** argv) {
    using namespace raykit;
    raykit::cl::Device* dev = nullptr;
    try {
        dev = &raykit::cl::Device::shared();  // RAYKIT_CL_DEVICE picks another (see `raykit info --device`)
    } catch (const raykit::cl::NoDeviceError& e) {
        std::printf("no OpenCL device: %s\n", e.what());
        return 77;
    }
    const Mesh mesh = argc > 1 ? load_obj(argv[1]) : make_bumpy_torus(20000);
    const Bvh bvh = build_bvh(mesh);                        // any builder's tree will do
    raykit::cl::MeshTracer tracer(*dev, mesh, bvh);          // compiles the kernels (cached), uploads the tree
    const BlockBvh8 cpu_tree = BlockBvh8::build(mesh, bvh);  // the CPU's twin of what the device walks

    // Host-made rays: from a sphere around the mesh toward random points of its box, every
    // fourth one aimed exactly at a vertex (where triangles meet: ties, the hard case).
    const AABB box = mesh.bounds();
    const float radius = glm::length(box.max - box.min);
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> u01(0.0f, 1.0f);
    std::vector<Ray> rays(20000);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const vec3 from = box.center() + radius * glm::normalize(vec3(u01(rng), u01(rng), u01(rng)) - 0.5f);
        const vec3 to = i % 4 == 1 ? mesh.positions[std::size_t(u01(rng) * float(mesh.positions.size() - 1))]
                                   : box.min + vec3(u01(rng), u01(rng), u01(rng)) * (box.max - box.min);
        rays[i] = Ray{from, 0.0f, to - from, i % 2 ? kInf : 0.999f};  // odd: unbounded; even: stop short of the point
    }
    const std::vector<Hit> hits = tracer.closest(rays);              // upload, trace, download
    const std::vector<std::uint32_t> blocked = tracer.any(rays);     // 1 = something in [tmin, tmax]

    // Camera rays made on the device and traced there: only the hits come back.
    const Camera cam = camera_looking_at(box, 256, 192);
    const std::size_t n = std::size_t(cam.width) * cam.height;
    raykit::cl::Buffer<Ray> cam_rays;
    raykit::cl::Buffer<Hit> cam_hits;
    tracer.camera_rays(cam.frame(), cam_rays);  // bit-identical to camera_rays(cam) on the CPU
    tracer.closest(cam_rays, cam_hits, n);      // queued after it; nothing waits yet
    const std::vector<Hit> cam_result = cam_hits.read(*dev);

    // The oracle: the same queries on the CPU.
    const bool exact = dev->info().fp64;
    auto same = [&](const Hit& d, const Hit& c) {
        if (exact)
            return d.prim == c.prim && std::bit_cast<std::uint32_t>(d.t) == std::bit_cast<std::uint32_t>(c.t) &&
                   std::bit_cast<std::uint32_t>(d.u) == std::bit_cast<std::uint32_t>(c.u) &&
                   std::bit_cast<std::uint32_t>(d.v) == std::bit_cast<std::uint32_t>(c.v);
        // float edge functions: a tie at a shared edge may go to the neighbour, t may differ in the last bits
        return d.prim == c.prim || std::fabs(d.t - c.t) <= 1e-5f * c.t;
    };
    std::size_t closest_wrong = 0, any_wrong = 0, camera_wrong = 0, hit_count = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit c = intersect_closest(cpu_tree, rays[i]);
        closest_wrong += !same(hits[i], c);
        any_wrong += blocked[i] != std::uint32_t(intersect_any(cpu_tree, rays[i]));
        hit_count += c.valid();
    }
    const std::vector<Ray> cpu_cam = camera_rays(cam);
    std::size_t camera_hits = 0;
    for (std::size_t i = 0; i < n; ++i) {
        const Hit c = intersect_closest(cpu_tree, cpu_cam[i]);
        camera_wrong += !same(cam_result[i], c);
        camera_hits += c.valid();
    }

    std::printf("device: %s (%s)\n", dev->info().label().c_str(),
                exact ? "has doubles: hits must equal the CPU's bit for bit" : "no doubles: hits compared with tolerance");
    std::printf("%zu triangles; %zu host rays (%zu hit): %zu closest and %zu any-hit answers differ from the CPU\n",
                mesh.triangle_count(), rays.size(), hit_count, closest_wrong, any_wrong);
    std::printf("%zu camera rays made on the device (%zu hit): %zu differ from the CPU\n", n, camera_hits, camera_wrong);
    const bool ok = closest_wrong == 0 && any_wrong == 0 && camera_wrong == 0 && hit_count > 0 && camera_hits > 0;
    if (!ok) std::printf("FAILED\n");
    return ok ? 0 : 1;
}
