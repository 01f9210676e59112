// benchmarks/anim_charts.cpp — the data of the animation charts, as CSV on stdout.
//
//   anim_charts interp [GOBLIN_DIR] > docs/anim_interp_error.csv
//       Interpolation error against cost, slerp vs the thesis's Euler scheme,
//       on the goblin's 800-frame animation (35 bones). For every key-frame
//       stride S in {1, 2, 4, 8, 16, 32} (interpolating between frames f and
//       f + S, as if the animation had been keyed every S frames) and every
//       start frame f (f + S < N) at t in {0.25, 0.5, 0.75}, every bone's local
//       rotation is interpolated both ways. Columns:
//         method, stride, samples (bone rotations),
//         mean_deg_vs_slerp, max_deg_vs_slerp   angle between the method's and
//                                               slerp's rotation (0 for slerp)
//         mean_deg_vs_key, max_deg_vs_key       at t = 0.5 with an even stride:
//                                               angle to the real key frame
//                                               f + S/2 (empty for S = 1)
//         ns_per_bone                           interpolate_poses wall time per
//                                               bone (best of 9 passes)
//   anim_charts sah [GOBLIN_DIR] > docs/anim_sah_growth.csv
//       SAH growth under refit over the goblin's animation: the character's
//       tree is built (binned SAH, build_bvh) from frame 0's skinned vertices,
//       then refitted every frame; RebuildPolicy (threshold 1.15) rebuilds it
//       when SAH(refitted) / SAH(after the last build) passes the threshold.
//       Columns: frame, sah_policy (the tree the policy keeps, after any
//       rebuild of this frame), growth (SAH refitted / SAH after the last
//       build, before the decision), rebuilt (1 when the policy rebuilt this
//       frame), sah_fresh (a fresh build of this frame), refit_only_vs_fresh
//       (a tree refitted from frame 0 and never rebuilt, over sah_fresh).
//   GOBLIN_DIR defaults to RAYKIT_SHARED_DATA_DIR/smd/hl2_goblin.
//
// Build (the lead adds it to benchmarks/CMakeLists.txt):
//   add_executable(anim_charts anim_charts.cpp)
//   target_link_libraries(anim_charts PRIVATE raykit::raykit raykit_tool_flags)
//   target_compile_definitions(anim_charts PRIVATE RAYKIT_SHARED_DATA_DIR="${RAYKIT_SHARED_DATA_DIR}")
// Charts: /usr/bin/python3 benchmarks/plot_anim.py docs/anim_interp_error.csv docs/anim_sah_growth.csv docs/
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/bvh/rebuild_policy.hpp"
#include "raykit/bvh/refit.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/io/smd.hpp"
#include "raykit/scene/build_options.hpp"

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

namespace {

using namespace raykit;

/// Angle of the rotation between a and b, in degrees (atan2 form: exact 0 for equal inputs,
/// accurate for small angles, unlike acos of the dot product).
double angle_deg(const glm::dquat& a, const glm::dquat& b) {
    const glm::dquat q = glm::conjugate(glm::normalize(a)) * glm::normalize(b);
    const double v = std::sqrt(q.x * q.x + q.y * q.y + q.z * q.z);
    return 2.0 * std::atan2(v, std::abs(q.w)) * 180.0 / 3.14159265358979323846;
}

int interp_chart(const SmdSkeletonAnim& anim) {
    const std::size_t n = anim.frame_count(), bones = anim.frames.empty() ? 0 : anim.frames[0].size();
    std::printf("method,stride,samples,mean_deg_vs_slerp,max_deg_vs_slerp,mean_deg_vs_key,max_deg_vs_key,ns_per_bone\n");
    const double ts[] = {0.25, 0.5, 0.75};
    for (std::size_t stride : {1u, 2u, 4u, 8u, 16u, 32u}) {
        if (stride >= n) break;
        for (Interpolation m : {Interpolation::slerp, Interpolation::euler}) {
            double sum = 0.0, worst = 0.0, ksum = 0.0, kworst = 0.0;
            std::size_t samples = 0, ksamples = 0;
            std::vector<BoneTransform> out(bones), ref(bones);
            for (std::size_t f = 0; f + stride < n; ++f) {
                for (double t : ts) {
                    interpolate_poses(anim.frame(f), anim.frame(f + stride), t, m, out);
                    interpolate_poses(anim.frame(f), anim.frame(f + stride), t, Interpolation::slerp, ref);
                    for (std::size_t b = 0; b < bones; ++b) {
                        const double e = angle_deg(out[b].rotation, ref[b].rotation);
                        sum += e;
                        worst = std::max(worst, e);
                        ++samples;
                    }
                    if (t == 0.5 && stride % 2 == 0) {
                        const auto& key = anim.frame(f + stride / 2);
                        for (std::size_t b = 0; b < bones; ++b) {
                            const glm::dvec3 r(key[b].rotation.x, key[b].rotation.y, key[b].rotation.z);
                            const double e = angle_deg(out[b].rotation, euler_xyz_quat(r));
                            ksum += e;
                            kworst = std::max(kworst, e);
                            ++ksamples;
                        }
                    }
                }
            }
            double best = std::numeric_limits<double>::infinity();
            for (int pass = 0; pass < 9; ++pass) {  // the first passes warm up; best of 9
                const auto t0 = std::chrono::steady_clock::now();
                for (std::size_t f = 0; f + stride < n; ++f)
                    for (double t : ts) interpolate_poses(anim.frame(f), anim.frame(f + stride), t, m, out);
                best = std::min(best, std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count());
            }
            const double per_bone = best / double(samples);
            if (ksamples)
                std::printf("%s,%zu,%zu,%.6g,%.6g,%.6g,%.6g,%.4g\n", m == Interpolation::slerp ? "slerp" : "euler", stride,
                            samples, sum / double(samples), worst, ksum / double(ksamples), kworst, per_bone);
            else
                std::printf("%s,%zu,%zu,%.6g,%.6g,,,%.4g\n", m == Interpolation::slerp ? "slerp" : "euler", stride, samples,
                            sum / double(samples), worst, per_bone);
        }
    }
    return 0;
}

int sah_chart(const SmdModel& model, const SmdSkeletonAnim& anim) {
    const Skeleton skeleton(model);
    const PackedSkin skin = pack_skin(model.weights, model.bones.size());
    const Mesh& m = model.mesh;
    std::vector<vec3> pos(m.positions.size());
    auto boxes_of = [&](Bvh& b) {
        refit(b, [&](std::uint32_t i) {
            AABB box;
            for (int c = 0; c < 3; ++c) box.grow(pos[m.triangles[i].v[c]]);
            return box;
        });
    };
    auto build = [&]() { return build_bvh(MeshView(std::span<const vec3>(pos), m.triangles), BuildOptions{}); };
    Bvh kept, refit_only;
    RebuildPolicy policy;
    std::printf("frame,sah_policy,growth,rebuilt,sah_fresh,refit_only_vs_fresh\n");
    for (std::size_t f = 0; f < anim.frame_count(); ++f) {
        const std::vector<SkinMatrix> mats =
            skin_matrices(skeleton, sample_frame(anim, double(f), Interpolation::slerp, WrapMode::clamp));
        skin_vertices(skin, mats, m.positions, {}, pos, {});
        const Bvh fresh = build();
        const double sah_fresh = sah_cost(fresh);
        double growth = 1.0;
        int rebuilt = 0;
        if (f == 0) {
            kept = fresh;
            refit_only = fresh;
            policy.reset(sah_fresh);
        } else {
            boxes_of(kept);
            boxes_of(refit_only);
            const double c = sah_cost(kept);
            growth = policy.growth(c);
            if (policy.should_rebuild(c)) {
                kept = fresh;
                policy.reset(sah_fresh);
                rebuilt = 1;
            }
        }
        std::printf("%zu,%.6g,%.6g,%d,%.6g,%.6g\n", f, sah_cost(kept), growth, rebuilt, sah_fresh,
                    sah_cost(refit_only) / sah_fresh);
    }
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    try {
        const std::string what = argc > 1 ? argv[1] : "";
        if (what != "interp" && what != "sah") {
            std::fprintf(stderr, "usage: anim_charts interp|sah [GOBLIN_DIR]\n");
            return 2;
        }
        const std::filesystem::path dir =
            argc > 2 ? std::filesystem::path(argv[2]) : std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / "smd" / "hl2_goblin";
        const SmdModel model = load_smd_reference(dir / "Goblin_Reference.smd");
        const SmdSkeletonAnim anim = load_smd_animation(dir / "Goblin_Anim.smd", model);
        return what == "interp" ? interp_chart(anim) : sah_chart(model, anim);
    } catch (const std::exception& e) {
        std::fprintf(stderr, "anim_charts: %s\n", e.what());
        return 1;
    }
}
