// raykit — command line front end of the raykit library.
//
//   raykit info SCENE.obj [--builder sah] [--leaf N] [--threads T] [--json]
//   raykit trace SCENE.obj RAYS.txt HITS.txt [--any-hit] [--test watertight|mt|thesis] [...]
//   raykit check SCENE.obj [--rays N] [--seed S] [...]
//   raykit generate torus|icosphere|soup OUT.obj [--tris N] [--seed S]
//   raykit skin REF.smd [ANIM.smd FRAME] [--interp slerp|euler] [--device cpu|cl]
//   raykit animate REF.smd ANIM.smd OUT_%03d.png [--scene STATIC.obj] [--frames N] [...]
//   raykit render SCENE.obj OUT.png [...]
//
// Every error ends with a one-line reason on stderr and a non-zero exit:
// 2 for bad usage (after the usage text), 1 for anything else (no usage text:
// a library error is never taken for a bad flag). Out of memory is one line
// too, "raykit: error: out of memory (...)", never a bare std::bad_alloc.
//
// Bounds (issue 12): every numeric flag has a range, checked before any work;
// outputs are checked writable and scenes regular files before anything is
// loaded. check --rays is at most 1,000,000 (its time is rays x triangles, the
// brute-force reference: 100,000 rays on 1,280 triangles took 2.4 s here) and
// generate --tris at most 1,000,000 (soup, the largest file per triangle:
// 139 MB written in 4 s on a loaded 2-core machine; 10^7 took 76 s and 1.4 GB).
// --threads is at most raykit::kMaxThreads (1024); 2^31 once overflowed a
// shift in the binned SAH and hung.
#include <charconv>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <map>
#include <limits>
#include <new>
#include <random>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/io/obj_write.hpp"
#include "raykit/io/rays.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/generate.hpp"

#include "cli_animate.hpp"
#include "cli_render.hpp"
#include "cli_skin.hpp"
#if RAYKIT_CLI_HAVE_CL
#include "cli_device.hpp"
#endif

namespace {

using namespace raykit;
using Clock = std::chrono::steady_clock;

struct UsageError : std::runtime_error {
    using std::runtime_error::runtime_error;
};

constexpr const char* kUsage = R"(usage:
  raykit info SCENE.obj [--builder NAME] [--window W] [--axis A] [--metric M] [--pairing P] [--radius R] [--optimize on|off]
                        [--leaf N] [--leaf-block B] [--threads T] [--json]
  raykit info --device         lists OpenCL platforms and devices, and which one raykit picks and why
  raykit animate-test SCENE.obj [--frames N]   a "wave" vertex hook moves a dynamic copy each frame (N in 1..1000): refit, TLAS, trace, device and CPU
  raykit trace SCENE.obj RAYS.txt HITS.txt [--builder NAME] [--any-hit] [--test watertight|mt|thesis] [--threads T] [--device cpu|cl]
  raykit check SCENE.obj [--rays N] [--seed S] [--builder NAME] [--test watertight|mt|thesis] [--threads T]
  raykit generate torus|icosphere|soup OUT.obj [--tris N] [--seed S]
                 N in 1..1000000 (default 100000): about N for the torus, the largest icosphere level within N
  raykit skin REF.smd [ANIM.smd FRAME] [--interp slerp|euler] [--device cpu|cl]
  raykit animate REF.smd ANIM.smd OUT_%03d.png [--scene STATIC.obj] [--frames N] [--fps F] [--device cpu|cl]
                 ...render flags (raykit animate alone lists all options)
  raykit render SCENE.obj OUT.png [--width W] [--height H] [--spp N] [--max-depth D] [--shader NAME]
                [--camera EX EY EZ TX TY TZ] [--up UX UY UZ] [--fov DEG] [--light X Y Z R G B]... (raykit render alone lists all options)

  --rays N         check: random rays, 1..1000000 (default 2000)
  --builder NAME   BVH builder: sah (binned SAH, default), pairwise, sortaxis, ploc
  --leaf N         largest leaf (primitives), default 8
  --leaf-block B   SAH counts leaves in blocks of B primitives (1 default; 4 with --leaf 12 suits
                   the CPU trace, which tests leaves 4 triangles at a time)
  --window W       sortaxis: candidates per element, 1..4096, default 2 (the thesis used 6)
  --axis A         sortaxis: x | longest | morton (default)
  --metric M       pairwise: centre (default) | area; sortaxis: area (default) | centre
  --pairing P      sortaxis: mutual (default: mutual nearest neighbours) | greedy (the thesis's rule)
  --radius R       ploc: neighbours searched each way, 1..1024, default 4
  --optimize on|off  sortaxis, ploc: post-pass (reinsertion + treelets); default on for ploc, off for sortaxis
  --threads T      worker threads, 0..1024, 0 = all (default)
  --test NAME      ray/triangle test: watertight (default), mt (Moller-Trumbore), thesis
skin: prints the skinned position of every triangle corner (triangles in file order), one "x y z" per line;
      FRAME may be fractional; without ANIM, the bind pose.
RAYS.txt: one ray per line, "ox oy oz dx dy dz tmin tmax" (tmax may be inf).
HITS.txt: one line per ray, "prim t u v" ("-1 0 0 0" on a miss); with --any-hit "1" or "0".
)";

/// Parsed "--flag value" options plus positional arguments.
struct Args {
    std::vector<std::string> pos;
    std::map<std::string, std::string> opt;
    std::vector<std::string> flags;

    Args(int argc, char** argv, int first, const std::vector<std::string>& valued,
         const std::vector<std::string>& boolean) {
        for (int i = first; i < argc; ++i) {
            std::string a = argv[i];
            if (a.rfind("--", 0) == 0) {
                if (std::find(valued.begin(), valued.end(), a) != valued.end()) {
                    if (i + 1 >= argc) throw UsageError(a + " needs a value");
                    opt[a] = argv[++i];
                } else if (std::find(boolean.begin(), boolean.end(), a) != boolean.end()) {
                    flags.push_back(a);
                } else {
                    throw UsageError("unknown option " + a);
                }
            } else {
                pos.push_back(std::move(a));
            }
        }
    }
    bool has(const std::string& f) const { return std::find(flags.begin(), flags.end(), f) != flags.end(); }
    std::string get(const std::string& k, const std::string& def) const {
        auto it = opt.find(k);
        return it == opt.end() ? def : it->second;
    }
    template <class T>
    T number(const std::string& k, T def) const {
        auto it = opt.find(k);
        if (it == opt.end()) return def;
        T v{};
        const char* b = it->second.data();
        const char* e = b + it->second.size();
        auto [p, ec] = std::from_chars(b, e, v);
        if (ec != std::errc() || p != e) throw UsageError(k + " expects a number, got '" + it->second + "'");
        return v;
    }
    /// Integer option `k` in [lo, hi], `def` when absent; anything else is a UsageError naming the range.
    template <class T>
    T count(const std::string& k, T def, std::uint64_t lo, std::uint64_t hi) const {
        auto it = opt.find(k);
        if (it == opt.end()) return def;
        std::uint64_t v = 0;
        if (std::string why = raykit::detail::cli_render::count_problem(k, it->second, lo, hi, v); !why.empty())
            throw UsageError(why);
        return static_cast<T>(v);
    }
};

/// Most rays `check` makes (see the header comment).
constexpr std::uint64_t kMaxCheckRays = 1'000'000;
/// Most triangles `generate` makes (see the header comment).
constexpr std::uint64_t kMaxGenerateTris = 1'000'000;
/// Most frames `animate-test` runs.
constexpr std::uint64_t kMaxAnimateTestFrames = 1000;

/// Every output checked writable and every input a regular file, before any work.
void check_files(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) {
    for (const std::string& o : outputs) raykit::detail::cli_render::check_writable(o);
    for (const std::string& i : inputs) raykit::detail::check_text_file(i);
}

/// Options every command that builds a tree takes.
const std::vector<std::string> kTreeFlags = {"--builder", "--leaf",    "--leaf-block", "--threads", "--window",
                                             "--axis",    "--metric",  "--pairing",    "--radius",  "--optimize"};

std::vector<std::string> with_tree_flags(std::vector<std::string> v) {
    v.insert(v.end(), kTreeFlags.begin(), kTreeFlags.end());
    return v;
}

BuildOptions tree_options(const Args& a) {
    BuildOptions o;
    try {
        o.builder = BuildOptions::parse_builder(a.get("--builder", "sah"));
        o.axis = BuildOptions::parse_axis(a.get("--axis", "morton"));
        // unset settings keep the chosen builder's own defaults
        if (a.opt.count("--metric")) o.metric = BuildOptions::parse_metric(a.get("--metric", ""));
        if (a.opt.count("--pairing")) o.pairing = BuildOptions::parse_pairing(a.get("--pairing", ""));
        if (a.opt.count("--optimize")) {
            const std::string v = a.get("--optimize", "");
            if (v != "on" && v != "off") throw std::invalid_argument("--optimize takes on or off, not '" + v + "'");
            o.optimize = v == "on" ? OptimizeConfig{} : OptimizeConfig::off();
        }
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    constexpr unsigned kMaxUnsigned = std::numeric_limits<unsigned>::max();
    o.leaf.max_leaf_size = a.count<unsigned>("--leaf", 8, 1, kMaxUnsigned);
    o.leaf.leaf_block = a.number<unsigned>("--leaf-block", 1);
    if (!valid_leaf_block(o.leaf.leaf_block)) throw UsageError("--leaf-block must be 1, 2, 4, 8 or 16");
    o.threads = a.count<unsigned>("--threads", 0, 0, kMaxThreads);
    o.window = a.count<unsigned>("--window", o.window, 1, 4096);
    o.radius = a.count<unsigned>("--radius", o.radius, 1, 1024);
    return o;
}

std::string describe(const BuildOptions& o) {
    std::string s = BuildOptions::name(o.builder);
    if (o.builder == BuildOptions::Builder::sortaxis)
        s += std::string(" window ") + std::to_string(o.window) + " axis " + BuildOptions::name(o.axis) + " metric " +
             BuildOptions::name(o.metric) + " pairing " + (o.pairing ? BuildOptions::name(*o.pairing) : "default");
    if (o.builder == BuildOptions::Builder::pairwise) s += std::string(" metric ") + BuildOptions::name(o.metric);
    if (o.builder == BuildOptions::Builder::ploc) s += " radius " + std::to_string(o.radius);
    return s;
}

Bvh build_tree(const Mesh& mesh, const BuildOptions& o) { return build_bvh(MeshView(mesh), o); }

Mesh load_scene(const std::string& path) {
    Mesh m = load_obj(path);
    for (const std::string& w : m.warnings) std::fprintf(stderr, "raykit: warning: %s\n", w.c_str());
    return m;
}

int cmd_info(int argc, char** argv) {
    Args a(argc, argv, 2, with_tree_flags({}), {"--json", "--device"});
    if (a.has("--device") && a.pos.empty()) {
#if RAYKIT_CLI_HAVE_CL
        raykit_cli_print_devices();
        return 0;
#else
        throw std::runtime_error("this raykit was built without OpenCL (install ocl-icd-opencl-dev, opencl-clhpp-headers and pocl-opencl-icd, then rebuild)");
#endif
    }
    if (a.pos.size() != 1) throw UsageError("info takes one SCENE.obj");
    const BuildOptions t = tree_options(a);
    check_files({a.pos[0]}, {});
    const Mesh mesh = load_scene(a.pos[0]);
    const auto t0 = Clock::now();
    const Bvh bvh = build_tree(mesh, t);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    const double cost = sah_cost(bvh);
    if (a.has("--json")) {
        std::printf(
            "{\"file\": \"%s\", \"triangles\": %zu, \"vertices\": %zu, \"materials\": %zu, \"builder\": \"%s\", "
            "\"settings\": \"%s\", \"max_leaf_size\": %u, \"leaf_block\": %u, \"nodes\": %zu, \"leaves\": %zu, \"depth\": %d, "
            "\"sah_cost\": %.6f, \"build_ms\": %.3f, \"memory_bytes\": %zu}\n",
            a.pos[0].c_str(), mesh.triangle_count(), mesh.vertex_count(), mesh.materials.size(),
            BuildOptions::name(t.builder), describe(t).c_str(), t.leaf.max_leaf_size, t.leaf.leaf_block, bvh.nodes.size(),
            bvh.leaf_count(), bvh.depth(), cost, ms, bvh.memory_bytes());
    } else {
        std::printf("file        %s\ntriangles   %zu\nvertices    %zu\nmaterials   %zu\nbuilder     %s (max leaf %u)\n"
                    "nodes       %zu\nleaves      %zu\ndepth       %d\nSAH cost    %.4f\nbuild       %.2f ms\n"
                    "memory      %zu bytes\n",
                    a.pos[0].c_str(), mesh.triangle_count(), mesh.vertex_count(), mesh.materials.size(),
                    describe(t).c_str(), t.leaf.max_leaf_size, bvh.nodes.size(), bvh.leaf_count(), bvh.depth(), cost,
                    ms, bvh.memory_bytes());
    }
    return 0;
}

enum class TestKind { watertight, mt, thesis };

TestKind test_kind(const Args& a) {
    const std::string s = a.get("--test", "watertight");
    if (s == "watertight") return TestKind::watertight;
    if (s == "mt") return TestKind::mt;
    if (s == "thesis") return TestKind::thesis;
    throw UsageError("unknown --test '" + s + "' (known: watertight, mt, thesis)");
}

template <class F>
decltype(auto) with_test(TestKind k, F&& f) {
    switch (k) {
        case TestKind::mt: return f(MollerTrumbore{});
        case TestKind::thesis: return f(ThesisTest{});
        default: return f(Watertight{});
    }
}

int cmd_trace(int argc, char** argv) {
    Args a(argc, argv, 2, with_tree_flags({"--test", "--device"}), {"--any-hit"});
    if (a.pos.size() != 3) throw UsageError("trace takes SCENE.obj RAYS.txt HITS.txt");
    const BuildOptions t = tree_options(a);
    const TestKind tk = test_kind(a);
    const std::string device = a.get("--device", "cpu");
    if (device != "cpu" && device != "cl") throw UsageError("--device must be cpu or cl");
    if (device == "cl" && tk != TestKind::watertight) throw UsageError("--device cl traces with the watertight test only");
    check_files({a.pos[0], a.pos[1]}, {a.pos[2]});
    const Mesh mesh = load_scene(a.pos[0]);
    const std::vector<Ray> rays = read_rays(a.pos[1]);
    const Bvh bvh = build_tree(mesh, t);
    std::ofstream out(a.pos[2], std::ios::binary);
    if (!out) throw std::runtime_error("cannot write " + a.pos[2]);
    const bool any = a.has("--any-hit");
    std::vector<Hit> hits(rays.size());
    std::vector<std::uint8_t> occl(rays.size());
    if (device == "cl") {
#if RAYKIT_CLI_HAVE_CL
        hits = raykit_cli_trace_device(mesh, bvh, rays, any);
        for (std::size_t i = 0; i < rays.size() && any; ++i) occl[i] = hits[i].prim == 1;
#else
        throw std::runtime_error("this raykit was built without OpenCL (install ocl-icd-opencl-dev, opencl-clhpp-headers and pocl-opencl-icd, then rebuild)");
#endif
    } else {
        // the CPU traces the same tree collapsed to 8-wide nodes: same answers, faster;
        // with the watertight test, through 4-triangle blocks (scene/block_bvh.hpp)
        const WideBvh8 wide = WideBvh8::collapse(bvh);
        if (tk == TestKind::watertight) {
            const BlockBvh8 blocks = BlockBvh8::make(mesh, wide, t.threads);
            parallel_for(rays.size(), t.threads, [&](std::size_t i) {
                if (any) occl[i] = intersect_any(blocks, rays[i]);
                else hits[i] = intersect_closest(blocks, rays[i]);
            });
        } else {
            with_test(tk, [&](auto test) {
                using T = decltype(test);
                parallel_for(rays.size(), t.threads, [&](std::size_t i) {
                    if (any) occl[i] = intersect_any<T>(mesh, wide, rays[i]);
                    else hits[i] = intersect_closest<T>(mesh, wide, rays[i]);
                });
                return 0;
            });
        }
    }
    std::string buf;
    buf.reserve(rays.size() * 40);
    char line[128];
    for (std::size_t i = 0; i < rays.size(); ++i) {
        if (any) {
            buf += occl[i] ? "1\n" : "0\n";
        } else if (hits[i].valid()) {
            std::snprintf(line, sizeof line, "%u %.9g %.9g %.9g\n", hits[i].prim, hits[i].t, hits[i].u, hits[i].v);
            buf += line;
        } else {
            buf += "-1 0 0 0\n";
        }
    }
    out << buf;
    if (!out) throw std::runtime_error("error writing " + a.pos[2]);
    return 0;
}

int cmd_check(int argc, char** argv) {
    Args a(argc, argv, 2, with_tree_flags({"--test", "--rays", "--seed"}), {});
    if (a.pos.size() != 1) throw UsageError("check takes one SCENE.obj");
    const BuildOptions t = tree_options(a);
    const TestKind tk = test_kind(a);
    const auto n = a.count<std::size_t>("--rays", 2000, 1, kMaxCheckRays);
    const auto seed = a.count<std::uint64_t>("--seed", 1, 0, std::numeric_limits<std::uint64_t>::max());
    check_files({a.pos[0]}, {});
    const Mesh mesh = load_scene(a.pos[0]);
    const Bvh bvh = build_tree(mesh, t);
    const PrimitiveRefs refs = primitive_refs(mesh);
    if (std::string err = validate(bvh, refs.boxes); !err.empty()) throw std::runtime_error("invalid BVH: " + err);
    AABB box;
    for (const AABB& b : refs.boxes) box.grow(b);
    if (box.is_empty()) box = AABB{vec3(-1.0f), vec3(1.0f)};
    const vec3 c = box.center(), e = box.extent() + vec3(1e-3f);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::vector<Ray> rays(n);
    for (std::size_t i = 0; i < n; ++i) {
        Ray& r = rays[i];
        r.org = c + vec3(U(rng), U(rng), U(rng)) * e;
        if (i % 2 == 1 && mesh.triangle_count() > 0) {
            // aim at a vertex or an edge midpoint of a random triangle
            std::uniform_int_distribution<std::size_t> P(0, mesh.triangle_count() - 1);
            const std::size_t p = P(rng);
            const vec3 a0 = mesh.positions[mesh.triangles[p].v[0]], a1 = mesh.positions[mesh.triangles[p].v[1]];
            r.dir = (i % 4 == 1 ? a0 : (a0 + a1) * 0.5f) - r.org;
        } else {
            r.dir = vec3(U(rng), U(rng), U(rng));
        }
        if (r.dir == vec3(0.0f)) r.dir = vec3(0.0f, 0.0f, 1.0f);
    }
    // every tree the CPU traces: the binary one, its 8-wide collapse and, for the
    // watertight test, the 4-triangle blocks made from that (what `trace` uses)
    const WideBvh8 wide = WideBvh8::collapse(bvh);
    if (std::string err = wide.validate(refs.boxes); !err.empty()) throw std::runtime_error("invalid wide BVH: " + err);
    const BlockBvh8 blocks = tk == TestKind::watertight ? BlockBvh8::make(mesh, wide, t.threads) : BlockBvh8{};
    std::vector<std::uint8_t> bad(n);
    with_test(tk, [&](auto test) {
        using T = decltype(test);
        parallel_for(n, t.threads, [&](std::size_t i) {
            const Hit h = intersect_closest<T>(mesh, bvh, rays[i]);
            const Hit w = intersect_closest<T>(mesh, wide, rays[i]);
            const Hit o = brute_force_closest<T>(mesh, rays[i]);
            const bool any = intersect_any<T>(mesh, bvh, rays[i]);
            const bool wany = intersect_any<T>(mesh, wide, rays[i]);
            bad[i] = h.prim != o.prim || h.t != o.t || any != o.valid() || w.prim != o.prim || w.t != o.t ||
                     wany != o.valid();
            if constexpr (std::is_same_v<T, Watertight>) {
                const Hit bh = intersect_closest(blocks, rays[i]);
                bad[i] |= bh.prim != o.prim || bh.t != o.t || bh.u != o.u || bh.v != o.v ||
                          intersect_any(blocks, rays[i]) != o.valid();
            }
        });
        return 0;
    });
    std::size_t disagree = 0;
    for (auto b : bad) disagree += b;
    std::printf("%zu rays, %zu disagreements with brute force (%zu triangles)\n", n, disagree, mesh.triangle_count());
    return disagree == 0 ? 0 : 1;
}

int cmd_animate_test(int argc, char** argv) {
    Args a(argc, argv, 2, {"--frames"}, {});
    if (a.pos.size() != 1) throw UsageError("animate-test takes one SCENE.obj");
    const int frames = a.count<int>("--frames", 10, 1, kMaxAnimateTestFrames);
#if RAYKIT_CLI_HAVE_CL
    check_files({a.pos[0]}, {});
    return raykit_cli_animate_test(load_scene(a.pos[0]), frames);
#else
    throw std::runtime_error("this raykit was built without OpenCL (install ocl-icd-opencl-dev, opencl-clhpp-headers and pocl-opencl-icd, then rebuild)");
#endif
}

int cmd_generate(int argc, char** argv) {
    Args a(argc, argv, 2, {"--tris", "--seed"}, {});
    if (a.pos.size() != 2) throw UsageError("generate takes KIND OUT.obj");
    const auto tris = a.count<std::size_t>("--tris", 100000, 1, kMaxGenerateTris);
    const auto seed = a.count<std::uint64_t>("--seed", 1, 0, std::numeric_limits<std::uint64_t>::max());
    const std::string& kind = a.pos[0];
    if (kind != "torus" && kind != "icosphere" && kind != "soup")
        throw UsageError("unknown mesh kind '" + kind + "' (known: torus, icosphere, soup)");
    check_files({}, {a.pos[1]});
    Mesh m;
    if (kind == "torus") m = make_bumpy_torus(tris);
    else if (kind == "icosphere") m = make_icosphere(icosphere_level_for(tris));
    else m = make_random_soup(tris, seed);
    save_obj(m, a.pos[1]);
    std::printf("wrote %s: %zu triangles, %zu vertices\n", a.pos[1].c_str(), m.triangle_count(), m.vertex_count());
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    if (argc < 2) {
        std::fputs(kUsage, stderr);
        std::fputs("raykit: error: no command given\n", stderr);
        return 2;
    }
    const std::string cmd = argv[1];
    try {
        if (cmd == "info") return cmd_info(argc, argv);
        if (cmd == "trace") return cmd_trace(argc, argv);
        if (cmd == "check") return cmd_check(argc, argv);
        if (cmd == "generate") return cmd_generate(argc, argv);
        if (cmd == "animate-test") return cmd_animate_test(argc, argv);
        if (cmd == "render") {
            try {
                return raykit_cli_render(argc, argv, 2);
            } catch (const RaykitCliRenderUsageError& e) {
                std::fputs(raykit_cli_render_usage(), stderr);
                std::fprintf(stderr, "raykit: error: %s\n", e.what());
                return 2;
            }
        }
        if (cmd == "animate") {
            try {
                return raykit_cli_animate(argc, argv, 2);
            } catch (const RaykitCliAnimateUsageError& e) {
                std::fputs(raykit_cli_animate_usage(), stderr);
                std::fprintf(stderr, "raykit: error: %s\n", e.what());
                return 2;
            }
        }
        if (cmd == "skin") {
            try {
                return raykit_cli_skin(argc, argv, 2);
            } catch (const raykit_cli::SkinUsageError& e) {
                throw UsageError(e.what());
            }
        }
        if (cmd == "--help" || cmd == "-h" || cmd == "help") {
            std::fputs(kUsage, stdout);
            return 0;
        }
        throw UsageError("unknown command '" + cmd + "'");
    } catch (const UsageError& e) {
        std::fputs(kUsage, stderr);
        std::fprintf(stderr, "raykit: error: %s\n", e.what());
        return 2;
    } catch (const std::bad_alloc&) {
        std::fprintf(stderr, "raykit: error: out of memory (%s needed more than this process may allocate)\n",
                     cmd.c_str());
        return 1;
    } catch (const std::exception& e) {
        std::fprintf(stderr, "raykit: error: %s\n", e.what());
        return 1;
    } catch (...) {
        std::fprintf(stderr, "raykit: error: unknown failure in %s\n", cmd.c_str());
        return 1;
    }
}
