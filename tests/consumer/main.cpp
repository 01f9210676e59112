// What the README's "Using it" shows, as a consumer builds it: make (or load) a mesh, build
// the fast tree, trace one ray, trace a batch of camera rays, render and write a PNG. Every
// answer is checked against brute force, so the program fails (exit 1) when raykit is wrong.
// Built through find_package and add_subdirectory, the latter with raykit's strict warning set,
// and once more with -march=native: both builds print one hash of their answers on the same
// exactly representable rays and mesh, which tests/CMakeLists.txt's package_default_vs_native
// compares (a default build dispatches to the CPU's vector level and fuses as a native one does).
#include <bit>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <vector>

#include <raykit.hpp>

namespace {

/// A hash of every answer (prim, t, u, v bits; any-hit) on a jittered height field and rays whose
/// coordinates are small integers over powers of two: inputs no compiler flag can change.
std::uint64_t answer_hash() {
    using namespace raykit;
    std::uint64_t state = 12345;
    const auto next = [&state](int range) {  // a fixed LCG: the same numbers everywhere
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return int((state >> 33) % std::uint64_t(2 * range + 1)) - range;
    };
    Mesh m;
    const int n = 96;
    for (int z = 0; z <= n; ++z)
        for (int x = 0; x <= n; ++x) {
            const float jx = float(next(64)), jy = float(next(4096)), jz = float(next(64));
            m.positions.emplace_back(float(x * 64 + int(jx)) / 1024.0f, jy / 2048.0f, float(z * 64 + int(jz)) / 1024.0f);
        }
    for (int z = 0; z < n; ++z)
        for (int x = 0; x < n; ++x) {
            const auto a = std::uint32_t(z * (n + 1) + x), b = a + 1, c = a + std::uint32_t(n) + 1, d = c + 1;
            m.triangles.push_back(Triangle{{a, b, c}});
            m.triangles.push_back(Triangle{{b, d, c}});
        }
    const BlockBvh8 tree = BlockBvh8::build(m);
    std::vector<Ray> rays;
    for (int i = 0; i < 20000; ++i) {
        const float ox = float(next(1024)) / 128.0f, oy = 2.0f + float(next(512)) / 512.0f, oz = float(next(1024)) / 128.0f;
        const float dx = float(next(256)), dy = float(next(256) - 512), dz = float(next(256));
        rays.push_back(Ray{{ox + 3.0f, oy, oz + 3.0f}, 0.0f, {dx / 256.0f, dy / 256.0f, dz / 256.0f}, kInf});
    }
    std::vector<Hit> hits(rays.size());
    std::vector<std::uint8_t> occluded(rays.size());
    intersect_closest(tree, rays, hits);
    intersect_any(tree, rays, occluded);
    std::uint64_t h = 1469598103934665603ull;
    const auto mix = [&h](std::uint32_t w) { h = (h ^ w) * 1099511628211ull; };
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit one = intersect_closest(tree, rays[i]);
        for (const Hit& x : {hits[i], one}) {
            mix(x.prim);
            mix(std::bit_cast<std::uint32_t>(x.t));
            mix(std::bit_cast<std::uint32_t>(x.u));
            mix(std::bit_cast<std::uint32_t>(x.v));
        }
        mix(occluded[i]);
    }
    return h;
}

}  // namespace

int main(int argc, char** argv) {
    using namespace raykit;
    std::printf("answers %016llx (vector level %s)\n", static_cast<unsigned long long>(answer_hash()),
                isa_name(active_isa()));
    const Mesh mesh = argc > 1 ? load_obj(argv[1]) : make_icosphere(3);  // or any OBJ file
    const BlockBvh8 tree = BlockBvh8::build(mesh);                       // the CPU's fastest tree

    // one ray
    const Ray ray{{0.01f, 0.02f, -5.0f}, 0.0f, {0.0f, 0.0f, 1.0f}, kInf};
    const Hit one = intersect_closest(tree, ray);
    bool ok = one.valid() && one.prim == brute_force_closest(mesh, ray).prim;

    // a batch: one camera ray per pixel, traced as packets on all cores
    Camera cam = frame_scene(mesh.bounds(), 64, 48);
    const std::vector<Ray> rays = camera_rays(cam);
    std::vector<Hit> hits(rays.size());
    intersect_closest(tree, rays, hits);
    std::size_t hit_count = 0, wrong = 0;
    for (std::size_t i = 0; i < rays.size(); i += 7) {  // every 7th ray against brute force
        const Hit b = brute_force_closest(mesh, rays[i]);
        wrong += b.prim != hits[i].prim || (b.valid() && b.t != hits[i].t);
    }
    for (const Hit& h : hits) hit_count += h.valid();
    ok = ok && wrong == 0 && hit_count > 0;

    // a picture: the renderer's default Whitted shading, one light, written as PNG
    RenderScene rs = prepare_render_scene(mesh);
    rs.lights.push_back(default_key_light(cam));
    RenderSettings set;
    set.spp = 4;
    const Image img = render_cpu(rs.view(), cam, set);
    const auto png = std::filesystem::temp_directory_path() / "raykit_consumer.png";
    write_png(img, png);
    ok = ok && std::filesystem::file_size(png) > 0;

    std::printf("one ray: prim %u at t=%g; batch: %zu of %zu rays hit, %zu wrong; wrote %s\n", one.prim,
                double(one.t), hit_count, rays.size(), wrong, png.string().c_str());
    return ok ? 0 : 1;
}
