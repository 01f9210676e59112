// benchmarks/bench_cl.cpp — the OpenCL device path next to the CPU path.
//
// Device: raykit::cl::Device::shared() (RAYKIT_CL_DEVICE to choose; PoCL's CPU
// device when there is no GPU). Every case skips itself when there is no
// OpenCL device. Timings wait for the device (clFinish) and use real time.
//
// Cases (items/s = rays/s for traces; counters in ms where named so):
//   cl_trace/<scene>/<rays>/<closest|any>/device       MeshTracer (8-wide nodes over 4-triangle
//                                                      blocks, cl/device_tree.hpp), rays resident on
//                                                      the device, one launch per iteration, packets
//                                                      of 16 rays (kernels/raykit/kernels/
//                                                      trace_packet.hpp) on every device, GPUs too
//   cl_trace/<scene>/<rays>/<closest|any>/device_single the same, one ray per work-item (the
//                                                      default walk where the device is not a CPU)
//   cl_trace/<scene>/<rays>/<closest|any>/device_q, device_q_single   the same with the nodes
//                                                      quantized (NodeForm::quantized, 104 bytes)
//   cl_trace/<torus4M|torus16M>/<rays>/<closest|any>/device_single, device_q_single   the same on
//                                                      GPU-sized meshes, whose full nodes outgrow a
//                                                      GPU's L2 (skipped on CPU devices)
//   cl_trace/<scene>/<rays>/<closest|any>/cpu_blocks8/threads:2  the CPU's fastest path on the
//                                                      same tree (BlockBvh8::make of the same Bvh)
//   cl_trace/<scene>/<rays>/<closest|any>/cpu_batch8/threads:2  the same tree through the batch
//                                                      call (packets of 16, bvh/traverse_packet.hpp)
//   cl_trace/<scene>/<rays>/<closest|any>/cpu/threads:2 intersect_closest / intersect_any over
//                                                      2 std::threads (rkbench::trace_parallel)
//       counter cpu_ms: process CPU time per iteration (all threads, PoCL's too): on a
//       shared machine the ratio of cpu_ms is a steadier estimate of relative throughput
//       on dedicated cores than the wall-clock ratio
//       scene  torus100k, torus1M, bunny (if the shared data exists)   rays  primary, random
//       (rkbench ray sets, 262 144 rays; any-hit with tmax = inf)
//   cl_refit/<method>/tris:<T>/objects:<K>             refit of K dynamic objects of T/K triangles
//       each (bumpy tori); method level-wise | one-pass | cpu (raykit::refit per object, one
//       thread); counter levels = launches of level-wise; T = 10k, 100k, 1M; K = 1, 100
//   cl_program/first      clBuildProgram of the full scene program (hooks wave), made unique per
//                         iteration with a -D option (so neither raykit's nor PoCL's cache helps),
//                         plus the first launch (PoCL compiles the work-group function then)
//   cl_program/cached     build_program() of an already built program (the in-process cache)
//   cl_build/<mesh>/<ploc|sortaxis>/device   an object's tree built on the device
//                         (cl/device_build.hpp: PLOC or sort by axis, 8-wide nodes and blocks
//                         written into device arrays, refit tables included) from vertices
//                         already there; mesh torus2k (a character's size), bunny, torus100k;
//                         counters rounds (PLOC rounds or sort-by-axis levels), launches
//   cl_build/<mesh>/<ploc|sortaxis>/cpu_twin/threads:2   the same tree on the CPU
//                         (cpu_twin_build: PlocBuilder without post-pass or SortAxisBuilder,
//                         BlockBvh8::build) on 2 threads
//   cl_build/<mesh>/cpu_sah/threads:2    what the CPU frame rebuilds with (Scene::rebuild_object:
//                         binned SAH, BlockBvh8::build)
//   cl_frame/torus100k/device   one frame of a 100k-triangle dynamic mesh: wave vertex hook,
//                         one-pass refit, top level, 1024x1024 camera rays (1 Mray) traced closest;
//                         counters vertex_ms, refit_ms, tlas_ms, trace_ms
//   cl_frame/torus100k/device_q the same walking quantized nodes (their quantize stage: quantize_ms)
//   cl_frame/torus100k/cpu      the same frame on the CPU twins (2 threads for vertices and rays)
//
//   cmake --build build-bench --target bench_cl
//   build-bench/benchmarks/bench_cl --benchmark_out=bench_cl.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <chrono>
#include <ctime>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "common.hpp"
#include "raykit/cl.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/scene.hpp"

namespace {

namespace rcl = raykit::cl;
using clock_type = std::chrono::steady_clock;

double ms_since(clock_type::time_point t0) {
    return std::chrono::duration<double, std::milli>(clock_type::now() - t0).count();
}

/// CPU time of the whole process (all threads, PoCL's included), in ms.
double process_cpu_ms() {
    timespec t{};
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e3 + double(t.tv_nsec) * 1e-6;
}

/// The device, or nullptr after marking the case skipped.
rcl::Device* device_or_skip(benchmark::State& state) {
    try {
        return &rcl::Device::shared();
    } catch (const rcl::NoDeviceError& e) {
        state.SkipWithError(e.what());
        return nullptr;
    }
}

// ---------------------------------------------------------------- trace

struct TraceSetup {
    std::unique_ptr<rcl::MeshTracer> tracer;
    rcl::Buffer<raykit::Ray> rays;
    rcl::Buffer<raykit::Hit> hits;
    rcl::Buffer<std::uint32_t> occluded;
};

TraceSetup& trace_setup(rcl::Device& dev, const rkbench::Scene& s, const std::string& set, rcl::NodeForm form) {
    static std::map<std::tuple<std::string, std::string, rcl::NodeForm>, std::unique_ptr<TraceSetup>> cache;
    auto& slot = cache[{s.name, set, form}];
    if (!slot) {
        slot = std::make_unique<TraceSetup>();
        slot->tracer = std::make_unique<rcl::MeshTracer>(dev, s.mesh, rkbench::raykit_bvh(s), std::string(), form);
        const auto& r = rkbench::rays(s, set);
        slot->rays = rcl::Buffer<raykit::Ray>(dev, r, CL_MEM_READ_ONLY);
        slot->hits = rcl::Buffer<raykit::Hit>(dev, r.size());
        slot->occluded = rcl::Buffer<std::uint32_t>(dev, r.size());
    }
    return *slot;
}

bool gpu_sized(const std::string& scene) { return scene == "torus4M" || scene == "torus16M"; }

void BM_TraceDevice(benchmark::State& state, const std::string& scene, const std::string& set, bool any,
                    bool packets, rcl::NodeForm form) {
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    if (gpu_sized(scene) && dev->info().is_cpu()) {
        state.SkipWithError("a GPU-sized mesh: run on GPUs only");
        return;
    }
    const rkbench::Scene* s = rkbench::scene_or_skip(state, scene);
    if (!s) return;
    TraceSetup& t = trace_setup(*dev, *s, set, form);
    if (t.tracer->node_form() != form) {
        state.SkipWithError("the tree could not be quantized");
        return;
    }
    t.tracer->set_packet_walk(packets);
    const std::size_t n = t.rays.size();
    // warm-up launch: PoCL compiles the kernel on its first launch
    any ? t.tracer->any(t.rays, t.occluded, n) : t.tracer->closest(t.rays, t.hits, n);
    dev->finish();
    const double c0 = process_cpu_ms();
    for (auto _ : state) {
        any ? t.tracer->any(t.rays, t.occluded, n) : t.tracer->closest(t.rays, t.hits, n);
        dev->finish();
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - c0) / double(state.iterations());
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * n));
    state.counters["Mrays/s"] = benchmark::Counter(double(n) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

void BM_TraceCpu(benchmark::State& state, const std::string& scene, const std::string& set, bool any) {
    const rkbench::Scene* s = rkbench::scene_or_skip(state, scene);
    if (!s) return;
    const raykit::Bvh& bvh = rkbench::raykit_bvh(*s);
    const auto& rays = rkbench::rays(*s, set);
    const raykit::MeshView mesh(s->mesh);
    std::vector<raykit::Hit> hits(rays.size());
    std::vector<std::uint8_t> occ(rays.size());
    const unsigned threads = static_cast<unsigned>(state.range(0));
    const double c0 = process_cpu_ms();
    for (auto _ : state) {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            if (any)
                for (std::size_t i = b; i < e; ++i) occ[i] = raykit::intersect_any(mesh, bvh, rays[i]);
            else
                for (std::size_t i = b; i < e; ++i) hits[i] = raykit::intersect_closest(mesh, bvh, rays[i]);
        });
        benchmark::DoNotOptimize(hits.data());
        benchmark::DoNotOptimize(occ.data());
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - c0) / double(state.iterations());
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rays.size()));
    state.counters["Mrays/s"] =
        benchmark::Counter(double(rays.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

// ---------------------------------------------------------------- refit

struct RefitSetup {
    raykit::Scene scene;
    std::unique_ptr<rcl::DeviceScene<>> ds;
    std::vector<std::uint32_t> objects;
};

RefitSetup& refit_setup(rcl::Device& dev, std::size_t tris, std::size_t objects) {
    static std::map<std::pair<std::size_t, std::size_t>, std::unique_ptr<RefitSetup>> cache;
    auto& slot = cache[{tris, objects}];
    if (!slot) {
        slot = std::make_unique<RefitSetup>();
        const raykit::Mesh m = raykit::make_bumpy_torus(tris / objects);
        for (std::size_t k = 0; k < objects; ++k) {
            const std::uint32_t o = slot->scene.add_object(m, raykit::ObjectKind::dynamic);
            slot->objects.push_back(o);
            slot->scene.add_instance(o, glm::translate(raykit::mat4(1.0f), raykit::vec3(3.0f * float(k % 10), 3.0f * float(k / 10), 0.0f)));
        }
        slot->scene.update_top_level();
        slot->ds = std::make_unique<rcl::DeviceScene<>>(dev, slot->scene);
        slot->ds->update();
    }
    return *slot;
}

enum class RefitCase { level_wise, one_pass, cpu };

void BM_Refit(benchmark::State& state, RefitCase which) {
    const auto tris = static_cast<std::size_t>(state.range(0));
    const auto objects = static_cast<std::size_t>(state.range(1));
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    RefitSetup& r = refit_setup(*dev, tris, objects);
    std::size_t nodes = 0;
    for (std::uint32_t o : r.objects) nodes += r.scene.objects()[o].bvh.nodes.size();
    if (which == RefitCase::cpu) {
        for (auto _ : state)
            for (std::uint32_t o : r.objects) r.scene.refit_object(o);
    } else {
        const auto m = which == RefitCase::level_wise ? rcl::RefitMethod::level_wise : rcl::RefitMethod::one_pass;
        r.ds->refit(m);  // warm-up (first launch compiles)
        dev->finish();
        for (auto _ : state) {
            r.ds->refit(m);
            dev->finish();
        }
    }
    state.counters["nodes"] = double(nodes);
    state.counters["levels"] = double(r.ds->refit_plan().levels());
    state.counters["ms"] = benchmark::Counter(1e-3, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
}

// ---------------------------------------------------------------- device builds

enum class BuildCase { device, cpu_twin, cpu_sah };

const raykit::Mesh* build_mesh(benchmark::State& state, const std::string& name) {
    static const raykit::Mesh small = raykit::make_bumpy_torus(2400);
    if (name == "torus2k") return &small;
    const rkbench::Scene* s = rkbench::scene_or_skip(state, name);
    return s ? &s->mesh : nullptr;
}

void BM_Build(benchmark::State& state, std::string name, BuildCase which, rcl::DeviceBuildMethod method) {
    const raykit::Mesh* mesh = build_mesh(state, name);
    if (!mesh) return;
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    rcl::DeviceBuildConfig cfg;
    cfg.method = method;
    if (which == BuildCase::cpu_twin) {
        for (auto _ : state) benchmark::DoNotOptimize(rcl::cpu_twin_build(*mesh, cfg, 2));
    } else if (which == BuildCase::cpu_sah) {
        for (auto _ : state) {
            const raykit::Bvh bvh = raykit::build_bvh<raykit::BinnedSahBuilder>(*mesh, raykit::BlockBvh8::sah_config(2));
            benchmark::DoNotOptimize(raykit::BlockBvh8::build(*mesh, bvh, 2));
        }
    } else {
        rcl::DeviceBuilder builder(*dev, cfg);
        const std::size_t n = mesh->triangles.size();
        rcl::Buffer<raykit::Triangle> tris(*dev, mesh->triangles);
        rcl::Buffer<float> pos(*dev, rcl::float_span(mesh->positions));
        rcl::Buffer<rcl::DeviceNode> nodes(*dev, rcl::DeviceBuilder::node_capacity(n));
        rcl::Buffer<raykit::TriangleBlock4> blocks(*dev, rcl::DeviceBuilder::block_capacity(n));
        rcl::Buffer<std::uint32_t> parents(*dev, nodes.size()), needs(*dev, nodes.size());
        rcl::Buffer<cl_uint2> starts(*dev, nodes.size());
        rcl::ObjectRecord rec{};
        rec.triangle_count = static_cast<std::uint32_t>(n);
        const rcl::DeviceBuildTarget out{&nodes, &blocks, {&parents, &needs, &starts}};
        rcl::DeviceBuildResult r = builder.build(tris, pos, rec, 0, out);  // warm-up: first launches compile
        dev->finish();
        for (auto _ : state) {
            r = builder.build(tris, pos, rec, 0, out);
            dev->finish();
        }
        state.counters["rounds"] = double(r.rounds);
        state.counters["launches"] = double(builder.launches()) / double(state.iterations() + 1);
    }
    state.SetItemsProcessed(std::int64_t(state.iterations()) * std::int64_t(mesh->triangles.size()));
}

// ---------------------------------------------------------------- program build

std::vector<rcl::SourcePart> scene_program_parts(const rcl::Device& dev) {
    std::vector<rcl::SourcePart> parts = rcl::base_parts();
    parts.push_back({"raykit/kernels/camera.hpp", raykit::kernels::kCamera});
    for (rcl::SourcePart& p : rcl::trace_parts(rcl::packet_walk_default(dev), rcl::TraceKernels::scene))
        parts.push_back(std::move(p));
    parts.push_back(rcl::refit_part());
    const auto hp = rcl::hook_parts<rcl::WaveHook>();
    parts.insert(parts.end(), hp.begin(), hp.end());
    return parts;
}

void BM_ProgramFirst(benchmark::State& state) {
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    const std::string src = rcl::assemble(scene_program_parts(*dev));
    static int nonce = 0;
    double build_ms = 0.0, launch_ms = 0.0;
    for (auto _ : state) {
        const std::string opts = rcl::raykit_build_options(*dev) + " -DRK_BENCH_NONCE=" + std::to_string(++nonce) + "_" +
                                 std::to_string(clock_type::now().time_since_epoch().count());
        auto t0 = clock_type::now();
        const rcl::Program p = rcl::build_program(*dev, src, opts);
        build_ms += ms_since(t0);
        t0 = clock_type::now();
        ::cl::Kernel k = p.kernel("rk_camera_rays");
        rcl::Buffer<raykit::Ray> rays;
        rcl::camera_rays(*dev, k, raykit::Camera{.width = 8, .height = 8}.frame(), rays);
        dev->finish();
        launch_ms += ms_since(t0);
    }
    state.counters["build_ms"] = build_ms / double(state.iterations());
    state.counters["first_launch_ms"] = launch_ms / double(state.iterations());
}

void BM_ProgramCached(benchmark::State& state) {
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    const std::string src = rcl::assemble(scene_program_parts(*dev));
    rcl::build_program(*dev, src, rcl::raykit_build_options(*dev));
    for (auto _ : state) benchmark::DoNotOptimize(rcl::build_program(*dev, src, rcl::raykit_build_options(*dev)));
}

// ---------------------------------------------------------------- frame

constexpr std::uint32_t kFrameSide = 1024;  // 1 Mray

struct FrameSetup {
    raykit::Scene scene;
    std::uint32_t object = 0;
    raykit::Camera camera;
    std::unique_ptr<rcl::DeviceScene<rcl::WaveHook>> ds, dq;  ///< full / quantized nodes
    rcl::Buffer<raykit::Ray> rays;
    rcl::Buffer<raykit::Hit> hits;
};

FrameSetup& frame_setup(rcl::Device* dev) {
    static std::unique_ptr<FrameSetup> f;
    if (!f) {
        f = std::make_unique<FrameSetup>();
        const rkbench::Scene* s = rkbench::scene("torus100k");
        f->object = f->scene.add_object(s->mesh, raykit::ObjectKind::dynamic);
        f->scene.add_instance(f->object);
        f->scene.update_top_level();
        raykit::AABB box = s->bounds;
        box.grow(box.max + raykit::vec3(0.2f));
        box.grow(box.min - raykit::vec3(0.2f));
        f->camera = raykit::camera_looking_at(box, kFrameSide, kFrameSide);
    }
    if (dev && !f->ds) {
        for (const rcl::NodeForm form : {rcl::NodeForm::full, rcl::NodeForm::quantized}) {
            auto& ds = form == rcl::NodeForm::full ? f->ds : f->dq;
            ds = std::make_unique<rcl::DeviceScene<rcl::WaveHook>>(*dev, f->scene, rcl::DeviceRebuild{}, form);
            ds->set_hook<rcl::WaveHook>(f->object, {});
            ds->update();
            ds->camera_rays(f->camera.frame(), f->rays);
            ds->closest(f->rays, f->hits, f->rays.size());
        }
        dev->finish();
    }
    return *f;
}

void BM_FrameDevice(benchmark::State& state, rcl::NodeForm form) {
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    FrameSetup& f = frame_setup(dev);
    rcl::DeviceScene<rcl::WaveHook>& ds = form == rcl::NodeForm::full ? *f.ds : *f.dq;
    double vertex = 0, refit = 0, quantize = 0, tlas = 0, trace = 0;
    float time = 0.0f;
    for (auto _ : state) {
        ds.set_hook<rcl::WaveHook>(f.object, {.time = time += 0.1f});
        const rcl::FrameTimes ft = ds.update(rcl::RefitMethod::one_pass);
        const auto t0 = clock_type::now();
        ds.camera_rays(f.camera.frame(), f.rays);
        ds.closest(f.rays, f.hits, f.rays.size());
        dev->finish();
        trace += ms_since(t0);
        vertex += ft.vertex_ms;
        refit += ft.refit_ms;
        quantize += ft.quantize_ms;
        tlas += ft.top_level_ms;
    }
    const double it = double(state.iterations());
    state.counters["vertex_ms"] = vertex / it;
    state.counters["refit_ms"] = refit / it;
    state.counters["quantize_ms"] = quantize / it;
    state.counters["tlas_ms"] = tlas / it;
    state.counters["trace_ms"] = trace / it;
    state.counters["Mrays/s"] = double(f.rays.size()) * 1e-3 / (trace / it);
}

void BM_FrameCpu(benchmark::State& state) {
    FrameSetup& f = frame_setup(nullptr);
    const raykit::CameraFrame cf = f.camera.frame();
    std::vector<raykit::Hit> hits(std::size_t(kFrameSide) * kFrameSide);
    double vertex = 0, tlas = 0, trace = 0;
    float time = 0.0f;
    for (auto _ : state) {
        const rcl::WaveHook::Params p{.time = time += 0.1f};
        auto t0 = clock_type::now();
        f.scene.move_vertices(f.object, [&](const raykit::Vertex& v, std::uint32_t i) { return rcl::WaveHook::apply(v, i, p); }, 2);
        vertex += ms_since(t0);  // includes the (single-threaded) refit
        t0 = clock_type::now();
        f.scene.update_top_level();
        tlas += ms_since(t0);
        t0 = clock_type::now();
        rkbench::trace_parallel(hits.size(), 2, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i)
                hits[i] = f.scene.intersect_closest(cf.ray(std::uint32_t(i % kFrameSide), std::uint32_t(i / kFrameSide)));
        });
        trace += ms_since(t0);
        benchmark::DoNotOptimize(hits.data());
    }
    const double it = double(state.iterations());
    state.counters["vertex_refit_ms"] = vertex / it;
    state.counters["tlas_ms"] = tlas / it;
    state.counters["trace_ms"] = trace / it;
    state.counters["Mrays/s"] = double(hits.size()) * 1e-3 / (trace / it);
}

/// The CPU's fastest path on the device's tree: BlockBvh8::build(mesh, raykit_bvh(s)), the
/// 8-wide nodes and 4-triangle blocks MeshTracer uploads (cl/device_tree.hpp).
void BM_TraceCpuBlocks(benchmark::State& state, const std::string& scene, const std::string& set, bool any,
                       bool batch) {
    const rkbench::Scene* s = rkbench::scene_or_skip(state, scene);
    if (!s) return;
    static std::map<std::string, std::unique_ptr<raykit::BlockBvh8>> cache;
    auto& blocks = cache[s->name];
    if (!blocks) blocks = std::make_unique<raykit::BlockBvh8>(raykit::BlockBvh8::build(s->mesh, rkbench::raykit_bvh(*s)));
    const auto& rays = rkbench::rays(*s, set);
    std::vector<raykit::Hit> hits(rays.size());
    std::vector<std::uint8_t> occ(rays.size());
    const unsigned threads = static_cast<unsigned>(state.range(0));
    const double c0 = process_cpu_ms();
    for (auto _ : state) {
        if (batch) {
            if (any) raykit::intersect_any(*blocks, rays, occ, threads);
            else raykit::intersect_closest(*blocks, rays, hits, threads);
        } else {
            rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
                if (any)
                    for (std::size_t i = b; i < e; ++i) occ[i] = raykit::intersect_any(*blocks, rays[i]);
                else
                    for (std::size_t i = b; i < e; ++i) hits[i] = raykit::intersect_closest(*blocks, rays[i]);
            });
        }
        benchmark::DoNotOptimize(hits.data());
        benchmark::DoNotOptimize(occ.data());
    }
    state.counters["cpu_ms"] = (process_cpu_ms() - c0) / double(state.iterations());
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations() * rays.size()));
    state.counters["Mrays/s"] = benchmark::Counter(double(rays.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}

const bool registered = [] {
    for (const std::string scene : {"torus100k", "torus1M", "bunny", "torus4M", "torus16M"})
        for (const std::string set : {"primary", "random"})
            for (const bool any : {false, true}) {
                const std::string base = "cl_trace/" + scene + "/" + set + "/" + (any ? "any" : "closest");
                for (const rcl::NodeForm form : {rcl::NodeForm::full, rcl::NodeForm::quantized})
                    for (const bool packets : {true, false}) {
                        if (packets && gpu_sized(scene)) continue;  // GPUs walk single rays
                        benchmark::RegisterBenchmark(
                            (base + (form == rcl::NodeForm::full ? "/device" : "/device_q") + (packets ? "" : "_single"))
                                .c_str(),
                            BM_TraceDevice, scene, set, any, packets, form)
                            ->UseRealTime()
                            ->MinTime(0.5)
                            ->Unit(benchmark::kMillisecond);
                    }
                if (gpu_sized(scene)) continue;  // no CPU rows: the device rows run on GPUs only
                for (const bool batch : {false, true})
                    benchmark::RegisterBenchmark((base + (batch ? "/cpu_batch8" : "/cpu_blocks8")).c_str(),
                                                 BM_TraceCpuBlocks, scene, set, any, batch)
                        ->ArgName("threads")
                        ->Arg(2)
                        ->UseRealTime()
                        ->MinTime(0.5)
                        ->Unit(benchmark::kMillisecond);
                benchmark::RegisterBenchmark((base + "/cpu").c_str(), BM_TraceCpu, scene, set, any)
                    ->ArgName("threads")
                    ->Arg(2)
                    ->UseRealTime()
                    ->MinTime(0.5)
                    ->Unit(benchmark::kMillisecond);
            }
    for (const auto& [name, which] : {std::pair{"level-wise", RefitCase::level_wise}, std::pair{"one-pass", RefitCase::one_pass},
                                      std::pair{"cpu", RefitCase::cpu}})
        benchmark::RegisterBenchmark((std::string("cl_refit/") + name).c_str(), BM_Refit, which)
            ->ArgNames({"tris", "objects"})
            ->ArgsProduct({{10000, 100000, 1000000}, {1, 100}})
            ->UseRealTime()
            ->MinTime(0.3)
            ->Unit(benchmark::kMillisecond);
    for (const char* mesh : {"torus2k", "bunny", "torus100k"}) {
        for (const auto& [method, mname] :
             {std::pair{rcl::DeviceBuildMethod::ploc, "ploc"}, std::pair{rcl::DeviceBuildMethod::sortaxis, "sortaxis"}})
            for (const auto& [name, which] : {std::pair{"device", BuildCase::device}, std::pair{"cpu_twin/threads:2", BuildCase::cpu_twin}})
                benchmark::RegisterBenchmark((std::string("cl_build/") + mesh + "/" + mname + "/" + name).c_str(), BM_Build,
                                             std::string(mesh), which, method)
                    ->UseRealTime()
                    ->MinTime(0.5)
                    ->Unit(benchmark::kMillisecond);
        benchmark::RegisterBenchmark((std::string("cl_build/") + mesh + "/cpu_sah/threads:2").c_str(), BM_Build, std::string(mesh),
                                     BuildCase::cpu_sah, rcl::DeviceBuildMethod::ploc)
            ->UseRealTime()
            ->MinTime(0.5)
            ->Unit(benchmark::kMillisecond);
    }
    benchmark::RegisterBenchmark("cl_program/first", BM_ProgramFirst)->Iterations(3)->UseRealTime()->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("cl_program/cached", BM_ProgramCached)->UseRealTime()->Unit(benchmark::kMicrosecond);
    benchmark::RegisterBenchmark("cl_frame/torus100k/device", BM_FrameDevice, rcl::NodeForm::full)->UseRealTime()->MinTime(1.0)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("cl_frame/torus100k/device_q", BM_FrameDevice, rcl::NodeForm::quantized)->UseRealTime()->MinTime(1.0)->Unit(benchmark::kMillisecond);
    benchmark::RegisterBenchmark("cl_frame/torus100k/cpu", BM_FrameCpu)->UseRealTime()->MinTime(1.0)->Unit(benchmark::kMillisecond);
    return true;
}();

}  // namespace
