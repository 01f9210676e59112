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
// Entry points:
//   void raykit_cli::add_skin_options(CLI::App&, SkinArgs&);
//   void raykit_cli::finish_skin_args(CLI::App&, SkinArgs&);
//       The arguments on a CLI11 app (raykit.cpp's `skin` subcommand), then what the parser
//       cannot check. Bad usage — wrong number of arguments, an unknown option, an option
//       without its value, --interp other than slerp/euler, --device other than cpu/cl (cl only
//       in OpenCL builds), FRAME not a finite number >= 0 — is a raykit_cli::UsageError
//       (exit code 2).
//   int raykit_cli::run_skin(const SkinArgs&);
//       Prints the corners. Every other failure throws another std::exception
//       (raykit::ParseError for bad files, std::runtime_error for FRAME beyond the last frame,
//       an animation none of whose bones is in REF's skeleton, or an output error): exit code 1.
//   int raykit_cli_skin(int argc, char** argv, int first_arg);
//       Both for argv[first_arg ..], the arguments after `skin`.
//   raykit_cli::SkinArgs raykit_cli::parse_skin_args(int argc, char** argv, int first_arg);
//   std::string raykit_cli::skin_corners_text(const SkinArgs&, std::vector<std::string>* warnings);
//       The two halves of the command, for tests: the parsed arguments, and
//       the exact text the command prints.
#pragma once

#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include "cli_common.hpp"
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

/// Bad command-line usage of `raykit skin`: the one raykit_cli::UsageError (exit code 2); this
/// name is kept for code written against the hand-written parser it replaced.
using SkinUsageError = UsageError;

struct SkinArgs {
    std::string reference;
    std::string animation;  ///< empty: bind pose
    double frame = 0.0;
    raykit::Interpolation interp = raykit::Interpolation::slerp;
    bool device_cl = false;  ///< --device cl: skin on the OpenCL device
    // as parsed, before finish_skin_args
    std::string interp_name = "slerp", device = "cpu";
    bool frame_given = false;
};

/// The arguments and options of `raykit skin` on a CLI11 app, filling `a` (then finish_skin_args).
inline void add_skin_options(CLI::App& app, SkinArgs& a) {
    app.add_option("REF.smd", a.reference, "the reference SMD: skeleton, bind pose, skinned mesh")
        ->required()
        ->type_name("");
    app.add_option("ANIM.smd", a.animation, "an animation SMD (bones matched by name); without it, the bind pose")
        ->type_name("");
    app.add_option("FRAME", a.frame, "frame number of ANIM, fractional allowed, in 0..last frame")
        ->type_name("")
        ->check(real_in([](double d) { return d >= 0.0; }, "must be a number >= 0"));
    app.add_option("--interp", a.interp_name, "between frames: slerp (default) or euler (per-axis lerp)")
        ->type_name("")
        ->check(CLI::IsMember({"slerp", "euler"}));
    app.add_option("--device", a.device, "where to skin: cpu (default) or cl (the OpenCL device)")
        ->type_name("")
        ->check(CLI::IsMember({"cpu", "cl"}));
}

/// What the parser cannot check: ANIM.smd comes with FRAME; --device cl needs an OpenCL build.
inline void finish_skin_args(CLI::App& app, SkinArgs& a) {
    a.frame_given = app.count("FRAME") > 0;
    if (!a.animation.empty() && !a.frame_given) throw UsageError("skin takes REF.smd [ANIM.smd FRAME]: FRAME is missing");
    a.interp = a.interp_name == "euler" ? raykit::Interpolation::euler : raykit::Interpolation::slerp;
    a.device_cl = a.device == "cl";
#if !RAYKIT_CLI_HAVE_CL
    if (a.device_cl) throw UsageError("--device cl: this raykit was built without OpenCL");
#endif
}

inline SkinArgs parse_skin_args(int argc, char** argv, int first_arg) {
    SkinArgs a;
    CLI::App app{"", "raykit skin"};
    add_skin_options(app, a);
    parse_args(app, argc, argv, first_arg);
    finish_skin_args(app, a);
    return a;
}

/// load_smd_animation(file, model), refused (std::runtime_error, one line) when none of the
/// file's bones is in the model's skeleton: it would animate nothing and only show the bind pose.
inline raykit::SmdSkeletonAnim load_animation_for(const std::string& file, const raykit::SmdModel& model,
                                                  const std::string& model_file) {
    // reference bones the file does not animate keep this marker; then the bind pose
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const std::vector<raykit::BonePose> unset(model.bones.size(), raykit::BonePose{raykit::vec3(nan), raykit::vec3(nan)});
    raykit::SmdSkeletonAnim anim = raykit::load_smd_animation(file, model.bones, unset);
    bool any = false;
    for (std::vector<raykit::BonePose>& frame : anim.frames)
        for (std::size_t i = 0; i < frame.size(); ++i) {
            if (std::isnan(frame[i].position.x)) frame[i] = i < model.bind_pose.size() ? model.bind_pose[i] : raykit::BonePose{};
            else any = true;
        }
    if (!any && !anim.frames.empty() && !model.bones.empty())
        throw std::runtime_error(file + ": none of its bones is in the skeleton of " + model_file +
                                 " (an animation of another model?)");
    return anim;
}

inline std::string skin_corners_text(const SkinArgs& a, std::vector<std::string>* warnings) {
    const raykit::SmdModel model = raykit::load_smd_reference(a.reference);
    if (warnings) warnings->insert(warnings->end(), model.mesh.warnings.begin(), model.mesh.warnings.end());
    const raykit::Skeleton skeleton(model);
    std::vector<raykit::BoneTransform> local;
    if (a.animation.empty()) {
        local = skeleton.bind_transforms();
    } else {
        const raykit::SmdSkeletonAnim anim = load_animation_for(a.animation, model, a.reference);
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

inline int run_skin(const SkinArgs& args) {
    std::vector<std::string> warnings;
    const std::string text = skin_corners_text(args, &warnings);
    for (const std::string& w : warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    if (std::fwrite(text.data(), 1, text.size(), stdout) != text.size() || std::fflush(stdout) != 0) {
        throw std::runtime_error("error writing the output");
    }
    return 0;
}

}  // namespace raykit_cli

inline int raykit_cli_skin(int argc, char** argv, int first_arg) {
    return raykit_cli::run_skin(raykit_cli::parse_skin_args(argc, argv, first_arg));
}
