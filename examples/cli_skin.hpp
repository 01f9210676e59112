// examples/cli_skin.hpp — the `raykit skin` command (to be wired into examples/raykit.cpp).
//
//   raykit skin REF.smd [ANIM.smd FRAME] [--interp slerp|euler] [--device cpu|cl]
//
// Loads the reference SMD, optionally an animation SMD (retargeted by bone
// name) and prints the skinned position of every triangle corner: triangles
// in file order, corners in file order, one line "x y z" (printf %.9g) each,
// so 3 * triangle_count lines on stdout. Without ANIM the bind pose is used
// (the file's own vertex positions, up to float rounding). FRAME is a frame
// number, fractional allowed, in [0, frame_count - 1]; between two frames the
// pose is interpolated (--interp slerp, the default, or euler: the thesis's
// per-axis shortest-angle lerp). Skinning runs on the CPU through the packed
// device layout (anim/skinning.hpp), or with `--device cl` on the OpenCL
// device as the vertex hook raykit::SkinHook (anim/skin_hook.hpp) of a
// DeviceScene holding the mesh as its one dynamic object (vertex stage and
// refit run; the positions are read back): the same lines, the numbers
// within 1e-5 of the model's extent of the CPU's. `--device cl` needs a
// build with RAYKIT_CLI_HAVE_CL=1 (else it is a usage error); with no
// OpenCL device it fails with raykit::cl::NoDeviceError (exit code 1).
// Loader warnings go to stderr as "raykit: warning: ...".
//
// Entry point:
//   int raykit_cli_skin(int argc, char** argv, int first_arg);
//       argv[first_arg] is the first argument after `skin`. Returns 0.
//       Throws raykit_cli::SkinUsageError (derived from std::runtime_error)
//       for bad usage — wrong number of arguments, an unknown option, an
//       option without its value, --interp other than slerp/euler, --device
//       other than cpu/cl (cl only in OpenCL builds), FRAME not a finite number >= 0 — which the caller
//       should report with the usage text and exit code 2. Every other
//       failure throws another std::exception (raykit::ParseError for bad
//       files, std::runtime_error for FRAME beyond the last frame or an
//       output error): exit code 1.
//   raykit_cli::SkinArgs raykit_cli::parse_skin_args(int argc, char** argv, int first_arg);
//   std::string raykit_cli::skin_corners_text(const SkinArgs&, std::vector<std::string>* warnings);
//       The two halves of the command, for tests: the parsed arguments, and
//       the exact text the command prints.
#pragma once

#include <charconv>
#include <cmath>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/io/smd.hpp"
#if RAYKIT_CLI_HAVE_CL
#include "raykit/anim/skin_hook.hpp"
#include "raykit/cl.hpp"
#include "raykit/scene/scene.hpp"
#endif

namespace raykit_cli {

/// Bad command-line usage of `raykit skin` (map to exit code 2).
struct SkinUsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

inline constexpr const char* kSkinUsage =
    "  raykit skin REF.smd [ANIM.smd FRAME] [--interp slerp|euler] [--device cpu|cl]\n";

struct SkinArgs {
    std::string reference;
    std::string animation;  ///< empty: bind pose
    double frame = 0.0;
    raykit::Interpolation interp = raykit::Interpolation::slerp;
    bool device_cl = false;  ///< --device cl: skin on the OpenCL device
};

inline SkinArgs parse_skin_args(int argc, char** argv, int first_arg) {
    SkinArgs a;
    std::vector<std::string> pos;
    for (int i = first_arg; i < argc; ++i) {
        const std::string s = argv[i];
        if (s == "--interp" || s == "--device") {
            if (i + 1 >= argc) throw SkinUsageError(s + " needs a value");
            const std::string v = argv[++i];
            if (s == "--interp") {
                if (v == "slerp") {
                    a.interp = raykit::Interpolation::slerp;
                } else if (v == "euler") {
                    a.interp = raykit::Interpolation::euler;
                } else {
                    throw SkinUsageError("unknown --interp '" + v + "' (known: slerp, euler)");
                }
            } else if (v == "cpu") {
                a.device_cl = false;
            } else if (v == "cl") {
#if RAYKIT_CLI_HAVE_CL
                a.device_cl = true;
#else
                throw SkinUsageError("--device cl: this raykit was built without OpenCL");
#endif
            } else {
                throw SkinUsageError("unknown --device '" + v + "' (known: cpu, cl)");
            }
        } else if (s.size() > 1 && s[0] == '-' && s[1] == '-') {
            throw SkinUsageError("unknown option " + s);
        } else {
            pos.push_back(s);
        }
    }
    if (pos.size() != 1 && pos.size() != 3) throw SkinUsageError("skin takes REF.smd [ANIM.smd FRAME]");
    a.reference = pos[0];
    if (pos.size() == 3) {
        a.animation = pos[1];
        const std::string& f = pos[2];
        double v = 0.0;
        const auto [p, ec] = std::from_chars(f.data(), f.data() + f.size(), v);
        if (ec != std::errc() || p != f.data() + f.size() || !std::isfinite(v) || v < 0.0) {
            throw SkinUsageError("FRAME must be a number >= 0, got '" + f + "'");
        }
        a.frame = v;
    }
    return a;
}

inline std::string skin_corners_text(const SkinArgs& a, std::vector<std::string>* warnings) {
    const raykit::SmdModel model = raykit::load_smd_reference(a.reference);
    if (warnings) warnings->insert(warnings->end(), model.mesh.warnings.begin(), model.mesh.warnings.end());
    const raykit::Skeleton skeleton(model);
    std::vector<raykit::BoneTransform> local;
    if (a.animation.empty()) {
        local = skeleton.bind_transforms();
    } else {
        const raykit::SmdSkeletonAnim anim = raykit::load_smd_animation(a.animation, model);
        if (warnings) warnings->insert(warnings->end(), anim.warnings.begin(), anim.warnings.end());
        const double last = static_cast<double>(anim.frame_count()) - 1.0;
        if (a.frame > last) {
            char buf[64];
            std::snprintf(buf, sizeof buf, "%g", a.frame);
            throw std::runtime_error("FRAME " + std::string(buf) + " is beyond the last frame of " + a.animation +
                                     " (frames 0.." + std::to_string(anim.frame_count() - 1) + ")");
        }
        local = raykit::sample_frame(anim, a.frame, a.interp, raykit::WrapMode::clamp);
    }
    const std::vector<raykit::SkinMatrix> mats = raykit::skin_matrices(skeleton, local);
    const raykit::PackedSkin skin = raykit::pack_skin(model.weights, model.bones.size());
    std::vector<raykit::vec3> pos;
#if RAYKIT_CLI_HAVE_CL
    if (a.device_cl) {
        raykit::Scene scene;
        const std::uint32_t body = scene.add_object(model.mesh, raykit::ObjectKind::dynamic);
        scene.add_instance(body);
        raykit::cl::DeviceScene<raykit::SkinHook> ds(raykit::cl::Device::shared(), scene);
        raykit::upload_skin(ds, scene, body, skin);
        raykit::upload_skin_matrices(ds, std::span<const raykit::SkinMatrix>(mats));
        ds.update();
        pos = ds.positions(body);
    } else
#endif
    {
        pos = raykit::skin_positions(skin, mats, model.mesh.positions);
    }
    std::string out;
    out.reserve(model.mesh.triangles.size() * 3 * 40);
    char line[128];
    for (const raykit::Triangle& t : model.mesh.triangles) {
        for (int c = 0; c < 3; ++c) {
            const raykit::vec3& p = pos[t.v[c]];
            const int len = std::snprintf(line, sizeof line, "%.9g %.9g %.9g\n", static_cast<double>(p.x),
                                          static_cast<double>(p.y), static_cast<double>(p.z));
            out.append(line, static_cast<std::size_t>(len));
        }
    }
    return out;
}

}  // namespace raykit_cli

inline int raykit_cli_skin(int argc, char** argv, int first_arg) {
    const raykit_cli::SkinArgs args = raykit_cli::parse_skin_args(argc, argv, first_arg);
    std::vector<std::string> warnings;
    const std::string text = raykit_cli::skin_corners_text(args, &warnings);
    for (const std::string& w : warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    if (std::fwrite(text.data(), 1, text.size(), stdout) != text.size() || std::fflush(stdout) != 0) {
        throw std::runtime_error("error writing the output");
    }
    return 0;
}
