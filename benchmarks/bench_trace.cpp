// benchmarks/bench_trace.cpp — single-ray closest-hit and any-hit throughput, raykit vs Embree 3.
//
// Cases: trace/<scene>/<rays>/<closest|any>/<raykit|wide|wide8|wide8copy|embree>/threads:<T>
//   scene   bunny, torus100k, torus1M            (common.hpp)
//   rays    primary, random, 262 144 rays each   (common.hpp; any-hit uses the same rays, tmax = inf)
//   T       1, 2 std::threads, static round-robin chunks of 256 rays (common.hpp trace_parallel)
// raykit: BinnedSahBuilder with its default Config, intersect_closest / intersect_any
// (watertight triangle test) on the binary Bvh; wide / wide8: the same tree collapsed
// to a WideBvh / WideBvh8 (bvh/wide.hpp, 4 / 8 children per node), same leaves, same answers;
// wide8copy: WideBvh8 with the opt-in LeafTriangles copy (36 B per triangle, no index chase). Embree: one default-config device, one scene per mesh with
// one RTC_GEOMETRY_TYPE_TRIANGLE geometry, RTC_BUILD_QUALITY_MEDIUM, rtcIntersect1 /
// rtcOccluded1. Both write one result per ray into the same output arrays. items/s = rays/s.
//
// Counters: Mrays/s; hit_frac (fraction of rays that hit / are occluded, from this
// library's results); mismatch (computed once, untimed, for every case of a scene and ray
// set): closest — rays whose hit/miss differs between raykit and Embree, or whose
// primitive differs while |t_raykit − t_embree| > 1e-4·t_raykit; any — rays whose
// occluded flag differs.
//
//   build-bench/benchmarks/bench_trace --benchmark_out=bench_trace.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

#include "common.hpp"

namespace {

using rkbench::Scene;

constexpr double kMinTime = 0.5;  // seconds per case

enum class Lib { raykit, wide, wide8, wide8copy, embree };

struct Outputs {
    std::vector<float> t;
    std::vector<std::uint32_t> prim;
    std::vector<std::uint8_t> occluded;
    explicit Outputs(std::size_t n) : t(n), prim(n), occluded(n) {}
};

template <class Tree, class Triangles>
void trace_raykit(const Tree& bvh, const Triangles& mesh, const std::vector<raykit::Ray>& rays, bool any,
                  unsigned threads, Outputs& out) {
    if (any) {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) out.occluded[i] = raykit::intersect_any(mesh, bvh, rays[i]);
        });
    } else {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                const raykit::Hit h = raykit::intersect_closest(mesh, bvh, rays[i]);
                out.t[i] = h.t;
                out.prim[i] = h.prim;
            }
        });
    }
}

#ifdef RAYKIT_HAVE_EMBREE
struct EmbreeScene {
    std::vector<rkbench::EmbreeVertex> verts;
    RTCScene scene = nullptr;
    std::string error;
};

/// Embree scene over `s` on the default device, MEDIUM quality, built once.
const EmbreeScene& embree_scene(const Scene& s) {
    static std::mutex m;
    static std::map<std::string, std::unique_ptr<EmbreeScene>> cache;
    std::lock_guard lock(m);
    auto& slot = cache[s.name];
    if (!slot) {
        slot = std::make_unique<EmbreeScene>();
        slot->verts = rkbench::embree_vertices(s.mesh);
        rkbench::take_embree_error();
        slot->scene = rkbench::make_embree_scene(rkbench::default_embree_device(), s.mesh, slot->verts,
                                                 RTC_BUILD_QUALITY_MEDIUM);
        slot->error = rkbench::take_embree_error();
    }
    return *slot;
}

void trace_embree(RTCScene scene, const std::vector<raykit::Ray>& rays, bool any, unsigned threads, Outputs& out) {
    if (any) {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            for (std::size_t i = b; i < e; ++i) {
                RTCRayHit rh = rkbench::to_embree(rays[i]);
                rtcOccluded1(scene, &ctx, &rh.ray);
                out.occluded[i] = rh.ray.tfar < 0.0f;  // Embree sets tfar = -inf on occlusion
            }
        });
    } else {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            RTCIntersectContext ctx;
            rtcInitIntersectContext(&ctx);
            for (std::size_t i = b; i < e; ++i) {
                RTCRayHit rh = rkbench::to_embree(rays[i]);
                rtcIntersect1(scene, &ctx, &rh);
                const bool hit = rh.hit.geomID != RTC_INVALID_GEOMETRY_ID;
                out.t[i] = hit ? rh.ray.tfar : raykit::kInf;
                out.prim[i] = hit ? rh.hit.primID : raykit::kInvalidIndex;
            }
        });
    }
}
#endif

/// Agreement of raykit and Embree on one scene and ray set, computed once.
struct Check {
    double mismatch_closest = -1, mismatch_any = -1;  // -1: Embree not built in
    double hit_frac_raykit = 0, hit_frac_embree = 0, occluded_frac_raykit = 0, occluded_frac_embree = 0;
};

const Check& check(const Scene& s, const std::string& set) {
    static std::mutex m;
    static std::map<std::string, Check> cache;
    std::lock_guard lock(m);
    const std::string key = s.name + "/" + set;
    if (auto it = cache.find(key); it != cache.end()) return it->second;
    Check c;
    const auto& rays = rkbench::rays(s, set);
    const std::size_t n = rays.size();
    Outputs rk(n);
    trace_raykit(rkbench::raykit_bvh(s), raykit::MeshView(s.mesh), rays, false, 0, rk);
    trace_raykit(rkbench::raykit_bvh(s), raykit::MeshView(s.mesh), rays, true, 0, rk);
    std::size_t hits = 0, occ = 0;
    for (std::size_t i = 0; i < n; ++i) {
        hits += rk.prim[i] != raykit::kInvalidIndex;
        occ += rk.occluded[i];
    }
    c.hit_frac_raykit = double(hits) / double(n);
    c.occluded_frac_raykit = double(occ) / double(n);
#ifdef RAYKIT_HAVE_EMBREE
    const EmbreeScene& es = embree_scene(s);
    if (es.error.empty()) {
        Outputs em(n);
        trace_embree(es.scene, rays, false, 0, em);
        trace_embree(es.scene, rays, true, 0, em);
        std::size_t mc = 0, ma = 0, ehits = 0, eocc = 0;
        for (std::size_t i = 0; i < n; ++i) {
            const bool hr = rk.prim[i] != raykit::kInvalidIndex, he = em.prim[i] != raykit::kInvalidIndex;
            ehits += he;
            eocc += em.occluded[i];
            if (hr != he) ++mc;
            else if (hr && rk.prim[i] != em.prim[i] && std::abs(rk.t[i] - em.t[i]) > 1e-4f * rk.t[i]) ++mc;
            ma += rk.occluded[i] != em.occluded[i];
        }
        c.mismatch_closest = double(mc);
        c.mismatch_any = double(ma);
        c.hit_frac_embree = double(ehits) / double(n);
        c.occluded_frac_embree = double(eocc) / double(n);
    }
#endif
    return cache[key] = c;
}

void BM_trace(benchmark::State& state, std::string scene_name, std::string set, bool any, Lib lib,
              unsigned threads) {
    const Scene* s = rkbench::scene_or_skip(state, scene_name);
    if (!s) return;
    const auto& rays = rkbench::rays(*s, set);
    const Check& c = check(*s, set);
    Outputs out(rays.size());
    // every raykit configuration: the same loop over (tree, triangle source)
    const auto time_raykit = [&](const auto& tree, const auto& tris) {
        for (auto _ : state) {
            trace_raykit(tree, tris, rays, any, threads, out);
            benchmark::ClobberMemory();
        }
        state.counters["hit_frac"] = any ? c.occluded_frac_raykit : c.hit_frac_raykit;
    };
    const raykit::MeshView mesh(s->mesh);
    if (lib == Lib::raykit) {
        time_raykit(rkbench::raykit_bvh(*s), mesh);
    } else if (lib == Lib::wide) {
        time_raykit(rkbench::raykit_wide_bvh(*s), mesh);
    } else if (lib == Lib::wide8) {
        time_raykit(rkbench::raykit_wide8_bvh(*s), mesh);
    } else if (lib == Lib::wide8copy) {
        time_raykit(rkbench::raykit_wide8_bvh(*s), rkbench::raykit_wide8_leaf_triangles(*s));
    } else {
#ifdef RAYKIT_HAVE_EMBREE
        const EmbreeScene& es = embree_scene(*s);
        if (!es.error.empty()) {
            state.SkipWithError(es.error.c_str());
            return;
        }
        for (auto _ : state) {
            trace_embree(es.scene, rays, any, threads, out);
            benchmark::ClobberMemory();
        }
        state.counters["hit_frac"] = any ? c.occluded_frac_embree : c.hit_frac_embree;
#else
        state.SkipWithError("built without Embree");
        return;
#endif
    }
    const double per_iter = double(rays.size());
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(rays.size()));
    state.counters["Mrays/s"] = benchmark::Counter(per_iter * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
    const double mm = any ? c.mismatch_any : c.mismatch_closest;
    if (mm >= 0) state.counters["mismatch"] = mm;
}

const bool registered = [] {
    std::vector<Lib> libs{Lib::raykit, Lib::wide, Lib::wide8, Lib::wide8copy};
#ifdef RAYKIT_HAVE_EMBREE
    libs.push_back(Lib::embree);
#endif
    for (const std::string& sc : rkbench::scene_names())
        for (const std::string& set : rkbench::ray_set_names())
            for (bool any : {false, true})
                for (unsigned threads : {1u, 2u})
                    for (Lib lib : libs) {
                        const std::string name = "trace/" + sc + "/" + set + "/" + (any ? "any" : "closest") + "/" +
                                                 (lib == Lib::raykit      ? "raykit"
                                                  : lib == Lib::wide      ? "wide"
                                                  : lib == Lib::wide8     ? "wide8"
                                                  : lib == Lib::wide8copy ? "wide8copy"
                                                                          : "embree") +
                                                 "/threads:" + std::to_string(threads);
                        benchmark::RegisterBenchmark(name.c_str(), BM_trace, sc, set, any, lib, threads)
                            ->UseRealTime()
                            ->MinTime(kMinTime)
                            ->Unit(benchmark::kMillisecond);
                    }
    return true;
}();

}  // namespace
