// What the README's "Using it" shows, as a consumer builds it: make (or load) a mesh, build
// the fast tree, trace one ray, trace a batch of camera rays, render and write a PNG. Every
// answer is checked against brute force, so the program fails (exit 1) when raykit is wrong.
// Built through find_package and add_subdirectory, the latter with raykit's strict warning set.
#include <cstdio>
#include <filesystem>
#include <vector>

#include <raykit.hpp>

int main(int argc, char** argv) {
    using namespace raykit;
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
