// examples/cli_render.hpp — the `raykit render` command (CPU renderer front end).
//
//   raykit render SCENE.obj OUT.png [options]
//
//   int raykit_cli_render(int argc, char** argv, int first_arg);
//       Parses argv[first_arg ..] (SCENE.obj, OUT.png and the options of raykit_cli_render_usage()),
//       loads the scene, builds the BVH, renders on the CPU, writes OUT.png (OUT.pfm when the
//       name ends in .pfm) and, with --pfm, a float copy. Returns 0. Prints warnings (missing
//       textures, ...) and, for renders that take more than a second on a terminal, a progress
//       bar to stderr; prints a one-line summary to stdout (rays traced by kind, Mrays/s, ms per
//       stage) unless --quiet.
//       Throws RaykitCliRenderUsageError (a std::invalid_argument) for bad usage — the caller
//       should print raykit_cli_render_usage() and exit with status 2 — and other
//       std::exceptions (raykit::ParseError, std::runtime_error, ...) for everything else,
//       e.g. "--device cl: ... not available yet" in builds without OpenCL (RAYKIT_CLI_HAVE_CL).
//       --device cl renders on the OpenCL device (raykit/cl/render.hpp: every shader, --spp N with
//       the CPU's sample positions, so the image equals the CPU's) and reports the second frame's
//       time (the first builds kernels); --threads and --profile apply to the CPU only.
//   const char* raykit_cli_render_usage();
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

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/scene/build_options.hpp"
#if defined(RAYKIT_CLI_HAVE_CL)
#include "raykit/cl.hpp"
#include "raykit/cl/render.hpp"
#endif

/// Bad command-line usage of `raykit render`.
struct RaykitCliRenderUsageError : std::invalid_argument {
    using std::invalid_argument::invalid_argument;
};

inline const char* raykit_cli_render_usage() {
    return R"(usage:
  raykit render SCENE.obj OUT.png [options]

  --width W  --height H     image size (default 640 x 480; each 1..65536, at most 16777216 pixels)
  --spp N                   samples per pixel, stratified and jittered, 1..65536 (default 1)
  --max-depth D             reflection/refraction bounces, 0..1000 (default 5)
  --shader NAME             whitted (default), normals, depth, ao, debug-cost
  --camera EX EY EZ TX TY TZ  eye and target (default: frame the whole scene)
  --up UX UY UZ             camera up vector (default 0 1 0)
  --fov DEG                 vertical field of view, in (0, 180) (default 45)
  --light X Y Z R G B       point light (repeatable; default: a key light above-left of the camera);
                            colours (here, --sun, --ambient, --background) are finite and >= 0
  --sun DX DY DZ R G B      directional light travelling along D (repeatable)
  --ambient R G B           ambient light (default 0.1 0.1 0.1)
  --background R G B        colour of rays that miss (default 0 0 0)
  --no-shadows              no shadow rays
  --filter NAME             texture filter: bilinear (default), nearest
  --ao-samples N            ao: rays per sample, 1..4096 (default 16)
  --ao-radius R             ao: occlusion distance, > 0 (default 0.1 x scene diagonal)
  --seed S                  random seed (default 0)
  --no-jitter               samples at stratum centres (1 spp = pixel centres)
  --threads T               worker threads, 0..1024, 0 = all (default 0)
  --device cpu|cl           renderer (default cpu; cl: the OpenCL device, same image as the CPU)
  --builder NAME            BVH builder: sah (default), pairwise, sortaxis, ploc
  --leaf-size N             largest BVH leaf, >= 1 (default 12; leaf cost in blocks of 4)
  --pfm OUT.pfm             also write linear float RGB (PFM)
  --alpha                   write coverage as PNG alpha
  --profile                 split the render time into trace / shadow / shade thread time
  --quiet                   no progress bar, no summary
)";
}

namespace raykit::detail::cli_render {

/// argv[first ..] split into positional arguments and options with their values.
struct Parsed {
    std::vector<std::string> pos;
    std::vector<std::pair<std::string, std::vector<std::string>>> opts;  // in command-line order

    bool has(std::string_view k) const {
        for (auto& o : opts)
            if (o.first == k) return true;
        return false;
    }
    const std::vector<std::string>* last(std::string_view k) const {
        const std::vector<std::string>* v = nullptr;
        for (auto& o : opts)
            if (o.first == k) v = &o.second;
        return v;
    }
};

/// Number of values each option takes.
inline int arity(std::string_view k) {
    static const std::pair<std::string_view, int> table[] = {
        {"--width", 1},   {"--height", 1},     {"--spp", 1},        {"--max-depth", 1}, {"--shader", 1},
        {"--camera", 6},  {"--up", 3},         {"--fov", 1},        {"--light", 6},     {"--sun", 6},
        {"--ambient", 3}, {"--background", 3}, {"--no-shadows", 0}, {"--filter", 1},    {"--ao-samples", 1},
        {"--ao-radius", 1}, {"--seed", 1},     {"--no-jitter", 0},  {"--threads", 1},   {"--device", 1},
        {"--builder", 1}, {"--leaf-size", 1}, {"--pfm", 1}, {"--alpha", 0},
        {"--profile", 0}, {"--quiet", 0}};
    for (auto& [name, n] : table)
        if (name == k) return n;
    return -1;
}

inline Parsed parse(int argc, char** argv, int first) {
    Parsed p;
    for (int i = first; i < argc; ++i) {
        std::string a = argv[i];
        if (a.size() > 2 && a.rfind("--", 0) == 0) {
            const int n = arity(a);
            if (n < 0) throw RaykitCliRenderUsageError("unknown option " + a);
            if (i + n >= argc) throw RaykitCliRenderUsageError(a + " needs " + std::to_string(n) + " value(s)");
            std::vector<std::string> vals(argv + i + 1, argv + i + 1 + n);
            i += n;
            p.opts.emplace_back(std::move(a), std::move(vals));
        } else {
            p.pos.push_back(std::move(a));
        }
    }
    return p;
}

template <class T>
T number(const std::string& opt, const std::string& s) {
    std::string_view v(s);
    if (!v.empty() && v[0] == '+') v.remove_prefix(1);
    T out{};
    const auto [ptr, ec] = std::from_chars(v.data(), v.data() + v.size(), out);
    if (ec != std::errc() || ptr != v.data() + v.size() || v.empty())
        throw RaykitCliRenderUsageError(opt + " expects a number, got '" + s + "'");
    if constexpr (std::is_floating_point_v<T>)
        if (!std::isfinite(out)) throw RaykitCliRenderUsageError(opt + " expects a finite number, got '" + s + "'");
    return out;
}

template <class T>
T number_or(const Parsed& p, const std::string& opt, T def) {
    const auto* v = p.last(opt);
    return v ? number<T>(opt, (*v)[0]) : def;
}

inline vec3 vec3_at(const std::string& opt, const std::vector<std::string>& v, std::size_t first) {
    return vec3(number<float>(opt, v[first]), number<float>(opt, v[first + 1]), number<float>(opt, v[first + 2]));
}

/// Largest image `render` makes, in pixels (see the header comment).
inline constexpr std::uint64_t kMaxPixels = std::uint64_t(1) << 24;
/// Largest --width / --height.
inline constexpr std::uint64_t kMaxSide = 65536;
/// Largest --spp.
inline constexpr std::uint64_t kMaxSpp = 65536;
/// Largest --max-depth.
inline constexpr std::uint64_t kMaxDepth = 1000;

/// Parses `s`, the value of `opt`, as an integer in [lo, hi] into `out`; returns why it is not one
/// ("" when it is). Accepts "+N" and integral exponent forms ("1e6"); a negative or huge value is
/// out of range, never wrapped.
inline std::string count_problem(const std::string& opt, const std::string& s, std::uint64_t lo, std::uint64_t hi,
                                 std::uint64_t& out) {
    const std::string range = opt + " must be in " + std::to_string(lo) + ".." + std::to_string(hi) + ", got '" + s + "'";
    std::string_view v(s);
    if (!v.empty() && v[0] == '+') v.remove_prefix(1);
    std::uint64_t u = 0;
    const auto [p, ec] = std::from_chars(v.data(), v.data() + v.size(), u);
    if (!v.empty() && p == v.data() + v.size() && ec == std::errc()) {
        out = u;
        return u < lo || u > hi ? range : "";
    }
    if (!v.empty() && p == v.data() + v.size() && ec == std::errc::result_out_of_range) return range;
    double d = 0.0;  // "-3", "1e12", "2.5", "inf"
    const auto [q, ed] = std::from_chars(v.data(), v.data() + v.size(), d);
    if (v.empty() || q != v.data() + v.size() || (ed != std::errc() && ed != std::errc::result_out_of_range))
        return opt + " expects a number, got '" + s + "'";
    if (ed == std::errc::result_out_of_range) return range;  // "1e400": from_chars left d at 0
    if (std::isnan(d) || (std::isfinite(d) && d != std::floor(d))) return opt + " must be an integer, got '" + s + "'";
    if (!(d >= double(lo) && d <= double(hi))) return range;
    out = static_cast<std::uint64_t>(d);
    return out < lo || out > hi ? range : "";
}

/// Integer option `opt` in [lo, hi] (its last value), `def` when absent.
template <class T>
T count_or(const Parsed& p, const std::string& opt, T def, std::uint64_t lo, std::uint64_t hi) {
    const auto* v = p.last(opt);
    if (!v) return def;
    std::uint64_t out = 0;
    if (std::string why = count_problem(opt, (*v)[0], lo, hi, out); !why.empty()) throw RaykitCliRenderUsageError(why);
    return static_cast<T>(out);
}

/// A colour given on the command line: finite and not negative.
inline vec3 colour_at(const std::string& opt, const std::vector<std::string>& v, std::size_t first) {
    const vec3 c = vec3_at(opt, v, first);
    if (!(c.x >= 0.0f && c.y >= 0.0f && c.z >= 0.0f))
        throw RaykitCliRenderUsageError(opt + " colour must be finite and >= 0, got " + v[first] + " " + v[first + 1] +
                                        " " + v[first + 2]);
    return c;
}

/// A position given on the command line: inside math/limits.hpp's coordinate range (rays from
/// farther out could be answered wrongly by the triangle tests).
inline vec3 position_at(const std::string& opt, const std::vector<std::string>& v, std::size_t first) {
    const vec3 p = vec3_at(opt, v, first);
    if (!coordinate_in_range(p.x) || !coordinate_in_range(p.y) || !coordinate_in_range(p.z))
        throw RaykitCliRenderUsageError(opt + " position must lie within +-2^32 (4.29e9) on every axis, got " +
                                        v[first] + " " + v[first + 1] + " " + v[first + 2]);
    return p;
}

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
inline double write_outputs(const Image& img, const Parsed& p) {
    const auto t0 = std::chrono::steady_clock::now();
    const std::filesystem::path out = p.pos[1];
    PngOptions po;
    po.alpha = p.has("--alpha");
    if (out.extension() == ".pfm" || out.extension() == ".PFM") write_pfm(img, out);
    else write_png(img, out, po);
    if (auto* v = p.last("--pfm")) write_pfm(img, (*v)[0]);
    return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

/// A progress bar on stderr (when it is a terminal) hooked to `set.progress`.
inline void attach_progress(ProgressBar& bar, RenderSettings& set, bool quiet) {
    bar.enabled = !quiet && ProgressBar::stderr_is_terminal();
    set.progress = [&bar](std::size_t done, std::size_t total) { bar.update(done, total); };
}

}  // namespace raykit::detail::cli_render

inline int raykit_cli_render(int argc, char** argv, int first_arg) {
    using namespace raykit;
    namespace cr = raykit::detail::cli_render;
    using Clock = std::chrono::steady_clock;
    auto ms_since = [](Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); };

    const cr::Parsed p = cr::parse(argc, argv, first_arg);
    if (p.pos.size() != 2) throw RaykitCliRenderUsageError("render takes SCENE.obj OUT.png");
    const std::string device = p.last("--device") ? (*p.last("--device"))[0] : "cpu";
#if !defined(RAYKIT_CLI_HAVE_CL)
    if (device == "cl")
        throw std::runtime_error("--device cl: the OpenCL renderer is not available yet in this build (use --device cpu)");
#endif
    if (device != "cpu" && device != "cl") throw RaykitCliRenderUsageError("unknown --device '" + device + "' (known: cpu, cl)");

    const auto width = cr::count_or<std::uint32_t>(p, "--width", 640, 1, cr::kMaxSide);
    const auto height = cr::count_or<std::uint32_t>(p, "--height", 480, 1, cr::kMaxSide);
    if (std::uint64_t(width) * height > cr::kMaxPixels)
        throw RaykitCliRenderUsageError("the image must be at most " + std::to_string(cr::kMaxPixels) + " pixels, " +
                                        std::to_string(width) + " x " + std::to_string(height) + " is " +
                                        std::to_string(std::uint64_t(width) * height));
    RenderSettings set;
    set.spp = cr::count_or<unsigned>(p, "--spp", 1, 1, cr::kMaxSpp);
    set.shade.max_depth = cr::count_or<unsigned>(p, "--max-depth", 5, 0, cr::kMaxDepth);
    try {
        if (auto* v = p.last("--shader")) set.shade.shader = parse_shader((*v)[0]);
        if (auto* v = p.last("--filter")) set.shade.filter = parse_texture_filter((*v)[0]);
    } catch (const std::invalid_argument& e) {
        throw RaykitCliRenderUsageError(e.what());
    }
    if (auto* v = p.last("--ambient")) set.shade.ambient = cr::colour_at("--ambient", *v, 0);
    if (auto* v = p.last("--background")) set.shade.background = cr::colour_at("--background", *v, 0);
    set.shade.shadows = !p.has("--no-shadows");
    set.shade.ao_samples = cr::count_or<unsigned>(p, "--ao-samples", 16, 1, 4096);
    if (auto* v = p.last("--ao-radius")) {
        // 0 stays the library's "0.1 x scene diagonal": only the default may mean that
        const std::string& r = (*v)[0];
        float radius = 0.0f;
        const auto [q, ec] = std::from_chars(r.data(), r.data() + r.size(), radius);
        if (ec != std::errc() || q != r.data() + r.size() || !std::isfinite(radius) || !(radius > 0.0f))
            throw RaykitCliRenderUsageError("--ao-radius must be a finite number > 0, got '" + r + "'");
        set.shade.ao_radius = radius;
    }
    set.seed = cr::count_or<std::uint64_t>(p, "--seed", 0, 0, std::numeric_limits<std::uint64_t>::max());
    set.jitter = !p.has("--no-jitter");
    set.threads = cr::count_or<unsigned>(p, "--threads", 0, 0, kMaxThreads);
    set.time_stages = p.has("--profile");
    const bool quiet = p.has("--quiet");
    const float fov = cr::number_or<float>(p, "--fov", 45.0f);
    if (!(fov > 0.0f && fov < 180.0f)) throw RaykitCliRenderUsageError("--fov must be in (0, 180)");
    for (const auto& [k, v] : p.opts) {
        if (k == "--light") (void)cr::position_at(k, v, 0), (void)cr::colour_at(k, v, 3);
        if (k == "--sun") {
            const vec3 d = cr::vec3_at(k, v, 0);
            if (!(glm::length(d) > 0.0f) || !std::isfinite(glm::length(d)))
                throw RaykitCliRenderUsageError("--sun direction must be non-zero with a finite length");
            (void)cr::colour_at(k, v, 3);
        }
    }
    if (auto* v = p.last("--up")) {
        const vec3 u = cr::vec3_at("--up", *v, 0);
        if (!(glm::length(u) > 0.0f) || !std::isfinite(glm::length(u)))
            throw RaykitCliRenderUsageError("--up must be non-zero with a finite length");
    }
    // a camera made from flags alone is checked here, where its errors are usage errors
    if (auto* v = p.last("--camera")) {
        Camera c;
        c.position = cr::position_at("--camera", *v, 0);
        c.target = cr::position_at("--camera", *v, 3);
        if (auto* u = p.last("--up")) c.up = cr::vec3_at("--up", *u, 0);
        c.vfov_degrees = fov;
        c.width = width;
        c.height = height;
        try {
            (void)c.frame();
        } catch (const std::invalid_argument& e) {
            throw RaykitCliRenderUsageError(std::string("--camera/--up: ") + e.what());
        }
    }

    BuildOptions build = render_build_options();
    try {
        if (auto* v = p.last("--builder")) build.builder = BuildOptions::parse_builder((*v)[0]);
    } catch (const std::invalid_argument& e) {
        throw RaykitCliRenderUsageError(e.what());
    }
    build.leaf.max_leaf_size = cr::count_or<unsigned>(p, "--leaf-size", 12, 1, std::numeric_limits<unsigned>::max());
    build.threads = set.threads;

    // ---- every output writable, the scene a file, before any work
    cr::check_writable(p.pos[1]);
    if (auto* v = p.last("--pfm")) cr::check_writable((*v)[0]);
    raykit::detail::check_text_file(p.pos[0]);  // the scene a regular file, before any work

    // ---- load, build, materials
    auto t0 = Clock::now();
    Mesh mesh = load_obj(p.pos[0]);
    const double load_ms = ms_since(t0);
    for (const std::string& w : mesh.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    RenderScene rs = prepare_render_scene(std::move(mesh), build);
    for (const std::string& w : rs.materials[0].warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());

    // ---- camera and lights
    Camera cam;
    if (auto* v = p.last("--camera")) {
        cam.position = cr::vec3_at("--camera", *v, 0);
        cam.target = cr::vec3_at("--camera", *v, 3);
        cam.up = p.last("--up") ? cr::vec3_at("--up", *p.last("--up"), 0) : vec3(0.0f, 1.0f, 0.0f);
        cam.vfov_degrees = fov;
        cam.width = width;
        cam.height = height;
    } else {
        cam = frame_scene(rs.bounds(), width, height, fov);
        if (auto* v = p.last("--up")) cam.up = cr::vec3_at("--up", *v, 0);
    }
    try {
        (void)cam.frame();
    } catch (const std::invalid_argument& e) {
        // the flags were checked above: what fails now comes from the scene (e.g. bounds so
        // large that the framing camera is not finite), not a bad flag, so no usage text
        throw std::runtime_error(std::string("cannot frame ") + p.pos[0] + ": " + e.what());
    }
    for (const auto& [k, v] : p.opts) {
        if (k == "--light") rs.lights.push_back(Light::point(cr::vec3_at(k, v, 0), cr::vec3_at(k, v, 3)));
        if (k == "--sun") rs.lights.push_back(Light::directional(cr::vec3_at(k, v, 0), cr::vec3_at(k, v, 3)));
    }
    if (rs.lights.empty()) rs.lights.push_back(default_key_light(cam));

#if defined(RAYKIT_CLI_HAVE_CL)
    // ---- render on the OpenCL device (raykit/cl/render.hpp): the same shaders and samples as the
    // CPU. A first frame (one sample per pixel) builds the program and lets PoCL compile its
    // kernels; the full frame after it is the one timed ("frame").
    if (device == "cl") {
        raykit::cl::Device& dev = raykit::cl::Device::shared();
        auto tu = Clock::now();
        raykit::cl::DeviceRenderer renderer(dev, rs.view());
        const double upload_ms = ms_since(tu);
        raykit::cl::DeviceRenderStats first, st;
        RenderSettings warm = set;
        warm.spp = 1;
        (void)renderer.render(cam, warm, &first);
        cr::ProgressBar bar;
        cr::attach_progress(bar, set, quiet);
        const Image img = renderer.render(cam, set, &st);
        bar.finish();
        const double write_ms = cr::write_outputs(img, p);
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
    const double write_ms = cr::write_outputs(img, p);

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
