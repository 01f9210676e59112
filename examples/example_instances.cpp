// example_instances: a scene of instanced objects.
//
//   example_instances [MESH.obj] [OUT.png]
//
// Two objects (the given mesh, or an icosphere, and a generated torus) are stored once each and
// placed 25 times, each placement with its own rotation, non-uniform scale and position. A
// raykit::Scene traces a world ray by mapping it into each candidate instance's object space
// and walking that object's tree, under a top-level tree over the instances' world boxes; so
// 25 placements cost 25 small records, not 25 copies of the triangles. The program renders the
// scene, then checks a grid of rays against brute force over every instance's triangles moved
// to world space (no trees, no object-space rays): same instance hit, same distance.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <set>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>  // glm::translate, rotate, scale: any affine mat4 places an instance
#include <raykit.hpp>

int main(int argc, char** argv) {
    using namespace raykit;
    Mesh first = argc > 1 ? load_obj(argv[1]) : make_icosphere(3);
    const std::filesystem::path out =
        argc > 2 ? std::filesystem::path(argv[2]) : std::filesystem::temp_directory_path() / "example_instances.png";
    const AABB box = first.bounds();  // fit any mesh into the unit sphere, so the layout suits it
    const float fit = 2.0f / std::max(glm::length(box.max - box.min), 1e-6f);
    transform_positions(first, fit, -box.center() * fit);
    auto paint = [](Mesh m, vec3 colour) {  // one diffuse material for the whole mesh
        if (!m.materials.empty()) return m;  // an OBJ keeps its own
        m.materials.resize(1);
        m.materials[0].kd = colour;
        m.material_ids.assign(m.triangles.size(), 0);
        return m;
    };

    // Objects first (each gets its own tree), then instances that refer to them by index.
    RenderScene rs;  // a Scene plus one material table per object and lights: what render_cpu needs
    const std::uint32_t objects[2] = {rs.add_object(paint(std::move(first), vec3(0.8f, 0.5f, 0.2f))),
                                      rs.add_object(paint(make_bumpy_torus(2000, 0.15f, 0.7f, 0.25f), vec3(0.2f, 0.5f, 0.8f)))};
    for (int i = 0; i < 25; ++i) {
        mat4 m = glm::translate(mat4(1.0f), vec3(float(i % 5) * 1.6f - 3.2f, 0.0f, float(i / 5) * 1.6f - 3.2f));
        m = glm::rotate(m, 0.7f * float(i), glm::normalize(vec3(1.0f, 2.0f, float(i % 3))));
        m = glm::scale(m, vec3(0.8f + 0.1f * float(i % 4), 1.0f, 0.9f));
        rs.scene.add_instance(objects[i % 2], m);
    }
    rs.scene.update_top_level();  // after adding or moving instances, before tracing

    const Camera cam = camera_looking_at(rs.bounds(), 320, 240, vec3(0.3f, 1.0f, 0.9f));
    rs.lights.push_back(default_key_light(cam));
    write_png(render_cpu(rs.view(), cam, RenderSettings{}), out);

    // The oracle: one mesh of every instance's triangles in world space, each vertex moved by
    // its instance's transform in double precision, and for each triangle its (instance, triangle).
    Mesh world;
    std::vector<std::pair<std::uint32_t, std::uint32_t>> origin;
    for (std::uint32_t i = 0; i < rs.scene.instances().size(); ++i) {
        const SceneInstance& in = rs.scene.instances()[i];
        const Mesh& m = rs.scene.objects()[in.object].mesh;
        const auto base = static_cast<std::uint32_t>(world.positions.size());
        for (const vec3& p : m.positions) world.positions.push_back(vec3(glm::dmat4(in.transform) * glm::dvec4(p, 1.0)));
        for (const Triangle& t : m.triangles) world.triangles.push_back({{t[0] + base, t[1] + base, t[2] + base}});
        for (std::uint32_t t = 0; t < m.triangles.size(); ++t) origin.emplace_back(i, t);
    }

    // A grid of camera rays, each traced both ways. The two agree up to the rounding of the
    // transforms, so distances are compared with a tolerance.
    const CameraFrame frame = cam.frame();
    std::size_t checked = 0, hit = 0, wrong = 0, same_triangle = 0;
    std::set<std::uint32_t> seen;
    for (std::uint32_t y = 2; y < cam.height; y += 6)
        for (std::uint32_t x = 2; x < cam.width; x += 6, ++checked) {
            const Ray ray = frame.ray(x, y);
            const Hit h = rs.scene.intersect_closest(ray);  // h.inst: the instance, h.prim: its object's triangle
            const Hit b = brute_force_closest(world, ray);
            if (!h.valid() && !b.valid()) continue;
            const bool agree = h.valid() && b.valid() && h.inst == origin[b.prim].first &&
                               std::fabs(h.t - b.t) <= 1e-4f * b.t;  // a ray at an edge may take the neighbour
            if (!agree && ++wrong <= 5)
                std::printf("pixel (%u, %u): scene instance %u t %.7g, world brute force instance %d t %.7g\n", x, y,
                            h.inst, double(h.t), b.valid() ? int(origin[b.prim].first) : -1, double(b.t));
            if (!agree) continue;
            ++hit;
            seen.insert(h.inst);
            same_triangle += h.prim == origin[b.prim].second;
        }

    std::printf("%zu instances of %zu objects: %zu triangles stored, %zu in the world; wrote %s\n",
                rs.scene.instances().size(), rs.scene.objects().size(),
                rs.scene.objects()[0].mesh.triangle_count() + rs.scene.objects()[1].mesh.triangle_count(),
                world.triangle_count(), out.string().c_str());
    std::printf("checked %zu rays against world-space brute force: %zu differ; %zu hit (%zu the same triangle), "
                "%zu instances seen\n", checked, wrong, hit, same_triangle, seen.size());
    const bool ok = wrong == 0 && seen.size() >= 10;
    if (!ok) std::printf("FAILED\n");
    return ok ? 0 : 1;
}
