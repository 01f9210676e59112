// The thesis's bottom-up builders against the binned-SAH reference: speed
// against quality. One case per scene × builder setting × threads; the timed
// loop is the build (boxes included). Counters:
//   Mtris/s        build throughput
//   sah            SAH cost of the tree (Ct = Ci = 1, bvh/sah.hpp)
//   primary_Mrays  closest-hit Mrays/s on 512² camera rays (2 threads, once per case)
//   random_Mrays   closest-hit Mrays/s on 512² random rays (2 threads, once per case)
// Embree's scene builds at LOW / MEDIUM / HIGH quality are reference points
// (build speed and rtcIntersect1 speed on the same rays; their trees are not
// binary, so no SAH value).
//
// Names: builders/<scene>/<builder>[/<setting>]/threads:<T>
// plot.py turns the JSON into the charts in docs/.
#include <benchmark/benchmark.h>

#include <chrono>
#include <string>
#include <vector>

#include "common.hpp"
#include "raykit/scene/build_options.hpp"

using namespace raykit;

namespace {

struct Setting {
    std::string name;
    BuildOptions opt;
};

std::vector<Setting> settings() {
    std::vector<Setting> out;
    BuildOptions o;
    out.push_back({"sah", o});
    o.builder = BuildOptions::Builder::pairwise;
    o.metric = BuildOptions::Metric::centre;
    out.push_back({"pairwise/centre", o});
    o.metric = BuildOptions::Metric::area;
    out.push_back({"pairwise/area", o});
    const unsigned windows[] = {1u, 2u, 4u, 6u, 8u, 16u, 32u, 64u};
    // the thesis's rule: greedy pairing, centre distance, along x or in Morton order
    for (auto axis : {BuildOptions::Axis::x, BuildOptions::Axis::morton}) {
        for (unsigned w : windows) {
            BuildOptions s;
            s.builder = BuildOptions::Builder::sortaxis;
            s.axis = axis;
            s.metric = BuildOptions::Metric::centre;
            s.pairing = BuildOptions::Pairing::greedy;
            s.window = w;
            out.push_back({std::string("sortaxis/") + BuildOptions::name(axis) + "/W:" + std::to_string(w), s});
        }
    }
    for (unsigned w : {6u, 16u}) {
        BuildOptions s;
        s.builder = BuildOptions::Builder::sortaxis;
        s.axis = BuildOptions::Axis::morton;
        s.metric = BuildOptions::Metric::area;
        s.pairing = BuildOptions::Pairing::greedy;
        s.window = w;
        out.push_back({"sortaxis/morton-area/W:" + std::to_string(w), s});
    }
    // mutual nearest neighbours within ±W (the default: area, W 2)
    for (auto metric : {BuildOptions::Metric::area, BuildOptions::Metric::centre}) {
        for (unsigned w : windows) {
            if (metric == BuildOptions::Metric::centre && w != 2 && w != 6) continue;
            BuildOptions s;
            s.builder = BuildOptions::Builder::sortaxis;
            s.axis = BuildOptions::Axis::morton;
            s.metric = metric;
            s.pairing = BuildOptions::Pairing::mutual;
            s.window = w;
            out.push_back({std::string("sortaxis/mutual-") + BuildOptions::name(metric) + "/W:" + std::to_string(w), s});
        }
    }
    {
        BuildOptions s;
        s.builder = BuildOptions::Builder::sortaxis;
        s.optimize = OptimizeConfig{};
        out.push_back({"sortaxis/mutual-area/W:2/opt", s});
    }
    // PLOC without and with the post-pass (the default: R 4 with it)
    for (unsigned r : {2u, 4u, 8u, 16u, 32u}) {
        for (bool opt : {false, true}) {
            if (opt && r > 8) continue;
            BuildOptions s;
            s.builder = BuildOptions::Builder::ploc;
            s.radius = r;
            if (!opt) s.optimize = OptimizeConfig::off();
            out.push_back({"ploc/R:" + std::to_string(r) + (opt ? "/opt" : ""), s});
        }
    }
    return out;
}

double trace_mrays(const rkbench::Scene& s, const Bvh& bvh, const std::vector<Ray>& rays) {
    std::vector<std::uint8_t> sink(rays.size());
    const auto t0 = std::chrono::steady_clock::now();
    rkbench::trace_parallel(rays.size(), 2, [&](std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) sink[i] = intersect_closest(s.mesh, bvh, rays[i]).valid();
    });
    const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    benchmark::DoNotOptimize(sink.data());
    return double(rays.size()) / sec / 1e6;
}

void bm_build(benchmark::State& state, std::string scene, Setting st, unsigned threads) {
    const rkbench::Scene* s = rkbench::scene_or_skip(state, scene);
    if (!s) return;
    // the O(n log n)-but-sequential pairwise build on 1M triangles takes seconds: fewer iterations
    st.opt.threads = threads;
    Bvh bvh;
    for (auto _ : state) {
        bvh = build_bvh(MeshView(s->mesh), st.opt);
        benchmark::DoNotOptimize(bvh.nodes.data());
    }
    state.counters["Mtris/s"] =
        benchmark::Counter(double(s->triangles()) * double(state.iterations()) / 1e6, benchmark::Counter::kIsRate);
    state.counters["sah"] = sah_cost(bvh);
    state.counters["primary_Mrays"] = trace_mrays(*s, bvh, rkbench::rays(*s, "primary"));
    state.counters["random_Mrays"] = trace_mrays(*s, bvh, rkbench::rays(*s, "random"));
}

#ifdef RAYKIT_HAVE_EMBREE
void bm_embree(benchmark::State& state, std::string scene, RTCBuildQuality q, unsigned threads) {
    const rkbench::Scene* s = rkbench::scene_or_skip(state, scene);
    if (!s) return;
    const std::string cfg = "threads=" + std::to_string(threads);
    rkbench::EmbreeDevice dev(cfg.c_str());
    const auto verts = rkbench::embree_vertices(s->mesh);
    RTCScene sc = nullptr;
    for (auto _ : state) {
        if (sc) rtcReleaseScene(sc);
        sc = rkbench::make_embree_scene(dev.device, s->mesh, verts, q);
    }
    state.counters["Mtris/s"] =
        benchmark::Counter(double(s->triangles()) * double(state.iterations()) / 1e6, benchmark::Counter::kIsRate);
    for (const char* set : {"primary", "random"}) {
        const auto& rays = rkbench::rays(*s, set);
        std::vector<std::uint8_t> sink(rays.size());
        const auto t0 = std::chrono::steady_clock::now();
        rkbench::trace_parallel(rays.size(), 2, [&](std::size_t b, std::size_t e) {
            RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            for (std::size_t i = b; i < e; ++i) {
                RTCRayHit rh = rkbench::to_embree(rays[i]);
                rtcIntersect1(sc, &ctx, &rh);
                sink[i] = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
            }
        });
        const double sec = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        state.counters[std::string(set) + "_Mrays"] = double(rays.size()) / sec / 1e6;
    }
    rtcReleaseScene(sc);
}
#endif

const bool registered = [] {
    for (const std::string scene : {"bunny", "thesis", "torus100k", "torus1M"}) {
        for (unsigned threads : {1u, 2u}) {
            for (const Setting& st : settings()) {
                if (scene == "torus1M" && st.name.find("W:64") != std::string::npos) continue;
                // the thesis's x-axis trees on 1M triangles cost 50-200x binned SAH and trace for minutes
                if (scene == "torus1M" && st.name.rfind("sortaxis/x/", 0) == 0) continue;
                const std::string name = "builders/" + scene + "/" + st.name + "/threads:" + std::to_string(threads);
                auto* b = benchmark::RegisterBenchmark(name.c_str(), bm_build, scene, st, threads);
                b->Unit(benchmark::kMillisecond)->UseRealTime();
                if (scene == "torus1M") b->Iterations(st.opt.builder == BuildOptions::Builder::pairwise ? 1 : 3);
                else b->MinTime(0.2);
            }
#ifdef RAYKIT_HAVE_EMBREE
            const std::pair<const char*, RTCBuildQuality> qs[] = {
                {"low", RTC_BUILD_QUALITY_LOW}, {"medium", RTC_BUILD_QUALITY_MEDIUM}, {"high", RTC_BUILD_QUALITY_HIGH}};
            for (const auto& [qn, q] : qs) {
                const std::string name = "builders/" + scene + "/embree/" + qn + "/threads:" + std::to_string(threads);
                benchmark::RegisterBenchmark(name.c_str(), bm_embree, scene, q, threads)
                    ->Unit(benchmark::kMillisecond)
                    ->UseRealTime()
                    ->MinTime(0.2);
            }
#endif
        }
    }
    return true;
}();

}  // namespace
