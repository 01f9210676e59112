// examples/cli_render.hpp — the `raykit render` command (CPU renderer front end).
//
//   raykit render SCENE.obj OUT.png [options]
//
//   void raykit_cli::add_render_options(CLI::App&, RenderArgs&);
//       The command's arguments and options on a CLI11 app (raykit.cpp's `render` subcommand):
//       SCENE.obj, OUT.png and the flags `raykit render --help` lists, each with its range.
//   int raykit_cli::run_render(const RenderArgs&);
//       Checks what the parser cannot (image size, colours, positions, the camera the flags
//       make: raykit_cli::UsageError), every output writable and the scene a file, then loads
//       the scene, builds the BVH, renders on the CPU, writes OUT.png (OUT.pfm when the name
//       ends in .pfm) and, with --pfm, a float copy. Returns 0. Prints warnings (missing
//       textures, ...) and, for renders that take more than a second on a terminal, a progress
//       bar to stderr; prints a one-line summary to stdout (rays traced by kind, Mrays/s, ms per
//       stage) unless --quiet. Other failures are other std::exceptions (raykit::ParseError,
//       std::runtime_error, ...), e.g. "--device cl: ... not available yet" in builds without
//       OpenCL (RAYKIT_CLI_HAVE_CL).
//       --device cl renders on the OpenCL device (raykit/cl/render.hpp: every shader, --spp N with
//       the CPU's sample positions, so the image equals the CPU's) and reports the second frame's
//       time (the first builds kernels); --threads and --profile apply to the CPU only; --nodes
//       quantized walks quantized nodes there (the same image).
//   int raykit_cli_render(int argc, char** argv, int first_arg);
//       Both for argv[first_arg ..] (the arguments after `render`); a parse error is a UsageError.
//
// Defaults: no --camera frames the whole scene (bounding-sphere fit, looking from front-right-
// above); no --light/--sun places raykit::default_key_light (a white point light above-left of
// the camera).
//
// Bounds (issue 12): every numeric flag has a range and anything outside it is a usage error
// before any work. The image is at most 16,777,216 pixels (4096 x 4096): its float buffer is
// 16 bytes a pixel, so that is 256 MiB, and 65536 x 65536 asked for 64 GiB and ended in a bare
// std::bad_alloc. --ao-samples is capped at 4096 like --spp at 65536 (4e9 ran for minutes).
// OUT.png and --pfm are checked writable (folder exists, not a folder themselves) before the
// scene is loaded, so a bad --pfm no longer leaves a PNG behind.
#pragma once

#include <algorithm>
#include <charconv>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <limits>
#include <stdexcept>
#include <string>
#include <string_view>
#include <system_error>
#include <type_traits>
#include <utility>
#include <vector>

#if defined(__unix__) || defined(__APPLE__)
#include <unistd.h>
#endif

#include "cli_common.hpp"
#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/scene/build_options.hpp"
#if defined(RAYKIT_CLI_HAVE_CL)
#include "raykit/cl.hpp"
#include "raykit/cl/render.hpp"
#endif

/// Bad command-line usage of `raykit render` (the one raykit_cli::UsageError; this name is kept
/// for code written against the hand-written parser it replaced).
using RaykitCliRenderUsageError = raykit_cli::UsageError;

namespace raykit_cli {

/// `raykit render`'s arguments, as add_render_options fills them.
struct RenderArgs {
    std::string scene, out, pfm;
    std::uint32_t width = 640, height = 480;
    unsigned spp = 1, max_depth = 5, ao_samples = 16, threads = 0, leaf_size = 12;
    std::string shader = "whitted", filter = "bilinear", device = "cpu", builder = "sah", nodes = "full";
    std::vector<float> camera, up, ambient, background;
    std::vector<float> lights, suns;  ///< 6 values per --light / --sun, in command-line order
    float fov = 45.0f;
    float ao_radius = 0.0f;  ///< 0: the library's default (0.1 x scene diagonal)
    std::uint64_t seed = 0;
    bool no_shadows = false, no_jitter = false, alpha = false, profile = false, quiet = false;
};

}  // namespace raykit_cli

namespace raykit::detail::cli_render {
/// Largest image `render` makes, in pixels (see the header comment).
inline constexpr std::uint64_t kMaxPixels = std::uint64_t(1) << 24;
/// Largest --width / --height.
inline constexpr std::uint64_t kMaxSide = 65536;
/// Largest --spp.
inline constexpr std::uint64_t kMaxSpp = 65536;
/// Largest --max-depth.
inline constexpr std::uint64_t kMaxDepth = 1000;

/// "x y z" with %g.
inline std::string text3(const vec3& v) {
    char buf[96];
    std::snprintf(buf, sizeof buf, "%g %g %g", double(v.x), double(v.y), double(v.z));
    return buf;
}

/// A colour given on the command line (values checked finite by the parser): not negative.
inline vec3 colour_at(const std::string& opt, const std::vector<float>& v, std::size_t first) {
    const vec3 c(v[first], v[first + 1], v[first + 2]);
    if (!(c.x >= 0.0f && c.y >= 0.0f && c.z >= 0.0f))
        throw raykit_cli::UsageError(opt + " colour must be finite and >= 0, got " + text3(c));
    return c;
}

/// A position given on the command line: inside math/limits.hpp's coordinate range (rays from
/// farther out could be answered wrongly by the triangle tests).
inline vec3 position_at(const std::string& opt, const std::vector<float>& v, std::size_t first) {
    const vec3 p(v[first], v[first + 1], v[first + 2]);
    if (!coordinate_in_range(p.x) || !coordinate_in_range(p.y) || !coordinate_in_range(p.z))
        throw raykit_cli::UsageError(opt + " position must lie within +-2^32 (4.29e9) on every axis, got " +
                                     text3(p));
    return p;
}

inline vec3 vec3_at(const std::vector<float>& v, std::size_t first) { return vec3(v[first], v[first + 1], v[first + 2]); }

/// Throws std::runtime_error unless `path` can be written: its folder exists and is writable,
/// and `path` is not a folder (issue 12: every output is checked before any work).
inline void check_writable(const std::filesystem::path& path) {
    namespace fs = std::filesystem;
    std::error_code ec;
    if (path.empty()) throw std::runtime_error("empty output file name");
    if (fs::is_directory(path, ec)) throw std::runtime_error("cannot write " + path.string() + ": it is a folder");
    const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
    if (!fs::is_directory(dir, ec))
        throw std::runtime_error("cannot write " + path.string() + ": folder " + dir.string() + " does not exist");
#if defined(__unix__) || defined(__APPLE__)
    if (::access(dir.c_str(), W_OK | X_OK) != 0)
        throw std::runtime_error("cannot write " + path.string() + ": folder " + dir.string() + " is not writable");
    if (fs::exists(path, ec) && ::access(path.c_str(), W_OK) != 0)
        throw std::runtime_error("cannot write " + path.string() + ": permission denied");
#endif
}

/// Progress bar on stderr: appears once a render has run for a second, updates at most 10 times
/// a second, only when stderr is a terminal.
struct ProgressBar {
    std::chrono::steady_clock::time_point start = std::chrono::steady_clock::now(), last{};
    bool shown = false;
    bool enabled = true;

    static bool stderr_is_terminal() {
#if defined(__unix__) || defined(__APPLE__)
        return isatty(fileno(stderr)) != 0;
#else
        return false;
#endif
    }
    void update(std::size_t done, std::size_t total) {
        if (!enabled || total == 0) return;
        const auto now = std::chrono::steady_clock::now();
        if (now - start < std::chrono::seconds(1)) return;
        if (shown && done < total && now - last < std::chrono::milliseconds(100)) return;
        last = now;
        shown = true;
        constexpr int kWidth = 40;
        const double f = double(done) / double(total);
        const int n = int(f * kWidth);
        const double elapsed = std::chrono::duration<double>(now - start).count();
        const double eta = f > 0.0 ? elapsed * (1.0 - f) / f : 0.0;
        std::fprintf(stderr, "\r[%.*s%.*s] %3d%%  %.1f s left ", n, "########################################",
                     kWidth - n, "........................................", int(f * 100.0 + 0.5), eta);
        std::fflush(stderr);
    }
    void finish() {
        if (shown) std::fputc('\n', stderr);
    }
};

/// Writes OUT.png (or .pfm) and the optional --pfm copy; returns the ms it took.
inline double write_outputs(const Image& img, const raykit_cli::RenderArgs& a) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::filesystem::path out = a.out;
    PngOptions po;
    po.alpha = a.alpha;
    if (out.extension() == ".pfm" || out.extension() == ".PFM") write_pfm(img, out);
    else write_png(img, out, po);
    if (!a.pfm.empty()) write_pfm(img, a.pfm);
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// A progress bar on stderr (when it is a terminal) hooked to `set.progress`.
inline void attach_progress(ProgressBar& bar, RenderSettings& set, bool quiet) {
    bar.enabled = !quiet && ProgressBar::stderr_is_terminal();
    set.progress = [&bar](std::size_t done, std::size_t total) { bar.update(done, total); };
}

}  // namespace raykit::detail::cli_render

namespace raykit_cli {

/// The options of `raykit render` on `app` (a subcommand, or an app of its own), filling `a`.
/// --width and --height, the same on every command that writes images.
template <class W, class H>
void add_image_size_options(CLI::App& app, W& width, H& height) {
    namespace cr = raykit::detail::cli_render;
    app.add_option("--width", width, "image width, 1..65536 (default 640; at most 16777216 pixels in all)")
        ->type_name("W")
        ->transform(count_in(1, cr::kMaxSide));
    app.add_option("--height", height, "image height, 1..65536 (default 480)")
        ->type_name("H")
        ->transform(count_in(1, cr::kMaxSide));
}
/// --fov, the same on every command with a camera.
template <class F>
void add_fov_option(CLI::App& app, F& fov) {
    app.add_option("--fov", fov, "vertical field of view in degrees, in (0, 180) (default 45)")
        ->type_name("DEG")
        ->check(real_in([](double d) { return d > 0.0 && d < 180.0; }, "must be in (0, 180)"));
}
/// --threads, the same on every command that renders.
template <class T>
void add_threads_option(CLI::App& app, T& threads) {
    app.add_option("--threads", threads, "worker threads, 0..1024, 0 = all (default 0)")
        ->type_name("T")
        ->transform(count_in(0, raykit::kMaxThreads));
}

/// --builder, the same on every command that builds a tree.
inline void add_builder_option(CLI::App& app, std::string& builder) {
    app.add_option("--builder", builder, "BVH builder: sah (binned SAH, default), pairwise, sortaxis, ploc")
        ->type_name("")
        ->check(CLI::IsMember({"sah", "pairwise", "sortaxis", "ploc"}));
}
/// --nodes, the same on every command that can run on the device (checked against --device by
/// check_nodes_option).
inline void add_nodes_option(CLI::App& app, std::string& nodes) {
    app.add_option("--nodes", nodes,
                   "the device walk's nodes: full (default) or quantized (104 bytes a node, the same image; "
                   "with --device cl)")
        ->type_name("")
        ->check(CLI::IsMember({"full", "quantized"}));
}
/// --nodes quantized without --device cl is a usage error.
inline void check_nodes_option(const std::string& nodes, bool device_cl) {
    if (nodes == "quantized" && !device_cl) throw UsageError("--nodes quantized: only with --device cl");
}
/// --leaf-size (the largest leaf), with the command's own default in `help`; returns the option.
template <class L>
CLI::Option* add_leaf_size_option(CLI::App& app, L& leaf_size, const std::string& help) {
    return app.add_option("--leaf-size", leaf_size, help)
        ->type_name("N")
        ->transform(count_in(1, std::numeric_limits<unsigned>::max()));
}

inline void add_render_options(CLI::App& app, RenderArgs& a) {
    namespace cr = raykit::detail::cli_render;
    using MOP = CLI::MultiOptionPolicy;
    app.add_option("SCENE.obj", a.scene, "the scene (OBJ, with its MTL and textures)")->required()->type_name("");
    app.add_option("OUT.png", a.out, "the image: PNG, or PFM (linear float RGB) when the name ends in .pfm")
        ->required()
        ->type_name("");
    add_image_size_options(app, a.width, a.height);
    app.add_option("--spp", a.spp, "samples per pixel, stratified and jittered, 1..65536 (default 1)")
        ->type_name("N")
        ->transform(count_in(1, cr::kMaxSpp));
    app.add_option("--max-depth", a.max_depth, "reflection/refraction bounces, 0..1000 (default 5)")
        ->type_name("D")
        ->transform(count_in(0, cr::kMaxDepth));
    app.add_option("--shader", a.shader, "whitted (default), normals, depth, ao, debug-cost")
        ->type_name("")
        ->check(CLI::IsMember({"whitted", "normals", "depth", "ao", "debug-cost"}));
    app.add_option("--camera", a.camera, "eye and target (default: frame the whole scene)")
        ->type_name("EX EY EZ TX TY TZ")
        ->expected(6)
        ->check(finite());
    app.add_option("--up", a.up, "camera up vector (default 0 1 0)")->type_name("UX UY UZ")->expected(3)->check(finite());
    add_fov_option(app, a.fov);
    app.add_option("--light", a.lights,
                   "point light, repeatable (default: a key light above-left of the camera); colours here and "
                   "in --sun, --ambient, --background are >= 0")
        ->type_name("X Y Z R G B")
        ->expected(6)
        ->multi_option_policy(MOP::TakeAll)
        ->check(finite());
    app.add_option("--sun", a.suns, "directional light travelling along D, repeatable")
        ->type_name("DX DY DZ R G B")
        ->expected(6)
        ->multi_option_policy(MOP::TakeAll)
        ->check(finite());
    app.add_option("--ambient", a.ambient, "ambient light (default 0.1 0.1 0.1)")
        ->type_name("R G B")
        ->expected(3)
        ->check(finite());
    app.add_option("--background", a.background, "colour of rays that miss (default 0 0 0)")
        ->type_name("R G B")
        ->expected(3)
        ->check(finite());
    app.add_flag("--no-shadows", a.no_shadows, "no shadow rays");
    app.add_option("--filter", a.filter, "texture filter: bilinear (default), nearest")
        ->type_name("")
        ->check(CLI::IsMember({"bilinear", "nearest"}));
    app.add_option("--ao-samples", a.ao_samples, "ao: rays per sample, 1..4096 (default 16)")
        ->type_name("N")
        ->transform(count_in(1, 4096));
    app.add_option("--ao-radius", a.ao_radius, "ao: occlusion distance, > 0 (default 0.1 x scene diagonal)")
        ->type_name("R")
        ->check(real_in([](double d) { return d > 0.0; }, "must be a finite number > 0"));
    app.add_option("--seed", a.seed, "random seed (default 0)")
        ->type_name("S")
        ->transform(count_in(0, std::numeric_limits<std::uint64_t>::max()));
    app.add_flag("--no-jitter", a.no_jitter, "samples at stratum centres (1 spp = pixel centres)");
    add_threads_option(app, a.threads);
    app.add_option("--device", a.device, "renderer: cpu (default) or cl (the OpenCL device, the CPU's image)")
        ->type_name("")
        ->check(CLI::IsMember({"cpu", "cl"}));
    add_nodes_option(app, a.nodes);
    add_builder_option(app, a.builder);
    add_leaf_size_option(app, a.leaf_size, "largest BVH leaf, >= 1 (default 12; leaf cost in blocks of 4)");
    app.add_option("--pfm", a.pfm, "also write linear float RGB (PFM)")->type_name("OUT.pfm");
    app.add_flag("--alpha", a.alpha, "write coverage as PNG alpha");
    app.add_flag("--profile", a.profile, "split the render time into trace / shadow / shade thread time");
    app.add_flag("--quiet", a.quiet, "no progress bar, no summary");
}

/// Runs `raykit render` with parsed arguments: checks what the parser cannot (a UsageError),
/// every output writable and the scene a file, then loads, builds, renders and writes. Returns 0.
inline int run_render(const RenderArgs& a) {
    using namespace raykit;
    namespace cr = raykit::detail::cli_render;
    using Clock = std::chrono::steady_clock;
    auto ms_since = [](Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); };

    check_nodes_option(a.nodes, a.device == "cl");
#if !defined(RAYKIT_CLI_HAVE_CL)
    if (a.device == "cl")
        throw std::runtime_error("--device cl: the OpenCL renderer is not available yet in this build (use --device cpu)");
#endif
    const std::uint32_t width = a.width, height = a.height;
    if (std::uint64_t(width) * height > cr::kMaxPixels)
        throw UsageError("the image must be at most " + std::to_string(cr::kMaxPixels) + " pixels, " +
                         std::to_string(width) + " x " + std::to_string(height) + " is " +
                         std::to_string(std::uint64_t(width) * height));
    RenderSettings set;
    set.spp = a.spp;
    set.shade.max_depth = a.max_depth;
    try {
        set.shade.shader = parse_shader(a.shader);
        set.shade.filter = parse_texture_filter(a.filter);
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    if (!a.ambient.empty()) set.shade.ambient = cr::colour_at("--ambient", a.ambient, 0);
    if (!a.background.empty()) set.shade.background = cr::colour_at("--background", a.background, 0);
    set.shade.shadows = !a.no_shadows;
    set.shade.ao_samples = a.ao_samples;
    set.shade.ao_radius = a.ao_radius;  // 0 (the default only: the flag takes > 0) is 0.1 x scene diagonal
    set.seed = a.seed;
    set.jitter = !a.no_jitter;
    set.threads = a.threads;
    set.time_stages = a.profile;
    const bool quiet = a.quiet;
    const float fov = a.fov;
    for (std::size_t i = 0; i + 6 <= a.lights.size(); i += 6)
        (void)cr::position_at("--light", a.lights, i), (void)cr::colour_at("--light", a.lights, i + 3);
    for (std::size_t i = 0; i + 6 <= a.suns.size(); i += 6) {
        const vec3 d = cr::vec3_at(a.suns, i);
        if (!(glm::length(d) > 0.0f) || !std::isfinite(glm::length(d)))
            throw UsageError("--sun direction must be non-zero with a finite length");
        (void)cr::colour_at("--sun", a.suns, i + 3);
    }
    if (!a.up.empty()) {
        const vec3 u = cr::vec3_at(a.up, 0);
        if (!(glm::length(u) > 0.0f) || !std::isfinite(glm::length(u)))
            throw UsageError("--up must be non-zero with a finite length");
    }
    // a camera made from flags alone is checked here, where its errors are usage errors
    if (!a.camera.empty()) {
        Camera c;
        c.position = cr::position_at("--camera", a.camera, 0);
        c.target = cr::position_at("--camera", a.camera, 3);
        if (!a.up.empty()) c.up = cr::vec3_at(a.up, 0);
        c.vfov_degrees = fov;
        c.width = width;
        c.height = height;
        try {
            (void)c.frame();
        } catch (const std::invalid_argument& e) {
            throw UsageError(std::string("--camera/--up: ") + e.what());
        }
    }

    BuildOptions build = render_build_options();
    try {
        build.builder = BuildOptions::parse_builder(a.builder);
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    build.leaf.max_leaf_size = a.leaf_size;
    build.threads = set.threads;

    // ---- every output writable, the scene a file, before any work
    cr::check_writable(a.out);
    if (!a.pfm.empty()) cr::check_writable(a.pfm);
    raykit::detail::check_text_file(a.scene);  // the scene a regular file, before any work

    // ---- load, build, materials
    auto t0 = Clock::now();
    Mesh mesh = load_obj(a.scene);
    const double load_ms = ms_since(t0);
    for (const std::string& w : mesh.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    RenderScene rs = prepare_render_scene(std::move(mesh), build);
    for (const std::string& w : rs.materials[0].warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());

    // ---- camera and lights
    Camera cam;
    if (!a.camera.empty()) {
        cam.position = cr::vec3_at(a.camera, 0);
        cam.target = cr::vec3_at(a.camera, 3);
        cam.up = a.up.empty() ? vec3(0.0f, 1.0f, 0.0f) : cr::vec3_at(a.up, 0);
        cam.vfov_degrees = fov;
        cam.width = width;
        cam.height = height;
    } else {
        cam = frame_scene(rs.bounds(), width, height, fov);
        if (!a.up.empty()) cam.up = cr::vec3_at(a.up, 0);
    }
    try {
        (void)cam.frame();
    } catch (const std::invalid_argument& e) {
        // the flags were checked above: what fails now comes from the scene (e.g. bounds so
        // large that the framing camera is not finite), not a bad flag, so no usage text
        throw std::runtime_error(std::string("cannot frame ") + a.scene + ": " + e.what());
    }
    for (std::size_t i = 0; i + 6 <= a.lights.size(); i += 6)
        rs.lights.push_back(Light::point(cr::vec3_at(a.lights, i), cr::vec3_at(a.lights, i + 3)));
    for (std::size_t i = 0; i + 6 <= a.suns.size(); i += 6)
        rs.lights.push_back(Light::directional(cr::vec3_at(a.suns, i), cr::vec3_at(a.suns, i + 3)));
    if (rs.lights.empty()) rs.lights.push_back(default_key_light(cam));

#if defined(RAYKIT_CLI_HAVE_CL)
    // ---- render on the OpenCL device (raykit/cl/render.hpp): the same shaders and samples as the
    // CPU. A first frame (one sample per pixel) builds the program and lets PoCL compile its
    // kernels; the full frame after it is the one timed ("frame").
    if (a.device == "cl") {
        raykit::cl::Device& dev = raykit::cl::Device::shared();
        auto tu = Clock::now();
        raykit::cl::DeviceRenderer renderer(
            dev, rs.view(), a.nodes == "quantized" ? raykit::cl::NodeForm::quantized : raykit::cl::NodeForm::full);
        const double upload_ms = ms_since(tu);
        raykit::cl::DeviceRenderStats first, st;
        RenderSettings warm = set;
        warm.spp = 1;
        (void)renderer.render(cam, warm, &first);
        cr::ProgressBar bar;
        cr::attach_progress(bar, set, quiet);
        const Image img = renderer.render(cam, set, &st);
        bar.finish();
        const double write_ms = cr::write_outputs(img, a);
        if (!quiet)
            std::printf("raykit render: %ux%u, %u spp, %s, device %s: %llu rays (primary %llu, shadow %llu, "
                        "continuation %llu), %u bounces, peak queue %zu rays, %.2f Mrays/s; ms: load %.1f, build %.1f, "
                        "materials %.1f, upload %.1f, first frame %.1f, frame %.1f (device: camera %.1f, trace %.1f, "
                        "shade %.1f, shadow %.1f; resolve %.1f), write %.1f\n",
                        width, height, set.spp, shader_name(set.shade.shader), dev.info().name.c_str(),
                        (unsigned long long)st.total(), (unsigned long long)st.primary,
                        (unsigned long long)st.shadow, (unsigned long long)st.continuation, st.bounces, st.peak_queue,
                        st.render_ms > 0.0 ? double(st.total()) / (st.render_ms * 1e3) : 0.0, load_ms, rs.build_ms,
                        rs.materials_ms, upload_ms, first.render_ms, st.render_ms, st.camera_ms, st.trace_ms,
                        st.shade_ms, st.shadow_ms, st.resolve_ms, write_ms);
        return 0;
    }
#endif

    // ---- render
    cr::ProgressBar bar;
    cr::attach_progress(bar, set, quiet);
    RenderStats st;
    const Image img = render_cpu(rs.view(), cam, set, &st);
    bar.finish();
    const double write_ms = cr::write_outputs(img, a);

    if (!quiet) {
        const RayCounts& r = st.rays;
        std::printf("raykit render: %ux%u, %u spp, %s, %u thread%s: %llu rays (primary %llu, shadow %llu, "
                    "reflection %llu, refraction %llu, ao %llu), %.2f Mrays/s; ms: load %.1f, build %.1f, "
                    "materials %.1f, setup %.2f, render %.1f, resolve %.2f, write %.1f",
                    width, height, set.spp, shader_name(set.shade.shader), st.threads, st.threads == 1 ? "" : "s",
                    (unsigned long long)r.total(), (unsigned long long)r.primary, (unsigned long long)r.shadow,
                    (unsigned long long)r.reflection, (unsigned long long)r.refraction, (unsigned long long)r.ao,
                    st.mrays_per_second(), load_ms, rs.build_ms, rs.materials_ms, st.setup_ms, st.render_ms,
                    st.resolve_ms, write_ms);
        if (set.time_stages)
            std::printf("; thread-ms: trace %.1f, shadow %.1f, shade %.1f", st.trace_thread_ms, st.shadow_thread_ms,
                        st.shade_thread_ms);
        std::printf("\n");
    }
    return 0;
}

}  // namespace raykit_cli

/// `raykit render` from argv[first_arg ..] (the arguments after `render`): parses with the CLI's
/// own options and runs. Throws raykit_cli::UsageError for bad usage (exit code 2), other
/// std::exceptions for everything else (exit code 1).
inline int raykit_cli_render(int argc, char** argv, int first_arg) {
    raykit_cli::RenderArgs a;
    CLI::App app{"", "raykit render"};
    raykit_cli::add_render_options(app, a);
    raykit_cli::parse_args(app, argc, argv, first_arg);
    return raykit_cli::run_render(a);
}
