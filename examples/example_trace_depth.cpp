// example_trace_depth: trace a mesh and write a depth PNG.
//
//   example_trace_depth [MESH.obj] [OUT.png]
//
// Loads an OBJ (or, without one, generates a bumpy torus: raykit ships no data), builds the
// tree CPU queries are fastest on, traces one camera ray per pixel on all cores and writes the
// distance to the first hit as grey levels (near = white, miss = black). Then it checks itself:
// a sample of the rays is traced again by brute force (every triangle, no tree), and the
// program exits 1 when a hit differs, so the test that runs it fails.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <vector>

#include <raykit.hpp>  // <raykit/core.hpp> is enough to load, build and trace; the PNG writer is here

int main(int argc, char** argv) {
    using namespace raykit;
    const Mesh mesh = argc > 1 ? load_obj(argv[1]) : make_bumpy_torus(8000);
    const std::filesystem::path out =
        argc > 2 ? std::filesystem::path(argv[2]) : std::filesystem::temp_directory_path() / "example_trace_depth.png";

    // The tree: 8-wide nodes over blocks of 4 triangles, built with the SAH on all cores.
    // It copies the triangles it needs, so the mesh is not needed to trace it.
    const BlockBvh8 tree = BlockBvh8::build(mesh);

    // One ray per pixel centre of a camera that sees the whole mesh.
    const Camera cam = camera_looking_at(mesh.bounds(), 320, 240, vec3(0.2f, -0.5f, 1.0f));  // looking from +z, below
    const std::vector<Ray> rays = camera_rays(cam);
    std::vector<Hit> hits(rays.size());
    intersect_closest(tree, rays, hits);  // the batch call: packets of neighbouring rays, on all cores

    // Distance along the ray is t·|dir|: camera directions are not normalised and raykit
    // measures t in units of the direction's length.
    std::vector<float> dist(rays.size(), -1.0f);
    float nearest = kInf, farthest = 0.0f;
    std::size_t hit_count = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (!hits[i].valid()) continue;
        dist[i] = hits[i].t * glm::length(rays[i].dir);
        nearest = std::min(nearest, dist[i]);
        farthest = std::max(farthest, dist[i]);
        ++hit_count;
    }
    Image img(cam.width, cam.height);  // black, opaque
    const float range = std::max(farthest - nearest, 1e-6f);
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (dist[i] < 0.0f) continue;
        const float grey = 1.0f - 0.8f * (dist[i] - nearest) / range;  // 1 at the nearest hit, 0.2 at the farthest
        img.pixels[i] = vec4(grey, grey, grey, 1.0f);
    }
    write_png(img, out, {.alpha = false, .srgb = false});  // grey levels as they are, not sRGB-encoded

    // The oracle: brute_force_closest tests every triangle with the same watertight test, so
    // it must find the same triangle at the same t, bit for bit (ties go to the smaller index
    // in both). Every 11th ray keeps the check quick.
    std::size_t checked = 0, wrong = 0;
    for (std::size_t i = 0; i < rays.size(); i += 11, ++checked) {
        const Hit b = brute_force_closest(mesh, rays[i]);
        if (b.prim != hits[i].prim || (b.valid() && (b.t != hits[i].t || b.u != hits[i].u || b.v != hits[i].v))) {
            if (++wrong <= 5)
                std::printf("ray %zu: tree prim %u t %.9g, brute force prim %u t %.9g\n", i, hits[i].prim,
                            double(hits[i].t), b.prim, double(b.t));
        }
    }

    std::printf("%zu triangles, %zu of %zu rays hit (distance %.3g to %.3g); wrote %s\n", mesh.triangle_count(),
                hit_count, rays.size(), double(nearest), double(farthest), out.string().c_str());
    std::printf("checked %zu rays against brute force: %zu differ\n", checked, wrong);
    const bool ok = wrong == 0 && hit_count > 0;
    if (!ok) std::printf("FAILED\n");
    return ok ? 0 : 1;
}
