// examples/cli_animate.hpp — the `raykit animate` command: a skinned SMD
// character rendered frame by frame, alone or inside a static OBJ scene.
//
//   raykit animate REF.smd ANIM.smd OUT_%03d.png [--scene STATIC.obj] [--frames N] [--first F]
//                  [--fps F] [--device cpu|cl] [--nodes full|quantized] [--width W] [--height H]
//                  [--spp N] [--camera EX EY EZ TX TY TZ] [--fov DEG] [--light X Y Z R G B]
//                  [--place X Z] [--char-height H] [--yaw DEG] [--threads T] [--max-depth D]
//
// Frame k (k = 0 .. N-1) shows the animation at time (first + k) / fps seconds,
// i.e. animation frame (first + k) · anim_fps / fps (slerp between frames,
// looping); defaults: every frame of ANIM once (N = frame count) at the
// animation's own rate. OUT holds one integer conversion for the frame
// number k: %d, %Nd (space-padded) or %0Nd (zero-padded), width N <= 32, so
// every frame gets its own file name; no other '%' may appear. An OUT without
// a conversion is accepted only when one frame is rendered. Anything else is
// a usage error (exit code 2).
//
// Placement. SMD models are Z-up in their own units (the HL2 goblin is ~17
// units tall); OBJ scenes are Y-up. The character is turned Z-up -> Y-up,
// turned by --yaw about the vertical (default -50°: SMD characters face +x;
// this turns them towards the default camera), scaled to --char-height (default 1.8;
// the thesis scene's houses are ~6-10 units tall) and stood with its bind
// pose's feet on the first surface below (X, top of scene, Z) (--place,
// default: the scene's centre, or the origin without --scene). The placement
// is the character instance's transform: skinning stays in model space and
// rays are mapped into it. The camera (no --camera) frames the character's
// placed bind-pose box from the front-right-above at ~3x its size and stays
// fixed; the default light is default_key_light of that camera.
//
// The frame is raykit::FrameLoop (render/frame.hpp) over a RenderScene of two
// objects — the static OBJ (never touched again) and the dynamic character;
// this command only parses flags, samples the animation and prints. Per frame
// (wall-clock ms, one table row on stdout):
//   interpolate  sample_frame (slerp) + skin_matrices
//   skin         the vertex stage. CPU: SkinHook's CPU twin on every vertex.
//                cl: the matrices uploaded, SkinHook run by a
//                raykit::cl::DeviceScene<SkinHook>.
//   refit        the character's trees refitted in place (CPU: binary and
//                8-wide blocks; cl: its 8-wide tree and blocks on the device),
//                or rebuilt when the RebuildPolicy (threshold 1.15) says so (cl:
//                PLOC on the device, raykit::cl::DeviceRebuild; the policy's
//                cost measure and the rebuild are in this column too)
//   top          the top-level tree over the two instances
//   trace/shade  the render stage: CPU split by thread time (FrameLoop); cl:
//                device time of the closest-hit + shadow kernels / of the
//                shade kernels (raykit::cl::DeviceRenderer)
//   sah          SAH growth of the character's refitted tree over its last
//                build (CPU: of the binary tree; cl: of the 8-wide tree,
//                rk_tree_cost); decision "refit" or "rebuild" ("rebuild (host)"
//                where the device builder gave up and the CPU built it).
// With --device cl the whole frame runs on the device (DeviceScene update,
// then DeviceRenderer over it): no vertex is read back, only the image.
//
// Entry points:
//   void raykit_cli::add_animate_options(CLI::App&, AnimateArgs&);
//   void raykit_cli::finish_animate_args(AnimateArgs&);
//       The arguments on a CLI11 app (raykit.cpp's `animate` subcommand), then what the
//       parser cannot check; bad usage is a raykit_cli::UsageError (exit code 2).
//   int raykit_cli::run_animate(const AnimateArgs&);
//       Renders the frames. Returns 0; other std::exceptions for failures (exit code 1), e.g.
//       an ANIM none of whose bones is in REF's skeleton.
//   int raykit_cli_animate(int argc, char** argv, int first_arg);
//       All three for argv[first_arg ..], the arguments after `animate`.
//   raykit_cli::AnimateArgs raykit_cli::parse_animate_args(int argc, char** argv, int first_arg);
//       Also checks OUT (a usage error for a bad pattern, or for --frames N > 1
//       with an OUT without a conversion).
//   std::string raykit_cli::animate_frame_name(const std::string& pattern, long k);
//       OUT with its conversion replaced by k (OUT as is without one); throws
//       raykit_cli::UsageError for a pattern the rules above reject.
#pragma once

#include <algorithm>
#include <cctype>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <system_error>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "raykit.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/bvh/rebuild_policy.hpp"
#include "raykit/bvh/refit.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/io/smd.hpp"
#include "raykit/render/image.hpp"
#include "raykit/render/frame.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/anim/skin_hook.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/scene.hpp"
#include "cli_render.hpp"  // the render flags' shared limits (kMaxPixels)
#include "cli_skin.hpp"    // load_animation_for
#if RAYKIT_CLI_HAVE_CL
#include "raykit/cl.hpp"
#include "raykit/cl/render.hpp"
#endif

/// Bad command-line usage of `raykit animate`: the one raykit_cli::UsageError (exit code 2); this
/// name is kept for code written against the hand-written parser it replaced.
using RaykitCliAnimateUsageError = raykit_cli::UsageError;

namespace raykit_cli {

struct AnimateArgs {
    std::string reference, animation, output, scene;
    long frames = -1;  ///< -1: every frame
    long first = 0;
    double fps = 0.0;  ///< 0: the animation's
    bool device_cl = false;
    std::uint32_t width = 640, height = 480;
    unsigned spp = 1, threads = 0, max_depth = 2;
    std::optional<std::pair<raykit::vec3, raykit::vec3>> camera;
    float fov = 45.0f;
    std::vector<raykit::Light> lights;
    std::optional<std::pair<float, float>> place;
    float char_height = 1.8f;
    float yaw = -50.0f;  ///< faces the default camera
    // as parsed, before finish_animate_args
    std::string device = "cpu", nodes = "full";
    std::vector<float> camera_values, light_values, place_values;
};

inline constexpr int kAnimateMaxWidth = 32;  ///< widest %Nd field in OUT

namespace detail_animate {

/// The conversion of OUT: where it starts and ends ([at, end), end after the
/// 'd'), zero padding and width. at == npos: none. Throws for a bad pattern.
struct OutConversion {
    std::size_t at = std::string::npos, end = std::string::npos;
    bool zero = false;
    int width = 0;
};

inline OutConversion out_conversion(const std::string& pattern) {
    OutConversion c;
    c.at = pattern.find('%');
    if (c.at == std::string::npos) return c;
    const auto bad = [&](const std::string& why) {
        return RaykitCliAnimateUsageError("OUT '" + pattern + "': " + why +
                                          " (one frame-number conversion: %d, %4d or %04d, width <= " +
                                          std::to_string(kAnimateMaxWidth) + ")");
    };
    std::size_t e = c.at + 1;
    while (e < pattern.size() && pattern[e] == '0') {
        c.zero = true;
        ++e;
    }
    const std::size_t digits = e;
    while (e < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[e]))) ++e;
    if (e >= pattern.size() || pattern[e] != 'd') throw bad("only an integer conversion is allowed");
    if (e - digits > 2 || (e > digits && std::stoi(pattern.substr(digits, e - digits)) > kAnimateMaxWidth))
        throw bad("field width " + pattern.substr(digits, e - digits) + " is too large");
    c.width = e > digits ? std::stoi(pattern.substr(digits, e - digits)) : 0;
    c.end = e + 1;
    if (pattern.find('%', c.end) != std::string::npos) throw bad("a second '%'");
    return c;
}

}  // namespace detail_animate

/// Whether OUT has its frame-number conversion (throws for a bad pattern).
inline bool animate_pattern_has_conversion(const std::string& pattern) {
    return detail_animate::out_conversion(pattern).at != std::string::npos;
}

/// The arguments and options of `raykit animate` on a CLI11 app, filling `a` (then
/// finish_animate_args). Integer flags have the ranges of `raykit render`'s.
inline void add_animate_options(CLI::App& app, AnimateArgs& a) {
    namespace cr = raykit::detail::cli_render;
    app.add_option("REF.smd", a.reference, "the character: reference SMD")->required()->type_name("");
    app.add_option("ANIM.smd", a.animation, "its animation SMD (bones matched by name)")->required()->type_name("");
    app.add_option("OUT_%03d.png", a.output, "frame files: one %d, %Nd or %0Nd (N <= 32) for the frame number")
        ->required()
        ->type_name("");
    app.add_option("--scene", a.scene, "render the character inside this static scene")->type_name("STATIC.obj");
    app.add_option("--frames", a.frames, "frames to render, 1..1000000000 (default: every frame of ANIM)")
        ->type_name("N")
        ->transform(count_in(1, 1000000000));
    app.add_option("--first", a.first, "first frame number, 0..1000000000 (default 0)")
        ->type_name("F")
        ->transform(count_in(0, 1000000000));
    app.add_option("--fps", a.fps, "output frame rate, > 0 (default: the animation's)")
        ->type_name("F")
        ->check(real_in([](double d) { return d > 0.0; }, "must be > 0"));
    app.add_option("--device", a.device, "where the frame runs: cpu (default) or cl (skinning, refit, render on the device)")
        ->type_name("")
        ->check(CLI::IsMember({"cpu", "cl"}));
    add_nodes_option(app, a.nodes);
    add_image_size_options(app, a.width, a.height);
    app.add_option("--spp", a.spp, "samples per pixel, 1..65536 (default 1)")->type_name("N")->transform(count_in(1, cr::kMaxSpp));
    app.add_option("--max-depth", a.max_depth, "reflection/refraction bounces, 0..1000 (default 2)")
        ->type_name("D")
        ->transform(count_in(0, cr::kMaxDepth));
    app.add_option("--camera", a.camera_values, "eye and target (default: frame the character)")
        ->type_name("EX EY EZ TX TY TZ")
        ->expected(6)
        ->check(finite());
    add_fov_option(app, a.fov);
    app.add_option("--light", a.light_values, "point light, repeatable (default: a key light)")
        ->type_name("X Y Z R G B")
        ->expected(6)
        ->multi_option_policy(CLI::MultiOptionPolicy::TakeAll)
        ->check(finite());
    app.add_option("--place", a.place_values, "where the character stands (default: the scene's centre)")
        ->type_name("X Z")
        ->expected(2)
        ->check(finite());
    app.add_option("--char-height", a.char_height, "character height in scene units, > 0 (default 1.8)")
        ->type_name("H")
        ->check(real_in([](double d) { return d > 0.0; }, "must be > 0"));
    app.add_option("--yaw", a.yaw, "turn the character about the vertical, degrees (default -50: facing the default camera)")
        ->type_name("DEG")
        ->check(finite());
    add_threads_option(app, a.threads);
}

/// What the parser cannot check: OUT's pattern (and one file for several frames), the image
/// size, --device cl in a build without OpenCL; the vectors become camera, lights, place.
inline void finish_animate_args(AnimateArgs& a) {
    a.device_cl = a.device == "cl";
    check_nodes_option(a.nodes, a.device_cl);
#if !RAYKIT_CLI_HAVE_CL
    if (a.device_cl) throw UsageError("--device cl: this raykit was built without OpenCL");
#endif
    const std::vector<float>& c = a.camera_values;
    if (c.size() == 6) a.camera = {{c[0], c[1], c[2]}, {c[3], c[4], c[5]}};
    const std::vector<float>& l = a.light_values;
    a.lights.clear();
    for (std::size_t i = 0; i + 6 <= l.size(); i += 6)
        a.lights.push_back(raykit::Light::point({l[i], l[i + 1], l[i + 2]}, {l[i + 3], l[i + 4], l[i + 5]}));
    if (a.place_values.size() == 2) a.place = {{a.place_values[0], a.place_values[1]}};
    if (!animate_pattern_has_conversion(a.output) && a.frames > 1)
        throw UsageError("OUT '" + a.output + "' has no %d conversion but --frames " + std::to_string(a.frames) +
                         " would write every frame to that one file");
    if (std::uint64_t(a.width) * a.height > raykit::detail::cli_render::kMaxPixels)
        throw UsageError("the image must be at most " + std::to_string(raykit::detail::cli_render::kMaxPixels) +
                         " pixels");
}

inline AnimateArgs parse_animate_args(int argc, char** argv, int first_arg) {
    AnimateArgs a;
    CLI::App app{"", "raykit animate"};
    add_animate_options(app, a);
    parse_args(app, argc, argv, first_arg);
    finish_animate_args(a);
    return a;
}

/// OUT with its one integer conversion filled in with k (or OUT as is).
/// Distinct frame numbers give distinct names (the width only pads).
inline std::string animate_frame_name(const std::string& pattern, long k) {
    const detail_animate::OutConversion c = detail_animate::out_conversion(pattern);
    if (c.at == std::string::npos) return pattern;
    char buf[64];  // width <= 32 plus a long's digits and sign
    std::snprintf(buf, sizeof buf, c.zero ? "%0*ld" : "%*ld", c.width, k);
    return pattern.substr(0, c.at) + buf + pattern.substr(c.end);
}

}  // namespace raykit_cli

namespace raykit_cli {

inline int run_animate(const AnimateArgs& a) {
    using namespace raykit;
    using clock = std::chrono::steady_clock;
    auto ms = [](clock::time_point a) { return std::chrono::duration<double, std::milli>(clock::now() - a).count(); };
    const SmdModel model = load_smd_reference(a.reference);
    const SmdSkeletonAnim anim = load_animation_for(a.animation, model, a.reference);
    for (const std::string& w : model.mesh.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    for (const std::string& w : anim.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    if (anim.frame_count() == 0) throw std::runtime_error(a.animation + ": no frames");
    const Skeleton skeleton(model);
    const PackedSkin skin = pack_skin(model.weights, model.bones.size());
    const Mesh& cm = model.mesh;
    const std::size_t nv = cm.positions.size();

    // The scene: the static OBJ as a static object, the character as a dynamic object placed by
    // its instance's transform P (skinning stays in model space; rays are mapped per instance).
    RenderScene rs;
    Mesh static_mesh;
    if (!a.scene.empty()) {
        static_mesh = load_obj(a.scene);
        for (const std::string& w : static_mesh.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    }
    const auto static_tris = static_cast<std::uint32_t>(static_mesh.triangles.size());
    AABB static_box;
    for (const vec3& p : static_mesh.positions) static_box.grow(p);
    const BuildOptions build = render_build_options(a.threads);
    const std::uint32_t stat =
        static_mesh.triangles.empty() ? kInvalidIndex : rs.add_object(std::move(static_mesh), ObjectKind::static_object, build);
    const std::uint32_t body = rs.add_object(cm, ObjectKind::dynamic, build);
    for (const MaterialTable& mt : rs.materials)
        for (const std::string& w : mt.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());

    // Placement P: Z-up -> Y-up, yaw, scale to char_height, feet on the ground at (X, Z).
    AABB rest_box;
    for (const vec3& p : cm.positions) rest_box.grow(p);
    const float model_height = rest_box.max.z - rest_box.min.z;
    if (!(model_height > 0.0f)) throw std::runtime_error(a.reference + ": the model has no height");
    const float s = a.char_height / model_height;
    float px = 0.0f, pz = 0.0f, ground = 0.0f;
    if (a.place) {
        px = a.place->first;
        pz = a.place->second;
    } else if (stat != kInvalidIndex) {
        px = 0.5f * (static_box.min.x + static_box.max.x);
        pz = 0.5f * (static_box.min.z + static_box.max.z);
    }
    if (stat != kInvalidIndex) {
        Ray down;
        down.org = vec3(px, static_box.max.y + 1.0f, pz);
        down.dir = vec3(0.0f, -1.0f, 0.0f);
        const SceneObject& so = rs.scene.objects()[stat];
        const Hit h = intersect_closest(so.blocks, down);
        ground = h.valid() ? down.org.y - h.t : static_box.min.y;
    }
    mat4 P = glm::translate(mat4(1.0f), vec3(px, ground - rest_box.min.z * s, pz));
    P = glm::rotate(P, glm::radians(a.yaw), vec3(0.0f, 1.0f, 0.0f));
    P = glm::scale(P, vec3(s));
    P = glm::rotate(P, glm::radians(-90.0f), vec3(1.0f, 0.0f, 0.0f));  // SMD z-up -> y-up
    if (stat != kInvalidIndex) rs.scene.add_instance(stat);
    rs.scene.add_instance(body, P);
    rs.scene.update_top_level();

    const double fps = a.fps > 0.0 ? a.fps : double(anim.fps > 0.0f ? anim.fps : 30.0f);
    const long frames = a.frames >= 0 ? a.frames : long(anim.frame_count());
    if (frames > 1 && !raykit_cli::animate_pattern_has_conversion(a.output))
        throw RaykitCliAnimateUsageError("OUT '" + a.output + "' has no %d conversion but " + std::to_string(frames) +
                                         " frames would be written to that one file (add %03d, or --frames 1)");
    auto matrices_at = [&](long k, double* anim_frame) {
        const double f = double(a.first + k) * double(anim.fps > 0.0f ? anim.fps : 30.0f) / fps;
        *anim_frame = f;
        return skin_matrices(skeleton, sample_frame(anim, f, Interpolation::slerp, WrapMode::loop));
    };

    // Camera: frames the placed bind pose (~3x its size), fixed for all frames.
    Camera cam;
    cam.width = a.width;
    cam.height = a.height;
    cam.vfov_degrees = a.fov;
    if (a.camera) {
        cam.position = a.camera->first;
        cam.target = a.camera->second;
    } else {
        AABB cb;  // the placed vertices' box (an instance's world box bounds its turned box: larger)
        for (const vec3& p : cm.positions) cb.grow(vec3(P * glm::vec4(p, 1.0f)));
        const vec3 c = 0.5f * (cb.min + cb.max), h = 1.5f * (cb.max - cb.min);
        AABB wide;
        wide.grow(c - h);
        wide.grow(c + h);
        cam = frame_scene(wide, a.width, a.height, a.fov, vec3(0.8f, 0.35f, 1.0f));
    }
    rs.lights = a.lights;
    if (rs.lights.empty()) rs.lights.push_back(default_key_light(cam));
    RenderSettings set;
    set.spp = a.spp;
    set.threads = a.threads;
    set.shade.max_depth = a.max_depth;
    set.time_stages = true;  // the table splits trace and shade
    FrameLoop loop(rs, set);

#if RAYKIT_CLI_HAVE_CL
    std::optional<raykit::cl::DeviceScene<SkinHook>> ds;
    std::optional<raykit::cl::DeviceRenderer> renderer;
    if (a.device_cl) {
        raykit::cl::DeviceRebuild rebuild;  // the CPU frame's policy, on the device
        rebuild.enabled = true;
        ds.emplace(raykit::cl::Device::shared(), rs.scene, rebuild,
                   a.nodes == "quantized" ? raykit::cl::NodeForm::quantized : raykit::cl::NodeForm::full);
        upload_skin(*ds, rs.scene, body, skin);
        renderer.emplace(*ds, rs.materials, rs.lights);
    }
#endif
    const bool on_device = a.device_cl;
    std::printf("device: %s   static triangles: %u   character: %zu vertices, %zu triangles, %zu bones\n",
                on_device ? "cl (skinning, refit, top level and render on the device)" : "cpu", static_tris,
                nv, cm.triangles.size(), model.bones.size());
    std::printf("%6s %8s %8s %8s %8s %8s %8s %8s %7s  %s\n", "frame", "anim_f", "interp", "skin", "refit", "top",
                "trace", "shade", "sah", "decision");
    double sum[6] = {0, 0, 0, 0, 0, 0};
    for (long k = 0; k < frames; ++k) {
        double af = 0.0;
        const auto t = clock::now();
        const std::vector<SkinMatrix> mats = matrices_at(k, &af);
        const double interp_ms = ms(t);
        Image img;
        FrameStats st;
        bool host_built = false;
        if (!on_device) {
            const SkinHook::Host host{skin.offsets, skin.links, mats};
            loop.update(vertex_hook(
                [&](std::uint32_t, const Vertex& v, std::uint32_t i) { return SkinHook::apply(v, i, {}, host); },
                a.threads));
            img = loop.render(cam);
            st = loop.last();
        }
#if RAYKIT_CLI_HAVE_CL
        else {
            const auto t_upload = clock::now();
            upload_skin_matrices(*ds, std::span<const SkinMatrix>(mats));
            const double upload_ms = ms(t_upload);
            const raykit::cl::FrameTimes ft = ds->update(raykit::cl::RefitMethod::one_pass, TopLevelUpdate::refit);
            raykit::cl::DeviceRenderStats drs;
            img = renderer->render(cam, set, &drs);
            st.ms.vertex = upload_ms + ft.vertex_ms;
            st.ms.refit = ft.refit_ms + ft.rebuild_ms;
            st.ms.top = ft.top_level_ms;
            st.worst_growth = ft.worst_growth;
            st.rebuilt = ft.rebuilt;
            host_built = ft.rebuilt_on_host != 0;
            st.ms.trace = drs.trace_ms + drs.shadow_ms;
            st.ms.shade = drs.shade_ms;
        }
#endif
        write_png(img, raykit_cli::animate_frame_name(a.output, a.first + k));
        std::printf("%6ld %8.2f %8.3f %8.3f %8.3f %8.3f %8.2f %8.2f %7.3f  %s\n", a.first + k, af, interp_ms,
                    st.ms.vertex, st.ms.refit, st.ms.top, st.ms.trace, st.ms.shade, st.worst_growth,
                    st.rebuilt ? (host_built ? "rebuild (host)" : "rebuild") : "refit");
        std::fflush(stdout);
        const double row[6] = {interp_ms, st.ms.vertex, st.ms.refit, st.ms.top, st.ms.trace, st.ms.shade};
        for (int i = 0; i < 6; ++i) sum[i] += row[i];
    }
    if (frames > 0) {
        std::printf("%6s %8s %8.3f %8.3f %8.3f %8.3f %8.2f %8.2f   (mean ms over %ld frames)\n", "mean", "", sum[0] / frames,
                    sum[1] / frames, sum[2] / frames, sum[3] / frames, sum[4] / frames, sum[5] / frames, frames);
    }
    return 0;
}

}  // namespace raykit_cli

inline int raykit_cli_animate(int argc, char** argv, int first_arg) {
    return raykit_cli::run_animate(raykit_cli::parse_animate_args(argc, argv, first_arg));  // checks OUT too
}
