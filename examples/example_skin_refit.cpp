// example_skin_refit: load an SMD, skin a frame, refit.
//
//   example_skin_refit [REF.smd ANIM.smd [FRAME]]
//
// A skinned model (Valve SMD: skeleton, bind pose and weighted mesh, plus an animation matched
// to it by bone name) becomes a dynamic object of a raykit::Scene. At a frame (fractional frames
// interpolate; default: the middle one) each vertex is skinned from its rest copy and the
// object's trees are refitted in place: same topology, new boxes, no rebuild. Without files it
// writes a small model as SMD text and parses that: a tube on two bones, bent by its animation.
// Checks: the refitted tree is valid over the skinned triangles, camera rays through the scene
// hit exactly what brute force over the skinned mesh hits, and (tube) vertices on one bone are
// where a rotation by hand puts them. Exits 1 otherwise.
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

#include <raykit.hpp>

// The tube: radius 0.3 along y from 0 to 2, bones "root" at the origin and "tip" at y = 1.
// Vertices below y = 0.6 follow root alone, above 1.4 tip alone, in between they blend (the
// SMD vertex line: parent, position, normal, uv, then the links as bone-weight pairs).
static std::string tube_reference() {
    std::string s = "version 1\nnodes\n0 \"root\" -1\n1 \"tip\" 0\nend\n"
                    "skeleton\ntime 0\n0 0 0 0 0 0 0\n1 0 1 0 0 0 0\nend\ntriangles\n";
    auto corner = [&s](int ring, int seg) {
        const double a = 6.283185307179586 * seg / 16, y = 0.25 * ring, w = std::clamp((y - 0.6) / 0.8, 0.0, 1.0);
        char line[200];
        std::snprintf(line, sizeof line, "0 %.6f %.6f %.6f %.6f 0 %.6f %.4f %.4f 2 0 %.6f 1 %.6f\n", 0.3 * std::cos(a),
                      y, 0.3 * std::sin(a), std::cos(a), std::sin(a), seg / 16.0, y / 2, 1 - w, w);
        s += line;
    };
    for (int r = 0; r < 8; ++r)
        for (int k = 0; k < 16; ++k) {  // two triangles per quad: a material line, then 3 corners
            s += "tube\n";
            corner(r, k); corner(r + 1, k + 1); corner(r + 1, k);
            s += "tube\n";
            corner(r, k); corner(r, k + 1); corner(r + 1, k + 1);
        }
    return s + "end\n";
}
// Two key frames: at rest, then "tip" turned 1.2 radians about z (a local pose: relative to root).
static const char* const kTubeAnimation = "version 1\nnodes\n0 \"root\" -1\n1 \"tip\" 0\nend\nskeleton\n"
                                          "time 0\n0 0 0 0 0 0 0\n1 0 1 0 0 0 0\n"
                                          "time 1\n0 0 0 0 0 0 0\n1 0 1 0 0 0 1.2\nend\n";

int main(int argc, char** argv) {
    using namespace raykit;
    const bool files = argc > 2;
    const SmdModel model = files ? load_smd_reference(argv[1]) : parse_smd_reference(tube_reference(), "tube.smd", ".");
    const SmdSkeletonAnim anim = files ? load_smd_animation(argv[2], model)
                                       : parse_smd_animation(kTubeAnimation, "tube_bend.smd", model.bones, model.bind_pose);
    const double frame = argc > 3 ? std::atof(argv[3]) : 0.5 * double(anim.frame_count() - 1);

    // The model as a dynamic object: the Scene keeps its rest vertices and builds its trees once.
    Scene scene;
    const std::uint32_t body = scene.add_object(model.mesh, ObjectKind::dynamic);
    scene.add_instance(body);

    // One frame: local bone poses -> skinning matrices (world · inverse bind, one per bone);
    // the weights packed once (what the device's skinning hook reads too).
    const Skeleton skeleton(model);
    const std::vector<SkinMatrix> matrices = skin_matrices(skeleton, sample_frame(anim, frame));
    const PackedSkin skin = pack_skin(model.weights, model.bones.size());
    const SkinHook::Host host{skin.offsets, skin.links, matrices};
    // The vertex stage: vertex i from its rest copy, then both trees refitted in place.
    scene.move_vertices(body, [&](const Vertex& v, std::uint32_t i) { return SkinHook::apply(v, i, {}, host); });
    scene.update_top_level();  // the object's box changed

    // Check 1: the refitted binary tree is a valid tree over the skinned triangles.
    const SceneObject& obj = scene.objects()[body];
    std::vector<AABB> boxes(obj.mesh.triangle_count());
    for (std::size_t t = 0; t < boxes.size(); ++t) boxes[t] = MeshView(obj.mesh).bounds(t);
    const std::string problem = validate(obj.bvh, boxes);
    float moved = 0.0f;
    for (std::size_t i = 0; i < obj.mesh.positions.size(); ++i)
        moved = std::max(moved, glm::length(obj.mesh.positions[i] - model.mesh.positions[i]));
    // Check 2, the generated tube only: at frame 0.5 tip is turned 0.6 radians about z at
    // (0, 1, 0), so vertices on tip alone (y >= 1.4) turn with it and those on root stay.
    double by_hand = 0.0;
    for (std::size_t i = 0; !files && i < obj.mesh.positions.size(); ++i) {
        const vec3 p = model.mesh.positions[i];
        const double a = p.y >= 1.4f ? 0.6 : 0.0, c = std::cos(a), sn = std::sin(a);
        if (p.y > 0.6f && p.y < 1.4f) continue;  // blended
        const glm::dvec3 want(p.x * c - (p.y - 1) * sn, 1 + p.x * sn + (p.y - 1) * c, p.z);
        by_hand = std::max(by_hand, glm::length(want - glm::dvec3(obj.mesh.positions[i])));
    }

    // Check 3: rays through the scene (the refitted 8-wide block tree) against brute force over
    // the skinned triangles: the same watertight test, so the same triangle at the same t.
    const Camera cam = camera_looking_at(obj.mesh.bounds(), 128, 96);
    std::size_t hits = 0, wrong = 0;
    for (const Ray& ray : camera_rays(cam)) {
        const Hit h = scene.intersect_closest(ray), b = brute_force_closest(obj.mesh, ray);
        hits += b.valid();
        wrong += h.prim != b.prim || (b.valid() && h.t != b.t);
    }

    std::printf("%zu bones, %zu triangles, %zu loader warnings; frame %g of 0..%zu\n", model.bones.size(),
                model.mesh.triangle_count(), model.mesh.warnings.size(), frame, anim.frame_count() - 1);
    std::printf("skinned: largest vertex move %.3g (model size %.3g)%s; refitted tree: %s\n", double(moved),
                double(glm::length(model.mesh.bounds().max - model.mesh.bounds().min)),
                files ? "" : (by_hand <= 1e-5 ? ", one-bone vertices where computed by hand" : ", NOT where computed by hand"),
                problem.empty() ? "valid" : problem.c_str());
    std::printf("checked %u camera rays against brute force on the skinned mesh: %zu hit, %zu differ\n",
                cam.width * cam.height, hits, wrong);
    const bool ok = problem.empty() && wrong == 0 && hits > 0 && (files || (moved > 0.0f && by_hand <= 1e-5));
    if (!ok) std::printf("FAILED\n");
    return ok ? 0 : 1;
}
