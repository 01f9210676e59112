// benchmarks/bench_render.cpp — CPU renderer frame time (Google Benchmark).
//
// Cases: render/<scene>/<variant>/spp:<N>/threads:<T>, 640 x 480, one point light.
//   scene    thesis  RAYKIT_SHARED_DATA_DIR/obj/thesis_scene/Scene.obj (24k triangles, 21 textured
//                    materials, alpha-tested foliage), camera (20, 8, 24) -> (0, 2.5, 0), fov 45,
//                    light at (-25, 35, 30)  (the view of docs/thesis_scene.png)
//            bunny   RAYKIT_SHARED_DATA_DIR/obj/stanford_bunny/stanford-bunny.obj (69k triangles, no
//                    materials), raykit::frame_scene + raykit::default_key_light
//   variant  primary   depth shader: camera rays + closest hit only
//            noshadow  whitted, max depth 1, no shadow rays
//            full      whitted, max depth 1 (one reflection bounce), shadow rays — the target
//            mirror    full, with every material made a mirror (illum 3, Ks 0.3): one reflection ray
//                      per hit, so the bounce is exercised (the thesis scene has no reflective material)
//   N        1, 4 samples per pixel;  T  1, 2 threads
// Load, BVH build, LeafTriangles and texture loading are done once, outside the timing.
//
// Counters: Mrays_s (all rays traced per second of wall time), rays (per frame), and per stage,
// from one extra untimed frame with RenderSettings::time_stages: trace_ms, shadow_ms, shade_ms
// (thread time per frame divided by T, i.e. the wall-time share of each stage; shade includes
// camera rays and texture lookups).
//
//   build/benchmarks/bench_render --benchmark_out=bench_render.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <string>

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/render/render_cpu.hpp"

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

namespace {

using namespace raykit;

constexpr std::uint32_t kWidth = 640, kHeight = 480;

struct BenchScene {
    RenderScene rs;
    Camera cam;
};

std::filesystem::path data(const char* rel) { return std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / rel; }

/// Loaded once per (scene, mirror) pair; nullptr when the data file is missing.
const BenchScene* bench_scene(const std::string& name, bool mirror) {
    static std::mutex m;
    static std::map<std::pair<std::string, bool>, std::unique_ptr<BenchScene>> cache;
    std::lock_guard lock(m);
    auto key = std::make_pair(name, mirror);
    if (auto it = cache.find(key); it != cache.end()) return it->second.get();
    const std::filesystem::path file =
        name == "thesis" ? data("obj/thesis_scene/Scene.obj") : data("obj/stanford_bunny/stanford-bunny.obj");
    if (!std::filesystem::exists(file)) return (cache[key] = nullptr).get();
    auto s = std::make_unique<BenchScene>();
    Mesh mesh = load_obj(file);
    if (mirror) {
        if (mesh.materials.empty()) {
            mesh.materials.emplace_back();
            for (auto& id : mesh.material_ids) id = 0;
        }
        for (Material& mat : mesh.materials) {
            mat.illum = 3;
            mat.ks = vec3(0.3f);
        }
    }
    s->rs = prepare_render_scene(std::move(mesh));
    if (name == "thesis") {
        s->cam.position = vec3(20.0f, 8.0f, 24.0f);
        s->cam.target = vec3(0.0f, 2.5f, 0.0f);
        s->cam.vfov_degrees = 45.0f;
        s->cam.width = kWidth;
        s->cam.height = kHeight;
        s->rs.lights.push_back(Light::point(vec3(-25.0f, 35.0f, 30.0f)));
    } else {
        s->cam = frame_scene(s->rs.bounds(), kWidth, kHeight);
        s->rs.lights.push_back(default_key_light(s->cam));
    }
    return (cache[key] = std::move(s)).get();
}

void run(benchmark::State& state, const std::string& scene, const std::string& variant, unsigned spp,
         unsigned threads) {
    const BenchScene* s = bench_scene(scene, variant == "mirror");
    if (!s) {
        state.SkipWithError((scene + ": data file not found under " RAYKIT_SHARED_DATA_DIR).c_str());
        return;
    }
    RenderSettings set;
    set.spp = spp;
    set.threads = threads;
    set.shade.max_depth = 1;
    if (variant == "primary") set.shade.shader = ShaderKind::depth;
    if (variant == "noshadow") set.shade.shadows = false;
    const ShadeScene view = s->rs.view();
    RenderStats st;
    std::uint64_t rays = 0;
    for (auto _ : state) {
        Image img = render_cpu(view, s->cam, set, &st);
        benchmark::DoNotOptimize(img.pixels.data());
        rays += st.rays.total();
    }
    const std::uint64_t per_frame = st.rays.total();
    state.counters["Mrays_s"] = benchmark::Counter(double(rays) * 1e-6, benchmark::Counter::kIsRate);
    state.counters["rays"] = double(per_frame);
    RenderSettings prof = set;
    prof.time_stages = true;
    RenderStats ps;
    render_cpu(view, s->cam, prof, &ps);
    state.counters["trace_ms"] = ps.trace_thread_ms / ps.threads;
    state.counters["shadow_ms"] = ps.shadow_thread_ms / ps.threads;
    state.counters["shade_ms"] = ps.shade_thread_ms / ps.threads;
}

const bool registered = [] {
    for (const char* scene : {"thesis", "bunny"})
        for (const char* variant : {"primary", "noshadow", "full", "mirror"})
            for (unsigned spp : {1u, 4u})
                for (unsigned threads : {1u, 2u}) {
                    const std::string name = std::string("render/") + scene + "/" + variant + "/spp:" +
                                             std::to_string(spp) + "/threads:" + std::to_string(threads);
                    benchmark::RegisterBenchmark(name.c_str(), [=](benchmark::State& st) {
                        run(st, scene, variant, spp, threads);
                    })
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime()
                        ->MinTime(spp == 1 ? 1.0 : 2.0);
                }
    return true;
}();

}  // namespace
