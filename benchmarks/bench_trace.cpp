// benchmarks/bench_trace.cpp — single-ray closest-hit and any-hit throughput, raykit vs Embree 3.
//
// Cases: trace/<scene>/<rays>/<closest|any>/<raykit|wide8|block8|batch|embree|embree_high|embree16>/threads:<T>
//   scene   bunny, torus100k, torus1M            (common.hpp)
//   rays    primary, random, 262 144 rays each   (common.hpp; any-hit uses the same rays, tmax = inf)
//   T       1, 2 std::threads, static round-robin chunks of 256 rays (common.hpp trace_parallel)
// raykit: BinnedSahBuilder with its default Config, intersect_closest / intersect_any
// (watertight triangle test) on the binary Bvh; wide8: the same tree collapsed to a
// WideBvh8 (bvh/wide.hpp, 8 children per node), same leaves, same answers; block8:
// BlockBvh8::build (scene/block_bvh.hpp): a binned-SAH tree built for 4-triangle blocks
// (leaf_block 4, leaves up to 12), collapsed 8-wide, leaves tested 4 triangles at a time
// (vertex copies, 160 B per block); batch: the same BlockBvh8 through the batch call
// intersect_closest / intersect_any(tree, rays, results) on each thread's chunks of 256 rays
// (packets of kPacketWidth consecutive rays, bvh/traverse_packet.hpp). Embree: one
// default-config device, one scene per mesh with one RTC_GEOMETRY_TYPE_TRIANGLE geometry,
// scene and geometry at RTC_BUILD_QUALITY_MEDIUM (embree, embree16) or HIGH (embree_high,
// spatial splits); rtcIntersect1 / rtcOccluded1, or for embree16 rtcIntersect16 /
// rtcOccluded16 on 16 consecutive rays (the batch's grouping; a coherent context). All write
// one result per ray into the same output arrays. items/s = rays/s.
//
// Counters: Mrays/s; hit_frac (fraction of rays that hit / are occluded, from this
// library's results); mismatch (computed once, untimed, for every case of a scene and ray
// set): closest — rays whose hit/miss differs between raykit and Embree, or whose
// primitive differs while |t_raykit − t_embree| > 1e-4·t_raykit; any — rays whose
// occluded flag differs. block_vs_binary: rays whose block8 hit (prim, t) or
// occluded flag differs from the binary tree's in any bit (expected 0: same test, same tie rule).
//
//   build-bench/benchmarks/bench_trace --benchmark_out=bench_trace.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <map>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <vector>

#include "common.hpp"

namespace {

using rkbench::Scene;

constexpr double kMinTime = 0.5;  // seconds per case

enum class Lib { raykit, wide, wide8, block8, batch, embree, embree_high, embree16 };

struct Outputs {
    std::vector<float> t;
    std::vector<std::uint32_t> prim;
    std::vector<std::uint8_t> occluded;
    explicit Outputs(std::size_t n) : t(n), prim(n), occluded(n) {}
};

/// `query(ray, any)` returns a Hit (closest) or bool (any hit).
template <class Query>
void trace_raykit(Query&& query, const std::vector<raykit::Ray>& rays, bool any, unsigned threads, Outputs& out) {
    if (any) {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) out.occluded[i] = query.any(rays[i]);
        });
    } else {
        rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
            for (std::size_t i = b; i < e; ++i) {
                const raykit::Hit h = query.closest(rays[i]);
                out.t[i] = h.t;
                out.prim[i] = h.prim;
            }
        });
    }
}

/// A tree over a triangle source (indexed mesh or leaf copy).
template <class Tree, class Triangles>
struct TreeQuery {
    const Tree& tree;
    const Triangles& tris;
    raykit::Hit closest(const raykit::Ray& r) const { return raykit::intersect_closest(tris, tree, r); }
    bool any(const raykit::Ray& r) const { return raykit::intersect_any(tris, tree, r); }
};
template <class Tree, class Triangles>
TreeQuery(const Tree&, const Triangles&) -> TreeQuery<Tree, Triangles>;

/// A tree that carries its own triangles (BlockBvh).
template <class Tree>
struct SelfQuery {
    const Tree& tree;
    raykit::Hit closest(const raykit::Ray& r) const { return raykit::intersect_closest(tree, r); }
    bool any(const raykit::Ray& r) const { return raykit::intersect_any(tree, r); }
};
template <class Tree>
SelfQuery(const Tree&) -> SelfQuery<Tree>;

/// The batch call on each chunk of rays (packets inside).
void trace_batch(const raykit::BlockBvh8& tree, const std::vector<raykit::Ray>& rays, bool any, unsigned threads,
                 Outputs& out) {
    rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
        const std::span<const raykit::Ray> chunk(rays.data() + b, e - b);
        if (any) {
            raykit::intersect_any(tree, chunk, std::span<std::uint8_t>(out.occluded.data() + b, e - b), 1);
        } else {
            raykit::Hit hits[rkbench::kChunkRays];
            raykit::intersect_closest(tree, chunk, std::span<raykit::Hit>(hits, e - b), 1);
            for (std::size_t i = b; i < e; ++i) {
                out.t[i] = hits[i - b].t;
                out.prim[i] = hits[i - b].prim;
            }
        }
    });
}

#ifdef RAYKIT_HAVE_EMBREE
struct EmbreeScene {
    std::vector<rkbench::EmbreeVertex> verts;
    RTCScene scene = nullptr;
    std::string error;
};

/// Embree scene over `s` on the default device at `quality`, built once.
const EmbreeScene& embree_scene(const Scene& s, RTCBuildQuality quality = RTC_BUILD_QUALITY_MEDIUM) {
    static std::mutex m;
    static std::map<std::string, std::unique_ptr<EmbreeScene>> cache;
    std::lock_guard lock(m);
    auto& slot = cache[s.name + (quality == RTC_BUILD_QUALITY_HIGH ? "/high" : "/medium")];
    if (!slot) {
        slot = std::make_unique<EmbreeScene>();
        slot->verts = rkbench::embree_vertices(s.mesh);
        rkbench::take_embree_error();
        slot->scene = rkbench::make_embree_scene(rkbench::default_embree_device(), s.mesh, slot->verts, quality);
        slot->error = rkbench::take_embree_error();
    }
    return *slot;
}

/// rtcIntersect16 / rtcOccluded16 on 16 consecutive rays of each chunk (a short last group
/// has its missing lanes invalid).
void trace_embree16(RTCScene scene, const std::vector<raykit::Ray>& rays, bool any, unsigned threads, Outputs& out) {
    rkbench::trace_parallel(rays.size(), threads, [&](std::size_t b, std::size_t e) {
        RTCIntersectContext ctx = rkbench::coherent_context();
        alignas(64) int valid[16];
        for (std::size_t g = b; g < e; g += 16) {
            const std::size_t n = std::min<std::size_t>(16, e - g);
            RTCRayHit16 rh;
            for (unsigned k = 0; k < 16; ++k) {
                valid[k] = k < n ? -1 : 0;
                rkbench::set_lane(rh.ray, k, rays[g + (k < n ? k : 0)]);
                rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
                rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
            }
            if (any) {
                rtcOccluded16(valid, scene, &ctx, &rh.ray);
                for (unsigned k = 0; k < n; ++k) out.occluded[g + k] = rh.ray.tfar[k] < 0.0f;
            } else {
                rtcIntersect16(valid, scene, &ctx, &rh);
                for (unsigned k = 0; k < n; ++k) {
                    const bool hit = rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID;
                    out.t[g + k] = hit ? rh.ray.tfar[k] : raykit::kInf;
                    out.prim[g + k] = hit ? rh.hit.primID[k] : raykit::kInvalidIndex;
                }
            }
        }
    });
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
    double block_vs_binary = 0;
    double batch_vs_single = 0;  // batch answers differing from block8's single rays in any bit
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
    const raykit::MeshView mv(s.mesh);
    trace_raykit(TreeQuery{rkbench::raykit_bvh(s), mv}, rays, false, 0, rk);
    trace_raykit(TreeQuery{rkbench::raykit_bvh(s), mv}, rays, true, 0, rk);
    std::size_t hits = 0, occ = 0;
    for (std::size_t i = 0; i < n; ++i) {
        hits += rk.prim[i] != raykit::kInvalidIndex;
        occ += rk.occluded[i];
    }
    c.hit_frac_raykit = double(hits) / double(n);
    {
        Outputs bk(n);
        trace_raykit(SelfQuery{rkbench::raykit_block8_bvh(s)}, rays, false, 0, bk);
        trace_raykit(SelfQuery{rkbench::raykit_block8_bvh(s)}, rays, true, 0, bk);
        std::size_t d = 0;
        for (std::size_t i = 0; i < n; ++i)
            d += bk.prim[i] != rk.prim[i] || std::bit_cast<std::uint32_t>(bk.t[i]) != std::bit_cast<std::uint32_t>(rk.t[i]) ||
                 bk.occluded[i] != rk.occluded[i];
        c.block_vs_binary = double(d);
        Outputs bt(n);
        trace_batch(rkbench::raykit_block8_bvh(s), rays, false, 0, bt);
        trace_batch(rkbench::raykit_block8_bvh(s), rays, true, 0, bt);
        std::size_t db = 0;
        for (std::size_t i = 0; i < n; ++i)
            db += bt.prim[i] != bk.prim[i] || std::bit_cast<std::uint32_t>(bt.t[i]) != std::bit_cast<std::uint32_t>(bk.t[i]) ||
                  bt.occluded[i] != bk.occluded[i];
        c.batch_vs_single = double(db);
    }
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
    const auto time_raykit = [&](const auto& query) {
        for (auto _ : state) {
            trace_raykit(query, rays, any, threads, out);
            benchmark::ClobberMemory();
        }
        state.counters["hit_frac"] = any ? c.occluded_frac_raykit : c.hit_frac_raykit;
    };
    const raykit::MeshView mesh(s->mesh);
    if (lib == Lib::raykit) {
        time_raykit(TreeQuery{rkbench::raykit_bvh(*s), mesh});
    } else if (lib == Lib::wide) {
        time_raykit(TreeQuery{rkbench::raykit_wide_bvh(*s), mesh});
    } else if (lib == Lib::wide8) {
        time_raykit(TreeQuery{rkbench::raykit_wide8_bvh(*s), mesh});
    } else if (lib == Lib::block8) {
        time_raykit(SelfQuery{rkbench::raykit_block8_bvh(*s)});
    } else if (lib == Lib::batch) {
        for (auto _ : state) {
            trace_batch(rkbench::raykit_block8_bvh(*s), rays, any, threads, out);
            benchmark::ClobberMemory();
        }
        state.counters["hit_frac"] = any ? c.occluded_frac_raykit : c.hit_frac_raykit;
    } else {
#ifdef RAYKIT_HAVE_EMBREE
        const EmbreeScene& es = embree_scene(*s, lib == Lib::embree_high ? RTC_BUILD_QUALITY_HIGH : RTC_BUILD_QUALITY_MEDIUM);
        if (!es.error.empty()) {
            state.SkipWithError(es.error.c_str());
            return;
        }
        for (auto _ : state) {
            if (lib == Lib::embree16) trace_embree16(es.scene, rays, any, threads, out);
            else trace_embree(es.scene, rays, any, threads, out);
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
    if (lib == Lib::block8) state.counters["block_vs_binary"] = c.block_vs_binary;
    if (lib == Lib::batch) state.counters["batch_vs_single"] = c.batch_vs_single;
}

const bool registered = [] {
    std::vector<Lib> libs{Lib::raykit, Lib::wide8, Lib::block8, Lib::batch};
#ifdef RAYKIT_HAVE_EMBREE
    libs.insert(libs.end(), {Lib::embree, Lib::embree_high, Lib::embree16});
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
                                                  : lib == Lib::block8    ? "block8"
                                                  : lib == Lib::batch     ? "batch"
                                                  : lib == Lib::embree_high ? "embree_high"
                                                  : lib == Lib::embree16  ? "embree16"
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
