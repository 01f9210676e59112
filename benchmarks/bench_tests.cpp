// benchmarks/bench_tests.cpp — the ray/triangle tests, speed against accuracy.
//
// Cases: tests/<scene>/<watertight|mt|thesis|blocks>/threads:1
//   watertight, mt, thesis: intersect_closest<Test> over raykit_wide8_bvh(s) (the same
//     8-wide tree for all three, indexed triangles), on the scene's random rays.
//   blocks: BlockBvh8::build (watertight test, 4 triangles at a time, a tree built for it).
// Timed: closest hits of the 262,144 random rays (common.hpp), one thread. items/s = rays/s.
//
// Accuracy counters, computed once per scene and test, untimed:
//   edge_rays     100,000 rays aimed at interior vertices and edge midpoints of a tilted,
//                 jittered 400 x 400 grid (320,000 triangles) 1,000 units from the origin,
//                 from either side, at least 30 degrees off the plane (edge_case()): one
//                 continuous surface crossed well inside its border, so every ray must hit
//   edge_misses   of those, rays that report no hit (cracks)
//   wrong_prim    random rays whose primitive differs from brute force with the watertight
//                 test while their t differs by more than 1e-5 relative (a different
//                 surface, not a tie at a shared edge), or hit/miss differs
//
//   build-bench/benchmarks/bench_tests --benchmark_out=tests.json --benchmark_out_format=json
//   /usr/bin/python3 benchmarks/plot_tests.py tests.json docs/
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <map>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include "common.hpp"

namespace {

using rkbench::Scene;

enum class Kind { watertight, mt, thesis, blocks };

const char* name(Kind k) {
    switch (k) {
        case Kind::mt: return "mt";
        case Kind::thesis: return "thesis";
        case Kind::blocks: return "blocks";
        default: return "watertight";
    }
}

/// fn(query) with query(ray) -> Hit for kind k over a mesh, its WideBvh8 (scalar tests) and
/// a BlockBvh8 (blocks).
template <class Fn>
decltype(auto) with_query(Kind k, const raykit::MeshView& mv, const raykit::WideBvh8& w, const raykit::BlockBvh8& b,
                          Fn&& fn) {
    switch (k) {
        case Kind::mt:
            return fn([&](const raykit::Ray& r) { return raykit::intersect_closest<raykit::MollerTrumbore>(mv, w, r); });
        case Kind::thesis:
            return fn([&](const raykit::Ray& r) { return raykit::intersect_closest<raykit::ThesisTest>(mv, w, r); });
        case Kind::blocks:
            return fn([&](const raykit::Ray& r) { return raykit::intersect_closest(b, r); });
        default:
            return fn([&](const raykit::Ray& r) { return raykit::intersect_closest<raykit::Watertight>(mv, w, r); });
    }
}

/// The accuracy oracle: a tilted, jittered 400 x 400 grid of triangles (320,000), far from
/// the origin, and rays aimed at its interior vertices and edge midpoints from above or
/// below, at least 30 degrees off the plane. The grid is one continuous surface and every
/// ray crosses it well inside its border, so each ray must hit: a miss is a crack.
struct EdgeCase {
    raykit::Mesh mesh;
    raykit::WideBvh8 wide;
    raykit::BlockBvh8 blocks;
    std::vector<raykit::Ray> rays;
};

const EdgeCase& edge_case() {
    static const EdgeCase ec = [] {
        EdgeCase e;
        constexpr int n = 400;
        std::mt19937_64 rng(0xED6E5ull);
        std::uniform_real_distribution<float> U(-1.0f, 1.0f);
        // an orthonormal frame tilted off every axis
        const raykit::vec3 nrm = glm::normalize(raykit::vec3(0.3f, 0.8f, 0.5f));
        const raykit::vec3 tu = glm::normalize(glm::cross(nrm, raykit::vec3(0.0f, 0.0f, 1.0f)));
        const raykit::vec3 tv = glm::cross(nrm, tu);
        const raykit::vec3 origin(1000.0f, -500.0f, 250.0f);
        for (int j = 0; j <= n; ++j)
            for (int i = 0; i <= n; ++i) {
                const float x = float(i) + 0.3f * U(rng), y = float(j) + 0.3f * U(rng);  // jittered in-plane
                e.mesh.positions.push_back(origin + x * tu + y * tv);
            }
        const auto at = [&](int i, int j) { return std::uint32_t(j * (n + 1) + i); };
        for (int j = 0; j < n; ++j)
            for (int i = 0; i < n; ++i) {
                e.mesh.triangles.push_back({{at(i, j), at(i + 1, j), at(i + 1, j + 1)}});
                e.mesh.triangles.push_back({{at(i, j), at(i + 1, j + 1), at(i, j + 1)}});
            }
        e.wide = raykit::WideBvh8::build(
            raykit::build_bvh<raykit::BinnedSahBuilder>(e.mesh, raykit::BinnedSahBuilder::Config{}));
        e.blocks = raykit::BlockBvh8::build(e.mesh);
        std::uniform_int_distribution<int> inner(5, n - 5);
        for (int k = 0; k < 100000; ++k) {
            const int i = inner(rng), j = inner(rng);
            const raykit::vec3 a = e.mesh.positions[at(i, j)];
            const raykit::vec3 b = e.mesh.positions[k % 3 == 1 ? at(i + 1, j) : at(i + 1, j + 1)];  // an edge, or the diagonal
            const raykit::vec3 target = k % 3 == 0 ? a : (a + b) * 0.5f;
            const float side = (k & 4) ? 1.0f : -1.0f;
            const raykit::vec3 off = side * nrm * 3.0f + (U(rng) * tu + U(rng) * tv) * 1.5f;  // >= 30 deg off the plane
            e.rays.push_back(raykit::Ray{target + off, 0.0f, -off, raykit::kInf});
        }
        return e;
    }();
    return ec;
}

/// Misses of test `k` on edge_case()'s rays (each must hit).
std::size_t edge_misses(Kind k) {
    const EdgeCase& e = edge_case();
    return with_query(k, e.mesh, e.wide, e.blocks, [&](auto query) {
        std::size_t miss = 0;
        for (const raykit::Ray& r : e.rays) miss += !query(r).valid();
        return miss;
    });
}

struct Accuracy {
    double edge_rays = 0, edge_misses = 0, wrong_prim = 0;
};

const Accuracy& accuracy(const Scene& s, Kind k) {
    static std::mutex m;
    static std::map<std::pair<std::string, int>, Accuracy> cache;
    std::lock_guard lock(m);
    auto key = std::make_pair(s.name, int(k));
    if (auto it = cache.find(key); it != cache.end()) return it->second;
    Accuracy a;
    a.edge_rays = double(edge_case().rays.size());
    a.edge_misses = double(edge_misses(k));
    const auto& rays = rkbench::rays(s, "random");
    const raykit::MeshView mv(s.mesh);
    const raykit::Bvh& bvh = rkbench::raykit_bvh(s);
    with_query(k, mv, rkbench::raykit_wide8_bvh(s), rkbench::raykit_block8_bvh(s), [&](auto query) {
        for (std::size_t i = 0; i < rays.size(); i += 16) {  // every 16th: 16,384 rays
            const raykit::Hit o = raykit::intersect_closest(mv, bvh, rays[i]);  // == brute force (test_bvh)
            const raykit::Hit h = query(rays[i]);
            if (h.valid() != o.valid() || (h.valid() && h.prim != o.prim && std::abs(h.t - o.t) > 1e-5f * o.t))
                a.wrong_prim += 1;
        }
        return 0;
    });
    return cache[key] = a;
}

void BM_test(benchmark::State& state, std::string scene_name, Kind k) {
    const Scene* s = rkbench::scene_or_skip(state, scene_name);
    if (!s) return;
    const auto& rays = rkbench::rays(*s, "random");
    const Accuracy& a = accuracy(*s, k);
    std::vector<float> out(rays.size());
    with_query(k, s->mesh, rkbench::raykit_wide8_bvh(*s), rkbench::raykit_block8_bvh(*s), [&](auto query) {
        for (auto _ : state) {
            for (std::size_t i = 0; i < rays.size(); ++i) out[i] = query(rays[i]).t;
            benchmark::ClobberMemory();
        }
        return 0;
    });
    state.SetItemsProcessed(static_cast<std::int64_t>(state.iterations()) * static_cast<std::int64_t>(rays.size()));
    state.counters["Mrays/s"] =
        benchmark::Counter(double(rays.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
    state.counters["edge_rays"] = a.edge_rays;
    state.counters["edge_misses"] = a.edge_misses;
    state.counters["wrong_prim"] = a.wrong_prim;
}

const bool registered = [] {
    for (const std::string sc : {"bunny", "torus100k"})
        for (Kind k : {Kind::watertight, Kind::mt, Kind::thesis, Kind::blocks})
            benchmark::RegisterBenchmark(("tests/" + sc + "/" + name(k) + "/threads:1").c_str(), BM_test, sc, k)
                ->UseRealTime()
                ->MinTime(0.5)
                ->Unit(benchmark::kMillisecond);
    return true;
}();

}  // namespace
