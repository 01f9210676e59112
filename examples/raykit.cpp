// raykit — command line front end of the raykit library. One CLI11 parser (cli_common.hpp):
// `raykit --help` lists the commands, `raykit COMMAND --help` a command's arguments and flags;
// README.md's "Command line" synopsis lists the same flags (tests/test_cli.cpp checks both ways).
//
//   raykit info SCENE.obj [--builder sah] [--leaf-size N] [--threads T] [--json]
//   raykit trace SCENE.obj RAYS.txt HITS.txt [--any-hit] [--test watertight|mt|thesis] [...]
//   raykit check SCENE.obj [--rays N] [--seed S] [...]
//   raykit generate torus|icosphere|soup OUT.obj [--tris N] [--seed S]
//   raykit skin REF.smd [ANIM.smd FRAME] [--interp slerp|euler] [--device cpu|cl]
//   raykit animate REF.smd ANIM.smd OUT_%03d.png [--scene STATIC.obj] [--frames N] [...]
//   raykit render SCENE.obj OUT.png [...]
//
// The largest leaf is --leaf-size in every command (info, trace and check still take the old
// --leaf, hidden, with a warning).
//
// Every error ends with a one-line reason on stderr and a non-zero exit:
// 2 for bad usage (after a short usage line and where to find the full help), 1 for anything
// else (no usage line: a library error is never taken for a bad flag). Out of memory is one line
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
#include <chrono>
#include <cstdio>
#include <fstream>
#include <iostream>
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
using raykit_cli::UsageError;
using raykit_cli::count_in;
using Clock = std::chrono::steady_clock;

/// Most rays `check` makes (see the header comment).
constexpr std::uint64_t kMaxCheckRays = 1'000'000;
/// Most triangles `generate` makes (see the header comment).
constexpr std::uint64_t kMaxGenerateTris = 1'000'000;
/// Most frames `animate-test` runs.
constexpr std::uint64_t kMaxAnimateTestFrames = 1000;

constexpr const char* kNoOpenCL =
    "this raykit was built without OpenCL (install ocl-icd-opencl-dev, opencl-clhpp-headers and pocl-opencl-icd, "
    "then rebuild)";

/// Every output checked writable and every input a regular file, before any work.
void check_files(const std::vector<std::string>& inputs, const std::vector<std::string>& outputs) {
    for (const std::string& o : outputs) raykit::detail::cli_render::check_writable(o);
    for (const std::string& i : inputs) raykit::detail::check_text_file(i);
}

/// The flags of every command that builds a tree (info, trace, check).
struct TreeArgs {
    std::string builder = "sah", axis = "morton";
    std::string metric, pairing, optimize;  ///< empty: the builder's own default
    unsigned leaf_size = 8, leaf_block = 1, threads = 0;
    unsigned window = BuildOptions{}.window, radius = BuildOptions{}.radius;
    CLI::App* app = nullptr;  ///< the command, to ask whether the deprecated --leaf was given
};

void add_tree_options(CLI::App& app, TreeArgs& t) {
    t.app = &app;
    raykit_cli::add_builder_option(app, t.builder);
    raykit_cli::add_leaf_size_option(app, t.leaf_size, "largest leaf (primitives), >= 1 (default 8)");
    app.add_option("--leaf", t.leaf_size, "deprecated name of --leaf-size")
        ->group(raykit_cli::Formatter::kDeprecated)  // not in --help
        ->transform(count_in(1, std::numeric_limits<unsigned>::max()));
    app.add_option("--leaf-block", t.leaf_block,
                   "the SAH counts leaves in blocks of B primitives: 1 (default), 2, 4, 8 or 16 (4 with "
                   "--leaf-size 12 suits the CPU trace, which tests leaves 4 triangles at a time)")
        ->type_name("")
        ->check(CLI::IsMember({1u, 2u, 4u, 8u, 16u}));
    raykit_cli::add_threads_option(app, t.threads);
    app.add_option("--window", t.window, "sortaxis: candidates per element, 1..4096 (default 2; the thesis used 6)")
        ->type_name("W")
        ->transform(count_in(1, 4096));
    app.add_option("--axis", t.axis, "sortaxis: x, longest or morton (default)")
        ->type_name("")
        ->check(CLI::IsMember({"x", "longest", "morton"}));
    app.add_option("--metric", t.metric, "pairwise: centre (default) or area; sortaxis: area (default) or centre")
        ->type_name("")
        ->check(CLI::IsMember({"centre", "area"}));
    app.add_option("--pairing", t.pairing,
                   "sortaxis: mutual (default: mutual nearest neighbours) or greedy (the thesis's rule)")
        ->type_name("")
        ->check(CLI::IsMember({"mutual", "greedy"}));
    app.add_option("--radius", t.radius, "ploc: neighbours searched each way, 1..1024 (default 4)")
        ->type_name("R")
        ->transform(count_in(1, 1024));
    app.add_option("--optimize", t.optimize,
                   "sortaxis, ploc: post-pass (reinsertion + treelets); default on for ploc, off for sortaxis")
        ->type_name("")
        ->check(CLI::IsMember({"on", "off"}));
}

BuildOptions tree_options(const TreeArgs& a) {
    if (a.app && a.app->count("--leaf") > 0)
        std::fprintf(stderr, "raykit: warning: --leaf is deprecated, use --leaf-size (the same in every command)\n");
    BuildOptions o;
    try {
        o.builder = BuildOptions::parse_builder(a.builder);
        o.axis = BuildOptions::parse_axis(a.axis);
        // unset settings keep the chosen builder's own defaults
        if (!a.metric.empty()) o.metric = BuildOptions::parse_metric(a.metric);
        if (!a.pairing.empty()) o.pairing = BuildOptions::parse_pairing(a.pairing);
        if (!a.optimize.empty()) o.optimize = a.optimize == "on" ? OptimizeConfig{} : OptimizeConfig::off();
    } catch (const std::invalid_argument& e) {
        throw UsageError(e.what());
    }
    o.leaf.max_leaf_size = a.leaf_size;
    o.leaf.leaf_block = a.leaf_block;
    if (!valid_leaf_block(o.leaf.leaf_block)) throw UsageError("--leaf-block must be 1, 2, 4, 8 or 16");
    o.threads = a.threads;
    o.window = a.window;
    o.radius = a.radius;
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

struct InfoArgs {
    std::string scene;
    bool json = false, device = false;
    TreeArgs tree;
};

CLI::App* add_info(CLI::App& app, InfoArgs& a) {
    CLI::App* c = app.add_subcommand("info", "the scene and its tree: triangles, materials, nodes, leaves, depth, "
                                             "SAH cost, build time, memory; or, with --device, the OpenCL devices");
    c->add_option("SCENE.obj", a.scene, "the scene (OBJ)")->type_name("");
    add_tree_options(*c, a.tree);
    c->add_flag("--json", a.json, "one JSON object instead of the table");
    c->add_flag("--device", a.device, "lists OpenCL platforms and devices, and which one raykit picks and why");
    return c;
}

int cmd_info(const InfoArgs& a) {
    if (a.device && a.scene.empty()) {
#if RAYKIT_CLI_HAVE_CL
        raykit_cli_print_devices();
        return 0;
#else
        throw std::runtime_error(kNoOpenCL);
#endif
    }
    if (a.scene.empty()) throw UsageError("info takes one SCENE.obj (or --device)");
    const BuildOptions t = tree_options(a.tree);
    check_files({a.scene}, {});
    const Mesh mesh = load_scene(a.scene);
    const auto t0 = Clock::now();
    const Bvh bvh = build_tree(mesh, t);
    const double ms = std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
    const double cost = sah_cost(bvh);
    if (a.json) {
        std::printf(
            "{\"file\": \"%s\", \"triangles\": %zu, \"vertices\": %zu, \"materials\": %zu, \"builder\": \"%s\", "
            "\"settings\": \"%s\", \"max_leaf_size\": %u, \"leaf_block\": %u, \"nodes\": %zu, \"leaves\": %zu, \"depth\": %d, "
            "\"sah_cost\": %.6f, \"build_ms\": %.3f, \"memory_bytes\": %zu}\n",
            a.scene.c_str(), mesh.triangle_count(), mesh.vertex_count(), mesh.materials.size(),
            BuildOptions::name(t.builder), describe(t).c_str(), t.leaf.max_leaf_size, t.leaf.leaf_block, bvh.nodes.size(),
            bvh.leaf_count(), bvh.depth(), cost, ms, bvh.memory_bytes());
    } else {
        std::printf("file        %s\ntriangles   %zu\nvertices    %zu\nmaterials   %zu\nbuilder     %s (max leaf %u)\n"
                    "nodes       %zu\nleaves      %zu\ndepth       %d\nSAH cost    %.4f\nbuild       %.2f ms\n"
                    "memory      %zu bytes\n",
                    a.scene.c_str(), mesh.triangle_count(), mesh.vertex_count(), mesh.materials.size(),
                    describe(t).c_str(), t.leaf.max_leaf_size, bvh.nodes.size(), bvh.leaf_count(), bvh.depth(), cost,
                    ms, bvh.memory_bytes());
    }
    return 0;
}

enum class TestKind { watertight, mt, thesis };

TestKind test_kind(const std::string& s) {
    if (s == "mt") return TestKind::mt;
    if (s == "thesis") return TestKind::thesis;
    return TestKind::watertight;
}

void add_test_option(CLI::App& c, std::string& test) {
    c.add_option("--test", test, "ray/triangle test: watertight (default), mt (Moller-Trumbore), thesis")
        ->type_name("")
        ->check(CLI::IsMember({"watertight", "mt", "thesis"}));
}

template <class F>
decltype(auto) with_test(TestKind k, F&& f) {
    switch (k) {
        case TestKind::mt: return f(MollerTrumbore{});
        case TestKind::thesis: return f(ThesisTest{});
        default: return f(Watertight{});
    }
}

struct TraceArgs {
    std::string scene, rays, hits, test = "watertight", device = "cpu";
    bool any_hit = false;
    TreeArgs tree;
};

CLI::App* add_trace(CLI::App& app, TraceArgs& a) {
    CLI::App* c = app.add_subcommand("trace", "traces the rays of RAYS.txt, writes HITS.txt");
    c->add_option("SCENE.obj", a.scene, "the scene (OBJ)")->required()->type_name("");
    c->add_option("RAYS.txt", a.rays, "one ray per line, \"ox oy oz dx dy dz tmin tmax\" (tmax may be inf)")
        ->required()
        ->type_name("");
    c->add_option("HITS.txt", a.hits,
                  "one line per ray, \"prim t u v\" (\"-1 0 0 0\" on a miss); with --any-hit \"1\" or \"0\"")
        ->required()
        ->type_name("");
    add_tree_options(*c, a.tree);
    c->add_flag("--any-hit", a.any_hit, "occlusion only: 1 (something in the way) or 0 per ray");
    add_test_option(*c, a.test);
    c->add_option("--device", a.device, "cpu (default) or cl (the OpenCL device; the watertight test only)")
        ->type_name("")
        ->check(CLI::IsMember({"cpu", "cl"}));
    return c;
}

int cmd_trace(const TraceArgs& a) {
    const BuildOptions t = tree_options(a.tree);
    const TestKind tk = test_kind(a.test);
    const std::string& device = a.device;
    if (device == "cl" && tk != TestKind::watertight) throw UsageError("--device cl traces with the watertight test only");
    check_files({a.scene, a.rays}, {a.hits});
    const Mesh mesh = load_scene(a.scene);
    const std::vector<Ray> rays = read_rays(a.rays);
    const Bvh bvh = build_tree(mesh, t);
    std::ofstream out(a.hits, std::ios::binary);
    if (!out) throw std::runtime_error("cannot write " + a.hits);
    const bool any = a.any_hit;
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
        const WideBvh8 wide = WideBvh8::build(bvh);
        if (tk == TestKind::watertight) {
            const BlockBvh8 blocks = BlockBvh8::build(mesh, wide, t.threads);
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
    if (!out) throw std::runtime_error("error writing " + a.hits);
    return 0;
}

struct CheckArgs {
    std::string scene, test = "watertight";
    std::size_t rays = 2000;
    std::uint64_t seed = 1;
    TreeArgs tree;
};

CLI::App* add_check(CLI::App& app, CheckArgs& a) {
    CLI::App* c = app.add_subcommand("check", "traversal of the built tree against brute force on random rays; "
                                              "exits 1 if they disagree");
    c->add_option("SCENE.obj", a.scene, "the scene (OBJ)")->required()->type_name("");
    c->add_option("--rays", a.rays, "random rays, 1..1000000 (default 2000)")
        ->type_name("N")
        ->transform(count_in(1, kMaxCheckRays));
    c->add_option("--seed", a.seed, "random seed (default 1)")
        ->type_name("S")
        ->transform(count_in(0, std::numeric_limits<std::uint64_t>::max()));
    add_tree_options(*c, a.tree);
    add_test_option(*c, a.test);
    return c;
}

int cmd_check(const CheckArgs& a) {
    const BuildOptions t = tree_options(a.tree);
    const TestKind tk = test_kind(a.test);
    const std::size_t n = a.rays;
    const std::uint64_t seed = a.seed;
    check_files({a.scene}, {});
    const Mesh mesh = load_scene(a.scene);
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
    const WideBvh8 wide = WideBvh8::build(bvh);
    if (std::string err = wide.validate(refs.boxes); !err.empty()) throw std::runtime_error("invalid wide BVH: " + err);
    const BlockBvh8 blocks = tk == TestKind::watertight ? BlockBvh8::build(mesh, wide, t.threads) : BlockBvh8{};
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

struct AnimateTestArgs {
    std::string scene;
    int frames = 10;
};

CLI::App* add_animate_test(CLI::App& app, AnimateTestArgs& a) {
    CLI::App* c = app.add_subcommand("animate-test", "a \"wave\" vertex hook moves a dynamic copy each frame: "
                                                     "refit, TLAS, trace, on the device and the CPU");
    c->add_option("SCENE.obj", a.scene, "the scene (OBJ)")->required()->type_name("");
    c->add_option("--frames", a.frames, "frames, 1..1000 (default 10)")
        ->type_name("N")
        ->transform(count_in(1, kMaxAnimateTestFrames));
    return c;
}

int cmd_animate_test(const AnimateTestArgs& a) {
#if RAYKIT_CLI_HAVE_CL
    check_files({a.scene}, {});
    return raykit_cli_animate_test(load_scene(a.scene), a.frames);
#else
    (void)a;
    throw std::runtime_error(kNoOpenCL);
#endif
}

struct GenerateArgs {
    std::string kind, out;
    std::size_t tris = 100000;
    std::uint64_t seed = 1;
};

CLI::App* add_generate(CLI::App& app, GenerateArgs& a) {
    CLI::App* c = app.add_subcommand("generate", "writes a generated mesh as OBJ");
    c->add_option("KIND", a.kind, "torus (bumpy), icosphere or soup (random triangles)")
        ->required()
        ->type_name("")
        ->check(CLI::IsMember({"torus", "icosphere", "soup"}));
    c->add_option("OUT.obj", a.out, "the OBJ to write")->required()->type_name("");
    c->add_option("--tris", a.tris,
                  "triangles, 1..1000000 (default 100000): about N for the torus, exactly N for the soup, the "
                  "largest icosphere level (20 x 4^k) within N")
        ->type_name("N")
        ->transform(count_in(1, kMaxGenerateTris));
    c->add_option("--seed", a.seed, "soup: random seed (default 1)")
        ->type_name("S")
        ->transform(count_in(0, std::numeric_limits<std::uint64_t>::max()));
    return c;
}

int cmd_generate(const GenerateArgs& a) {
    check_files({}, {a.out});
    Mesh m;
    std::string note;
    if (a.kind == "torus") {
        m = make_bumpy_torus(a.tris);
        if (m.triangle_count() != a.tris) note = " (the nearest torus grid to --tris " + std::to_string(a.tris) + ")";
    } else if (a.kind == "icosphere") {
        const unsigned level = icosphere_level_for(a.tris);
        m = make_icosphere(level);
        if (m.triangle_count() != a.tris)
            note = " (icosphere level " + std::to_string(level) + ", the largest within --tris " +
                   std::to_string(a.tris) + "; levels have 20 x 4^k triangles, the next " +
                   std::to_string(m.triangle_count() * 4) + ")";
    } else {
        m = make_random_soup(a.tris, a.seed);
    }
    save_obj(m, a.out);
    std::printf("wrote %s: %zu triangles%s, %zu vertices\n", a.out.c_str(), m.triangle_count(), note.c_str(),
                m.vertex_count());
    return 0;
}

/// "usage: raykit CMD POSITIONALS [OPTIONS]" for `cmd` (the whole CLI when null), and where
/// the full help is.
std::string short_usage(const CLI::App* cmd) {
    if (!cmd) {
        return "usage: raykit COMMAND [ARGS] [OPTIONS]  (commands: info, trace, check, generate, skin, animate, "
               "render, animate-test)\nrun 'raykit --help' for the commands, 'raykit COMMAND --help' for one's "
               "arguments and options\n";
    }
    std::string u = "usage: raykit " + cmd->get_name();
    for (const CLI::Option* o : cmd->get_options([](const CLI::Option* o) { return o->get_positional(); }))
        u += o->get_required() ? " " + o->get_name() : " [" + o->get_name() + "]";
    return u + " [OPTIONS]\nrun 'raykit " + cmd->get_name() + " --help' for every option\n";
}

}  // namespace

int main(int argc, char** argv) {
    CLI::App app{"raykit: the command line of the raykit ray-tracing library", "raykit"};
    app.formatter(std::make_shared<raykit_cli::Formatter>());
    app.require_subcommand(1);
    InfoArgs info;
    TraceArgs trace;
    CheckArgs check;
    GenerateArgs generate;
    AnimateTestArgs animate_test;
    raykit_cli::SkinArgs skin;
    raykit_cli::AnimateArgs animate;
    raykit_cli::RenderArgs render;
    CLI::App* c_info = add_info(app, info);
    CLI::App* c_trace = add_trace(app, trace);
    CLI::App* c_check = add_check(app, check);
    CLI::App* c_generate = add_generate(app, generate);
    CLI::App* c_skin = app.add_subcommand("skin", "prints the skinned position of every triangle corner of an SMD "
                                                  "model, one \"x y z\" line each, triangles in file order");
    raykit_cli::add_skin_options(*c_skin, skin);
    CLI::App* c_animate = app.add_subcommand("animate", "renders a skinned SMD character frame by frame, alone or "
                                                        "inside a static OBJ scene, with per-frame timings");
    raykit_cli::add_animate_options(*c_animate, animate);
    CLI::App* c_render = app.add_subcommand("render", "renders a scene to PNG (or PFM) on the CPU or the OpenCL "
                                                      "device");
    raykit_cli::add_render_options(*c_render, render);
    CLI::App* c_animate_test = add_animate_test(app, animate_test);
    app.footer("Run 'raykit COMMAND --help' for a command's arguments and options. Bad arguments exit with 2, "
               "any other error with 1 and a one-line reason on stderr.");

    // the command named on the command line, for the usage line of a usage error
    const CLI::App* named = nullptr;
    const std::string cmd = argc > 1 ? argv[1] : "";
    for (const CLI::App* c : app.get_subcommands([](const CLI::App*) { return true; }))
        if (c->get_name() == cmd) named = c;
    try {
        if (argc < 2) throw UsageError("no command given");
        if (cmd == "help") {
            std::fputs(app.help().c_str(), stdout);
            return 0;
        }
        if (!named && cmd.rfind("-", 0) != 0) throw UsageError("unknown command '" + cmd + "'");
        try {
            app.parse(argc, argv);
        } catch (const CLI::CallForHelp& e) {
            return app.exit(e);  // the help of the command asked about, on stdout
        } catch (const CLI::CallForAllHelp& e) {
            return app.exit(e);
        } catch (const CLI::ParseError& e) {
            throw UsageError(e.what());
        }
        if (*c_info) return cmd_info(info);
        if (*c_trace) return cmd_trace(trace);
        if (*c_check) return cmd_check(check);
        if (*c_generate) return cmd_generate(generate);
        if (*c_animate_test) return cmd_animate_test(animate_test);
        if (*c_render) return raykit_cli::run_render(render);
        if (*c_animate) {
            raykit_cli::finish_animate_args(animate);
            return raykit_cli::run_animate(animate);
        }
        if (*c_skin) {
            raykit_cli::finish_skin_args(*c_skin, skin);
            return raykit_cli::run_skin(skin);
        }
        throw UsageError("no command given");
    } catch (const UsageError& e) {
        std::fputs(short_usage(named).c_str(), stderr);
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
