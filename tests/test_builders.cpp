// Bottom-up builders (pairwise, sort-by-axis, PLOC) against brute force, the
// O(n²) pairwise reference, thread-count independence and the depth bound.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <functional>
#include <limits>
#include <mutex>
#include <random>
#include <set>
#include <string>
#include <thread>

#include "raykit.hpp"
#include "test_support.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/generate.hpp"

using namespace raykit;

#if defined(__SANITIZE_ADDRESS__)
#define RAYKIT_TEST_SANITIZED 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RAYKIT_TEST_SANITIZED 1
#endif
#endif
#ifndef RAYKIT_TEST_SANITIZED
#define RAYKIT_TEST_SANITIZED 0
#endif

namespace {

/// Problem sizes: smaller under the sanitizers (about ten times slower).
constexpr bool kSanitized = RAYKIT_TEST_SANITIZED != 0;
constexpr std::size_t scaled(std::size_t release, std::size_t sanitized) { return kSanitized ? sanitized : release; }

using BuildFn = std::function<Bvh(std::span<const AABB>, std::span<const vec3>, unsigned threads, unsigned leaf)>;

struct Setting {
    std::string name;
    BuildFn build;
};

/// The post-pass (bvh/optimize.hpp) on other inputs and with heavier
/// settings than PLOC's default: after sort-by-axis (the thesis's greedy
/// pairing gives the worst trees to start from), and every node a treelet
/// root with many nodes reinserted.
std::vector<Setting> optimized_settings() {
    std::vector<Setting> s;
    using SA = SortAxisBuilder::Config::Axis;
    using SM = SortAxisBuilder::Config::Metric;
    using SP = SortAxisBuilder::Config::Pairing;
    s.push_back({"sortaxis/default/opt", [](std::span<const AABB> b, std::span<const vec3> c, unsigned threads,
                                            unsigned leaf) {
                     SortAxisBuilder::Config cfg;
                     cfg.threads = threads;
                     cfg.leaf.max_leaf_size = leaf;
                     cfg.optimize = OptimizeConfig{};
                     return SortAxisBuilder::build(b, c, cfg);
                 }});
    s.push_back({"sortaxis/x/centre/greedy/W6/opt", [](std::span<const AABB> b, std::span<const vec3> c,
                                                        unsigned threads, unsigned leaf) {
                     SortAxisBuilder::Config cfg;
                     cfg.axis = SA::x;
                     cfg.metric = SM::centre;
                     cfg.pairing = SP::greedy;
                     cfg.window = 6;
                     cfg.threads = threads;
                     cfg.leaf.max_leaf_size = leaf;
                     cfg.optimize = OptimizeConfig{};
                     return SortAxisBuilder::build(b, c, cfg);
                 }});
    s.push_back({"ploc/R8/opt-heavy", [](std::span<const AABB> b, std::span<const vec3> c, unsigned threads,
                                         unsigned leaf) {
                     PlocBuilder::Config cfg;
                     cfg.radius = 8;
                     cfg.threads = threads;
                     cfg.leaf.max_leaf_size = leaf;
                     cfg.optimize = {0.25f, 3u, 1u};
                     return PlocBuilder::build(b, c, cfg);
                 }});
    return s;
}

std::vector<Setting> all_settings() {
    std::vector<Setting> s;
    using PM = PairwiseBuilder::Config::Metric;
    for (PM metric : {PM::centre, PM::area})
        s.push_back({std::string("pairwise/") + (metric == PM::centre ? "centre" : "area"),
                     [metric](std::span<const AABB> b, std::span<const vec3> c, unsigned threads, unsigned leaf) {
                         PairwiseBuilder::Config cfg;
                         cfg.metric = metric;
                         cfg.threads = threads;
                         cfg.leaf.max_leaf_size = leaf;
                         return PairwiseBuilder::build(b, c, cfg);
                     }});
    using SA = SortAxisBuilder::Config::Axis;
    using SM = SortAxisBuilder::Config::Metric;
    using SP = SortAxisBuilder::Config::Pairing;
    for (SA axis : {SA::x, SA::longest, SA::morton})
        for (SM metric : {SM::centre, SM::area})
            for (SP pairing : {SP::greedy, SP::mutual})
                for (unsigned w : {1u, 2u, 6u, 32u}) {
                    const std::string name = std::string("sortaxis/") +
                                             (axis == SA::x ? "x" : axis == SA::longest ? "longest" : "morton") + "/" +
                                             (metric == SM::centre ? "centre" : "area") + "/" +
                                             (pairing == SP::greedy ? "greedy" : "mutual") + "/W" + std::to_string(w);
                    s.push_back({name, [axis, metric, pairing, w](std::span<const AABB> b, std::span<const vec3> c,
                                                                  unsigned threads, unsigned leaf) {
                                     SortAxisBuilder::Config cfg;
                                     cfg.axis = axis;
                                     cfg.metric = metric;
                                     cfg.pairing = pairing;
                                     cfg.window = w;
                                     cfg.threads = threads;
                                     cfg.leaf.max_leaf_size = leaf;
                                     return SortAxisBuilder::build(b, c, cfg);
                                 }});
                }
    for (unsigned r : {1u, 4u, 8u, 32u})
        for (bool opt : {false, true})
            s.push_back({"ploc/R" + std::to_string(r) + (opt ? "/opt" : "/plain"),
                         [r, opt](std::span<const AABB> b, std::span<const vec3> c, unsigned threads, unsigned leaf) {
                             PlocBuilder::Config cfg;
                             cfg.radius = r;
                             cfg.threads = threads;
                             cfg.leaf.max_leaf_size = leaf;
                             if (!opt) cfg.optimize = OptimizeConfig::off();
                             return PlocBuilder::build(b, c, cfg);
                         }});
    for (const Setting& st : optimized_settings()) s.push_back(st);
    return s;
}

/// One setting per builder (their defaults), for the more expensive tests.
std::vector<Setting> default_settings() {
    return {
        {"pairwise", [](std::span<const AABB> b, std::span<const vec3> c, unsigned threads, unsigned leaf) {
             PairwiseBuilder::Config cfg;
             cfg.threads = threads;
             cfg.leaf.max_leaf_size = leaf;
             return PairwiseBuilder::build(b, c, cfg);
         }},
        {"sortaxis", [](std::span<const AABB> b, std::span<const vec3> c, unsigned threads, unsigned leaf) {
             SortAxisBuilder::Config cfg;
             cfg.threads = threads;
             cfg.leaf.max_leaf_size = leaf;
             return SortAxisBuilder::build(b, c, cfg);
         }},
        {"ploc", [](std::span<const AABB> b, std::span<const vec3> c, unsigned threads, unsigned leaf) {
             PlocBuilder::Config cfg;
             cfg.threads = threads;
             cfg.leaf.max_leaf_size = leaf;
             return PlocBuilder::build(b, c, cfg);
         }},
    };
}

using raykit::test::random_rays;

/// A mesh, its primitive refs, rays and the brute-force answers (computed
/// once, shared by every builder).
struct TestScene {
    std::string name;
    Mesh mesh;
    PrimitiveRefs refs;
    std::vector<Ray> rays;
    std::vector<Hit> oracle;

    TestScene(std::string nm, Mesh m, std::size_t nrays, std::uint64_t seed) : name(std::move(nm)), mesh(std::move(m)) {
        refs = primitive_refs(mesh);
        rays = random_rays(mesh, nrays, seed);
        oracle.reserve(rays.size());
        for (const Ray& r : rays) oracle.push_back(brute_force_closest(mesh, r));
    }
};

void expect_valid(const TestScene& s, const Bvh& bvh, const std::string& what, unsigned leaf = 8) {
    EXPECT_EQ(validate(bvh, s.refs.boxes), "") << what << " over " << s.name;
    EXPECT_LE(bvh.depth(), RAYKIT_BVH_MAX_DEPTH) << what << " over " << s.name;
    for (const Node& n : bvh.nodes) {
        if (n.is_leaf()) {
            EXPECT_LE(n.count, std::max(1u, leaf)) << what << " over " << s.name;
        }
    }
    // the layout is exactly the compact pre-order one
    const std::vector<Node> tmp(bvh.nodes.begin(), bvh.nodes.end());
    const NodeArray again = detail::compact_preorder(tmp);
    ASSERT_EQ(again.size(), bvh.nodes.size()) << what;
    EXPECT_EQ(std::memcmp(again.data(), bvh.nodes.data(), again.size() * sizeof(Node)), 0)
        << what << " over " << s.name << ": not in compact pre-order";
}

/// Closest and any-hit queries equal the brute-force oracle on every ray.
void expect_matches_brute_force(const TestScene& s, const Bvh& bvh, const std::string& what) {
    std::size_t bad = 0;
    for (std::size_t i = 0; i < s.rays.size(); ++i) {
        const Hit h = intersect_closest(s.mesh, bvh, s.rays[i]);
        const Hit& o = s.oracle[i];
        const bool any = intersect_any(s.mesh, bvh, s.rays[i]);
        if (h.prim != o.prim || h.t != o.t || any != o.valid()) {
            if (++bad <= 3)
                ADD_FAILURE() << what << " over " << s.name << ", ray " << i << ": bvh prim " << h.prim << " t "
                              << h.t << " any " << any << ", brute force prim " << o.prim << " t " << o.t;
        }
    }
    EXPECT_EQ(bad, 0u) << what << " over " << s.name << ", of " << s.rays.size() << " rays";
}

bool same_tree(const Bvh& a, const Bvh& b) {
    return a.nodes.size() == b.nodes.size() && a.prim_ids == b.prim_ids &&
           std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(Node)) == 0;
}

Mesh mesh_of_triangles(const std::vector<std::array<vec3, 3>>& tris) {
    Mesh m;
    for (const auto& t : tris) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        for (const vec3& p : t) m.positions.push_back(p);
        m.triangles.push_back({{base, base + 1, base + 2}});
    }
    m.material_ids.assign(m.triangles.size(), kNoMaterial);
    return m;
}

/// Triangles shrinking geometrically towards a point (as in test_bvh).
Mesh geometric_progression(int count) {
    Mesh m;
    float s = 1.0f;
    for (int i = 0; i < count; ++i) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        const float x = s;
        m.positions.push_back({x, 0.0f, 0.0f});
        m.positions.push_back({x + s * 0.5f, s * 0.5f, 0.0f});
        m.positions.push_back({x, s * 0.5f, s * 0.5f});
        m.triangles.push_back({{base, base + 1, base + 2}});
        s *= (i < 120 ? 0.5f : 0.999f);
        if (s < 1e-30f) s = 1e-30f;
    }
    m.material_ids.assign(m.triangles.size(), kNoMaterial);
    return m;
}

/// A soup plus needles, zero-area, NaN and inf triangles (the last 50 are
/// non-finite and must never be hit).
Mesh degenerate_mesh(std::size_t soup) {
    Mesh m = make_random_soup(soup, 3, 0.1f);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int i = 0; i < 300; ++i) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        const vec3 p(float(i) / 300.0f, 0.5f, 0.5f);
        m.positions.push_back(p);
        m.positions.push_back(p + vec3(0.3f, 1e-7f, 0.0f));
        m.positions.push_back(i % 2 ? p : p + vec3(0.6f, 2e-7f, 0.0f));
        m.triangles.push_back({{base, base + 1, base + 2}});
    }
    for (int i = 0; i < 50; ++i) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        m.positions.push_back({nan, 0.5f, 0.5f});
        m.positions.push_back({0.2f, i % 2 ? kInf : nan, 0.5f});
        m.positions.push_back({0.5f, 0.5f, 0.5f});
        m.triangles.push_back({{base, base + 1, base + 2}});
    }
    m.material_ids.assign(m.triangles.size(), kNoMaterial);
    return m;
}

}  // namespace

TEST(Builders, EverySettingMatchesBruteForceOnSoupsAndATorus) {
    const std::size_t rays = scaled(600, 200);
    std::vector<TestScene> scenes;
    scenes.emplace_back("soup 1", make_random_soup(scaled(3000, 1000), 1, 0.05f), rays, 11);
    scenes.emplace_back("soup 2", make_random_soup(scaled(1500, 600), 2, 0.2f), rays, 12);
    scenes.emplace_back("torus", make_bumpy_torus(scaled(20000, 4000)), rays, 13);
    for (const Setting& st : all_settings())
        for (const TestScene& sc : scenes)
            for (unsigned leaf : {1u, 8u}) {
                const std::string what = st.name + " leaf " + std::to_string(leaf);
                const Bvh bvh = st.build(sc.refs.boxes, sc.refs.centers, 0, leaf);
                expect_valid(sc, bvh, what, leaf);
                expect_matches_brute_force(sc, bvh, what);
            }
}

TEST(Builders, SameTreeForOneTwoAndSevenThreads) {
    // big enough that every parallel pass runs in several chunks
    const Mesh torus = make_bumpy_torus(scaled(80000, 40000));
    const Mesh soup = make_random_soup(scaled(50000, 30000), 9, 0.02f);
    for (const Mesh* m : {&torus, &soup}) {
        const PrimitiveRefs r = primitive_refs(*m);
        for (const Setting& st : all_settings()) {
            // sort-by-axis: windows 2 and 32 cover the code paths (1 and 6 run everywhere else)
            auto ends_with = [&](const char* suffix) {
                const std::size_t k = std::strlen(suffix);
                return st.name.size() >= k && st.name.compare(st.name.size() - k, k, suffix) == 0;
            };
            if (st.name.rfind("sortaxis", 0) == 0 && (ends_with("/W1") || ends_with("/W6"))) continue;
            const Bvh a = st.build(r.boxes, r.centers, 1, 8);
            const Bvh b = st.build(r.boxes, r.centers, 2, 8);
            const Bvh c = st.build(r.boxes, r.centers, 7, 8);
            EXPECT_TRUE(same_tree(a, b)) << st.name << ": 1 vs 2 threads, " << m->triangle_count() << " triangles";
            EXPECT_TRUE(same_tree(a, c)) << st.name << ": 1 vs 7 threads, " << m->triangle_count() << " triangles";
            EXPECT_EQ(validate(a, r.boxes), "") << st.name;
        }
    }
}

TEST(Builders, PairwiseEqualsTheQuadraticReference) {
    using PM = PairwiseBuilder::Config::Metric;
    std::vector<std::pair<std::string, Mesh>> meshes;
    for (std::uint64_t seed = 1; seed <= 4; ++seed)
        for (std::size_t n : {1u, 2u, 3u, 5u, 17u, 65u, 200u, 700u})
            meshes.emplace_back("soup " + std::to_string(n) + "/" + std::to_string(seed),
                                make_random_soup(n, seed * 100 + n, 0.02f + 0.05f * float(seed)));
    meshes.emplace_back("soup 2000", make_random_soup(scaled(2000, 1000), 77, 0.05f));
    meshes.emplace_back("torus 2000", make_bumpy_torus(scaled(2000, 1000)));
    // exact ties: a regular grid of equal triangles, and coincident triangles
    {
        std::vector<std::array<vec3, 3>> grid, same;
        for (int i = 0; i < 12; ++i)
            for (int j = 0; j < 12; ++j)
                for (int k = 0; k < 6; ++k) {
                    const vec3 p{float(i), float(j), float(k)};
                    grid.push_back({p, p + vec3(0.5f, 0, 0), p + vec3(0, 0.5f, 0)});
                }
        for (int i = 0; i < 300; ++i) same.push_back({vec3(0), vec3(1, 0, 0), vec3(0, 1, 0)});
        meshes.emplace_back("grid", mesh_of_triangles(grid));
        meshes.emplace_back("coincident", mesh_of_triangles(same));
    }
    meshes.emplace_back("degenerate", degenerate_mesh(scaled(600, 300)));
    for (const auto& [name, m] : meshes) {
        const PrimitiveRefs r = primitive_refs(m);
        for (PM metric : {PM::centre, PM::area})
            for (unsigned leaf : {1u, 8u}) {
                PairwiseBuilder::Config cfg;
                cfg.metric = metric;
                cfg.leaf.max_leaf_size = leaf;
                const Bvh fast = PairwiseBuilder::build(r.boxes, r.centers, cfg);
                const Bvh ref = PairwiseBuilder::build_reference(r.boxes, r.centers, cfg);
                EXPECT_TRUE(same_tree(fast, ref)) << name << ", metric " << (metric == PM::centre ? "centre" : "area")
                                                  << ", leaf " << leaf;
                EXPECT_EQ(validate(fast, r.boxes), "") << name;
            }
    }
}

TEST(Builders, BinnedSahSameTreeWhenSubtreesSplitTheirPasses) {
    // subtrees of 64k primitives and more bin on the pool's spare members: at 150k triangles
    // both of the torus's root children are that large, and 7 threads leave members spare
    const Mesh torus = make_bumpy_torus(150000);
    const PrimitiveRefs r = primitive_refs(torus);
    BinnedSahBuilder::Config cfg;
    cfg.leaf.max_leaf_size = 8;
    cfg.threads = 1;
    const Bvh one = BinnedSahBuilder::build(r.boxes, r.centers, cfg);
    EXPECT_EQ(validate(one, r.boxes), "");
    for (unsigned t : {2u, 3u, 7u}) {
        cfg.threads = t;
        EXPECT_TRUE(same_tree(one, BinnedSahBuilder::build(r.boxes, r.centers, cfg))) << t << " threads";
    }
}

TEST(Builders, PairwiseOnSeveralThreadsEqualsTheQuadraticReference) {
    // Lists long enough (≥ 2 · 4096) that a level is cut into parts whose guesses are checked:
    // a random soup (no order: many wrong guesses), a torus (list order follows the surface) and
    // a grid of equal triangles (exact ties at every distance, so the tie rule decides).
    using PM = PairwiseBuilder::Config::Metric;
    std::vector<std::pair<std::string, Mesh>> meshes;
    meshes.emplace_back("soup", make_random_soup(9000, 41, 0.03f));
    meshes.emplace_back("torus", make_bumpy_torus(9000));
    {
        std::vector<std::array<vec3, 3>> grid;
        for (int i = 0; i < 24; ++i)
            for (int j = 0; j < 24; ++j)
                for (int k = 0; k < 16; ++k) {
                    const vec3 p{float(i), float(j), float(k)};
                    grid.push_back({p, p + vec3(0.5f, 0, 0), p + vec3(0, 0.5f, 0)});
                }
        meshes.emplace_back("grid", mesh_of_triangles(grid));
        // the same grid in a seeded random order: wrong guesses whose phantoms tie with them
        std::mt19937 rng(5);
        std::shuffle(grid.begin(), grid.end(), rng);
        meshes.emplace_back("shuffled grid", mesh_of_triangles(grid));
    }
    for (const auto& [name, m] : meshes) {
        const PrimitiveRefs r = primitive_refs(m);
        for (PM metric : {PM::centre, PM::area}) {
            PairwiseBuilder::Config cfg;
            cfg.metric = metric;
            cfg.leaf.max_leaf_size = 1;
            const Bvh ref = PairwiseBuilder::build_reference(r.boxes, r.centers, cfg);
            for (unsigned threads : {2u, 3u}) {
                cfg.threads = threads;
                const Bvh fast = PairwiseBuilder::build(r.boxes, r.centers, cfg);
                EXPECT_TRUE(same_tree(fast, ref)) << name << ", metric " << (metric == PM::centre ? "centre" : "area")
                                                  << ", " << threads << " threads";
            }
        }
    }
}

TEST(Builders, EmptyAndTinyInputs) {
    for (const Setting& st : all_settings()) {
        const Bvh e = st.build({}, {}, 0, 8);
        EXPECT_TRUE(e.nodes.empty()) << st.name;
        EXPECT_TRUE(e.prim_ids.empty()) << st.name;
        for (std::size_t n : {1u, 2u, 3u}) {
            const TestScene s("soup " + std::to_string(n), make_random_soup(n, 5 + n, 0.3f), 300, n);
            for (unsigned leaf : {1u, 8u}) {
                const Bvh bvh = st.build(s.refs.boxes, s.refs.centers, 0, leaf);
                expect_valid(s, bvh, st.name, leaf);
                expect_matches_brute_force(s, bvh, st.name);
            }
        }
    }
}

TEST(Builders, CoincidentCentroidsAndIdenticalTriangles) {
    std::vector<std::array<vec3, 3>> same, rotated;
    for (int i = 0; i < 1000; ++i) same.push_back({vec3(0), vec3(1, 0, 0), vec3(0, 1, 0)});
    for (int i = 0; i < 300; ++i) {
        const float a = 0.01f * float(i);
        std::array<vec3, 3> t;
        for (int k = 0; k < 3; ++k) {
            const float b = a + 2.0943951f * float(k);
            t[k] = {std::cos(b), std::sin(b), 0.001f * float(i)};
        }
        rotated.push_back(t);
    }
    const TestScene s1("identical", mesh_of_triangles(same), 300, 1);
    const TestScene s2("rotated", mesh_of_triangles(rotated), 600, 3);
    for (const Setting& st : all_settings())
        for (const TestScene* s : {&s1, &s2})
            for (unsigned leaf : {1u, 4u}) {
                const Bvh bvh = st.build(s->refs.boxes, s->refs.centers, 0, leaf);
                expect_valid(*s, bvh, st.name, leaf);
                expect_matches_brute_force(*s, bvh, st.name);
            }
    // ties go to the smallest index whatever the tree
    const Ray r{{0.2f, 0.2f, 1.0f}, 0.0f, {0, 0, -1}, kInf};
    for (const Setting& st : default_settings()) {
        const Bvh bvh = st.build(s1.refs.boxes, s1.refs.centers, 0, 4);
        EXPECT_EQ(intersect_closest(s1.mesh, bvh, r).prim, 0u) << st.name;
    }
}

TEST(Builders, DegenerateNeedleAndNanTrianglesBuildValidTrees) {
    const TestScene s("degenerate", degenerate_mesh(scaled(2000, 800)), scaled(1500, 400), 5);
    const auto finite = static_cast<std::uint32_t>(s.mesh.triangle_count() - 50);
    for (const Setting& st : all_settings()) {
        const Bvh bvh = st.build(s.refs.boxes, s.refs.centers, 0, 8);
        expect_valid(s, bvh, st.name);
        expect_matches_brute_force(s, bvh, st.name);
        for (const Ray& r : s.rays) {
            const Hit h = intersect_closest(s.mesh, bvh, r);
            if (h.valid()) {
                EXPECT_LT(h.prim, finite) << st.name << ": a NaN triangle was hit";
            }
        }
    }
    // all primitives non-finite: still one valid tree
    Mesh bad;
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int i = 0; i < 40; ++i) {
        const auto base = static_cast<std::uint32_t>(bad.positions.size());
        bad.positions.push_back({nan, 0, 0});
        bad.positions.push_back({0, kInf, 0});
        bad.positions.push_back({0, 0, -kInf});
        bad.triangles.push_back({{base, base + 1, base + 2}});
    }
    const PrimitiveRefs r = primitive_refs(bad);
    for (const Setting& st : default_settings()) {
        EXPECT_EQ(validate(st.build(r.boxes, r.centers, 0, 8), r.boxes), "") << st.name;
        EXPECT_EQ(validate(st.build(r.boxes, r.centers, 0, 1), r.boxes), "") << st.name;
    }
}

/// BinnedSahBuilder sanitizes by bvh/sanitize.hpp's one rule: its tree over NaN and inf
/// centroids is the tree over the same input with those centroids put at the centre of the
/// finite ones by hand, bit for bit (above the parallel-pass size, so chunked bounds count).
TEST(Builders, BinnedSahPutsNonFiniteCentroidsAtTheCentreOfTheFiniteOnes) {
    const PrimitiveRefs r = primitive_refs(degenerate_mesh(70000));
    AABB finite;
    std::size_t bad = 0;
    for (const vec3& c : r.centers) {
        if (is_finite(c)) finite.grow(c);
        else ++bad;
    }
    ASSERT_EQ(bad, 50u);
    auto filled = [&](vec3 fill) {
        std::vector<vec3> c = r.centers;
        for (vec3& p : c)
            if (!is_finite(p)) p = fill;
        return c;
    };
    const std::vector<vec3> by_hand = filled((finite.min + finite.max) * 0.5f);
    for (unsigned threads : {1u, 2u}) {
        BinnedSahBuilder::Config cfg;
        cfg.threads = threads;
        cfg.leaf.max_leaf_size = 4;
        const Bvh tree = BinnedSahBuilder::build(r.boxes, r.centers, cfg);
        EXPECT_TRUE(same_tree(tree, BinnedSahBuilder::build(r.boxes, by_hand, cfg))) << threads << " threads";
        // the comparison sees the rule: another place gives another tree
        EXPECT_FALSE(same_tree(tree, BinnedSahBuilder::build(r.boxes, filled(finite.min), cfg))) << threads << " threads";
    }
}

/// The deepest layout test_bvh knows: every builder stays within the bound
/// (PLOC merges chains here; the depth pass must cut them).
TEST(Builders, GeometricProgressionStaysWithinTheDepthBound) {
    const TestScene s("geometric progression", geometric_progression(4000), scaled(800, 300), 2);
    std::vector<Setting> settings = default_settings();
    for (const Setting& st : all_settings())
        if (st.name.rfind("ploc", 0) == 0 || st.name.find("/W32") != std::string::npos ||
            st.name.find("/opt") != std::string::npos)
            settings.push_back(st);
    for (const Setting& st : settings)
        for (unsigned leaf : {1u, 8u}) {
            const Bvh bvh = st.build(s.refs.boxes, s.refs.centers, 0, leaf);
            expect_valid(s, bvh, st.name, leaf);
            EXPECT_LE(bvh.depth(), RAYKIT_BVH_MAX_DEPTH) << st.name;
            std::printf("[ info ] geometric progression, %s leaf %u: depth %d\n", st.name.c_str(), leaf, bvh.depth());
            expect_matches_brute_force(s, bvh, st.name);
        }
}

/// A caterpillar merge tree over n primitives: each merge joins one primitive
/// with everything merged so far (on the left or on the right), one batch each.
static detail::MergeTree caterpillar(std::uint32_t n, bool left_deep) {
    detail::MergeTree t;
    t.prims = n;
    std::uint32_t cur = 0;
    for (std::uint32_t i = 1; i < n; ++i) {
        cur = left_deep ? t.add(cur, i) : t.add(i, cur);
        t.close_batch();
    }
    t.root = cur;
    return t;
}

/// The depth pass on its own: a caterpillar merge tree (each node one
/// primitive plus the rest) of 5000 levels is cut to the bound.
TEST(Builders, DepthPassCutsADegenerateMergeTree) {
    for (std::uint32_t n : {65u, 66u, 200u, 5000u}) {
        const TestScene s("caterpillar", make_random_soup(n, n, 0.05f), 200, n);
        const PrimitiveRefs& r = s.refs;
        for (bool left_deep : {false, true}) {
            const detail::MergeTree t = caterpillar(n, left_deep);
            for (unsigned leaf : {1u, 8u}) {
                detail::MergeTree copy = t;
                const Bvh bvh = detail::finish_bottom_up(copy, r.boxes, r.centers, {leaf, 1.0f, 1.0f}, 2);
                EXPECT_EQ(validate(bvh, r.boxes), "") << n << " left " << left_deep;
                EXPECT_LE(bvh.depth(), RAYKIT_BVH_MAX_DEPTH) << n;
                expect_matches_brute_force(s, bvh, "caterpillar " + std::to_string(n));
            }
        }
    }
}

TEST(Builders, InvalidInputThrows) {
    const PrimitiveRefs r = primitive_refs(make_random_soup(10, 1, 0.1f));
    const std::span<const vec3> short_centers(r.centers.data(), 9);
    EXPECT_THROW(PairwiseBuilder::build(r.boxes, short_centers), std::invalid_argument);
    EXPECT_THROW(SortAxisBuilder::build(r.boxes, short_centers), std::invalid_argument);
    EXPECT_THROW(PlocBuilder::build(r.boxes, short_centers), std::invalid_argument);
    SortAxisBuilder::Config sc;
    sc.window = 0;
    EXPECT_THROW(SortAxisBuilder::build(r.boxes, r.centers, sc), std::invalid_argument);
    PlocBuilder::Config pc;
    pc.radius = 0;
    EXPECT_THROW(PlocBuilder::build(r.boxes, r.centers, pc), std::invalid_argument);
}

TEST(Builders, BuildBvhTakesEveryBuilder) {
    const TestScene s("torus", make_bumpy_torus(5000), 300, 4);
    const Bvh a = build_bvh<PairwiseBuilder>(s.mesh, {});
    const Bvh b = build_bvh<SortAxisBuilder>(s.mesh, {});
    const Bvh c = build_bvh<PlocBuilder>(s.mesh, {});
    for (const Bvh* bvh : {&a, &b, &c}) {
        expect_valid(s, *bvh, "build_bvh");
        expect_matches_brute_force(s, *bvh, "build_bvh");
    }
}

/// SAH cost of each builder relative to binned SAH, printed; the defaults
/// of sort-by-axis and PLOC are held to the issue's targets (1.15x, 1.05x).
TEST(Builders, SahCostRelativeToBinnedSah) {
    const Mesh m = make_bumpy_torus(scaled(100000, 20000));
    const PrimitiveRefs r = primitive_refs(m);
    const double ref = sah_cost(BinnedSahBuilder::build(r.boxes, r.centers));
    std::printf("[ info ] SAH cost relative to binned SAH (%.3f), torus of %zu triangles:\n", ref,
                m.triangle_count());
    std::vector<Setting> settings = default_settings();
    for (const Setting& st : all_settings())
        if (st.name.find("/W6") != std::string::npos || st.name.find("/W32") != std::string::npos ||
            st.name.rfind("ploc", 0) == 0 || st.name.rfind("pairwise", 0) == 0)
            settings.push_back(st);
    for (const Setting& st : settings) {
        const Bvh bvh = st.build(r.boxes, r.centers, 0, 8);
        const double c = sah_cost(bvh);
        EXPECT_GT(c, 0.0) << st.name;
        if (st.name == "sortaxis") {
            EXPECT_LE(c, 1.15 * ref);  // measured 1.089 (100k), 1.081 (20k)
        }
        if (st.name == "ploc") {
            EXPECT_LE(c, 1.05 * ref);  // measured 1.045 (100k), 1.037 (20k)
        }
        std::printf("[ info ]   %-28s %8.3f  (%.3fx)\n", st.name.c_str(), c, c / ref);
    }
}

/// The post-pass only ever lowers the SAH cost: the same build with and
/// without it, on meshes of even and of very uneven triangles, degenerate
/// ones, and from the best and the worst bottom-up trees.
TEST(Builders, OptimizePassNeverRaisesTheSahCost) {
    std::vector<std::pair<std::string, Mesh>> meshes;
    meshes.reserve(8);
    meshes.emplace_back("torus", make_bumpy_torus(scaled(30000, 8000)));
    meshes.emplace_back("soup", make_random_soup(scaled(20000, 5000), 21, 0.05f));
    meshes.emplace_back("mixed sizes", make_random_soup(scaled(8000, 3000), 22, 0.6f));
    meshes.emplace_back("degenerate", degenerate_mesh(scaled(3000, 1000)));
    meshes.emplace_back("geometric progression", geometric_progression(2000));
    {
        std::vector<std::array<vec3, 3>> same;
        for (int i = 0; i < 500; ++i) same.push_back({vec3(0), vec3(1, 0, 0), vec3(0, 1, 0)});
        meshes.emplace_back("identical", mesh_of_triangles(same));
    }
    using SA = SortAxisBuilder::Config::Axis;
    using SP = SortAxisBuilder::Config::Pairing;
    const OptimizeConfig configs[] = {OptimizeConfig{}, {0.02f, 0u, 16u}, {0.0f, 1u, 16u}, {0.25f, 3u, 1u}};
    for (const auto& [name, m] : meshes) {
        const PrimitiveRefs r = primitive_refs(m);
        for (unsigned leaf : {1u, 4u, 8u})
            for (const OptimizeConfig& oc : configs) {
                PlocBuilder::Config p;
                p.leaf.max_leaf_size = leaf;
                p.optimize = OptimizeConfig::off();
                const double before = sah_cost(PlocBuilder::build(r.boxes, r.centers, p));
                p.optimize = oc;
                const Bvh after = PlocBuilder::build(r.boxes, r.centers, p);
                EXPECT_LE(sah_cost(after), before * (1.0 + 1e-6)) << "ploc, " << name << ", leaf " << leaf;
                EXPECT_EQ(validate(after, r.boxes), "") << name;
                for (SP pairing : {SP::greedy, SP::mutual}) {
                    SortAxisBuilder::Config c;
                    c.leaf.max_leaf_size = leaf;
                    c.pairing = pairing;
                    c.axis = pairing == SP::greedy ? SA::x : SA::morton;
                    const double b0 = sah_cost(SortAxisBuilder::build(r.boxes, r.centers, c));
                    c.optimize = oc;
                    const Bvh a = SortAxisBuilder::build(r.boxes, r.centers, c);
                    EXPECT_LE(sah_cost(a), b0 * (1.0 + 1e-6)) << "sortaxis, " << name << ", leaf " << leaf;
                    EXPECT_EQ(validate(a, r.boxes), "") << name;
                }
            }
    }
    // and it does lower it where there is something to gain
    const PrimitiveRefs r = primitive_refs(meshes[0].second);
    PlocBuilder::Config p;
    p.optimize = OptimizeConfig::off();
    const double plain = sah_cost(PlocBuilder::build(r.boxes, r.centers, p));
    p.optimize = OptimizeConfig{};
    EXPECT_LT(sah_cost(PlocBuilder::build(r.boxes, r.centers, p)), plain * 0.98);
}

/// On up to seven primitives one treelet holds them all, so the dynamic
/// program must find the best tree there is: compared with an exhaustive
/// search over every binary tree and every leaf merge (the same rule and
/// constants), written independently here.
TEST(Builders, TreeletFindsTheOptimalTreeOverSevenPrimitives) {
    for (std::uint64_t seed = 1; seed <= 40; ++seed)
        for (std::size_t n : {3u, 5u, 7u})
            for (unsigned leaf : {1u, 2u, 4u, 8u}) {
                const Mesh m = make_random_soup(n, seed * 31 + n, 0.1f + 0.1f * float(seed % 5));
                const PrimitiveRefs r = primitive_refs(m);
                // best[S]: least cost (Ct = Ci = 1, half areas) of a subtree over subset S
                const std::size_t full = (std::size_t(1) << n) - 1;
                std::vector<double> best(full + 1, 0.0);
                std::vector<AABB> box(full + 1);
                for (std::size_t S = 1; S <= full; ++S) {
                    std::size_t cnt = 0;
                    for (std::size_t i = 0; i < n; ++i)
                        if (S >> i & 1) {
                            box[S].grow(r.boxes[i]);
                            ++cnt;
                        }
                    const double a = box[S].half_area();
                    if (cnt == 1) {
                        best[S] = a;
                        continue;
                    }
                    double split = std::numeric_limits<double>::infinity();
                    for (std::size_t P = (S - 1) & S; P > 0; P = (P - 1) & S) split = std::min(split, best[P] + best[S ^ P]);
                    best[S] = a + split;
                    if (cnt <= leaf) best[S] = std::min(best[S], a * double(cnt));
                }
                const double optimum = best[full] / box[full].half_area();
                PlocBuilder::Config c;
                c.leaf.max_leaf_size = leaf;
                c.optimize = {0.0f, 1u, 1u};
                const Bvh bvh = PlocBuilder::build(r.boxes, r.centers, c);
                EXPECT_NEAR(sah_cost(bvh), optimum, 1e-5 * optimum) << n << " primitives, seed " << seed << ", leaf " << leaf;
                EXPECT_EQ(validate(bvh, r.boxes), "");
            }
}

/// The post-pass on a merge tree after a depth cut (nodes out of batch order,
/// some unreachable), and on one that restructuring may deepen: the result is
/// valid, within the depth bound and answers like brute force.
TEST(Builders, OptimizePassAfterADepthCut) {
    for (std::uint32_t n : {3u, 66u, 5000u}) {
        const TestScene s("caterpillar", make_random_soup(n, n + 7, 0.05f), 200, n);
        const PrimitiveRefs& r = s.refs;
        for (bool left_deep : {false, true}) {
            const detail::MergeTree t = caterpillar(n, left_deep);
            for (unsigned leaf : {1u, 8u})
                for (const OptimizeConfig& oc : {OptimizeConfig{}, OptimizeConfig{0.25f, 3u, 1u}}) {
                    detail::MergeTree copy = t;
                    const LeafCost lc{leaf, 1.0f, 1.0f};
                    detail::optimize_merge_tree(copy, r.boxes, r.centers, lc, oc, 2);
                    const Bvh bvh = detail::finish_bottom_up(copy, r.boxes, r.centers, lc, 2);
                    detail::MergeTree plain = t;
                    const double before = sah_cost(detail::finish_bottom_up(plain, r.boxes, r.centers, lc, 2));
                    EXPECT_EQ(validate(bvh, r.boxes), "") << n << " left " << left_deep;
                    EXPECT_LE(bvh.depth(), RAYKIT_BVH_MAX_DEPTH) << n;
                    EXPECT_LE(sah_cost(bvh), before * (1.0 + 1e-6)) << n;
                    expect_matches_brute_force(s, bvh, "optimized caterpillar " + std::to_string(n));
                }
        }
    }
}

/// Mutual pairing with equal distances everywhere (identical triangles, a
/// regular grid): ties pair neighbours two by two, so the tree stays
/// balanced instead of growing one pair per level.
TEST(Builders, MutualPairingSplitsTiesEvenly) {
    std::vector<std::array<vec3, 3>> same, grid;
    for (int i = 0; i < 4096; ++i) same.push_back({vec3(0), vec3(1, 0, 0), vec3(0, 1, 0)});
    for (int i = 0; i < 64; ++i)
        for (int j = 0; j < 64; ++j) {
            const vec3 p{float(i), float(j), 0.0f};
            grid.push_back({p, p + vec3(0.5f, 0, 0), p + vec3(0, 0.5f, 0)});
        }
    for (const auto* tris : {&same, &grid}) {
        const PrimitiveRefs r = primitive_refs(mesh_of_triangles(*tris));
        for (auto metric : {SortAxisBuilder::Config::Metric::centre, SortAxisBuilder::Config::Metric::area}) {
            SortAxisBuilder::Config c;
            c.metric = metric;
            c.leaf.max_leaf_size = 1;
            const Bvh bvh = SortAxisBuilder::build(r.boxes, r.centers, c);
            EXPECT_EQ(validate(bvh, r.boxes), "");
            EXPECT_LE(bvh.depth(), 16) << (tris == &same ? "identical" : "grid");  // 4096 = 2^12
        }
    }
}

/// Sort by axis written out plainly, as an oracle for SortAxisBuilder's default rule
/// (Morton keys, mutual nearest by merged area within ±W): every level stably sorted by key,
/// each element's nearest among its W neighbours on each side, mutual pairs merged (the new
/// node where its first child was, keyed by its box's centre), the others carried. For one
/// chunk per level (fewer than 2·kChunk elements) and inputs whose distances do not tie.
/// n centroids uniform in the unit cube, each with the box box_of(centroid, U) (U() draws from
/// [0, 1)); with `doubled`, every odd one repeats the one before it (same box, same centroid).
struct BoxSet {
    std::vector<AABB> boxes;
    std::vector<vec3> centers;
};
template <class BoxOf>
static BoxSet random_box_set(std::mt19937& rng, std::size_t n, bool doubled, const BoxOf& box_of) {
    std::uniform_real_distribution<float> dist(0.0f, 1.0f);
    auto U = [&] { return dist(rng); };
    BoxSet set{std::vector<AABB>(n), std::vector<vec3>(n)};
    std::vector<AABB>& boxes = set.boxes;
    std::vector<vec3>& centers = set.centers;
    for (std::size_t i = 0; i < n; ++i) {
        if (doubled && i % 2 == 1) {
            boxes[i] = boxes[i - 1];
            centers[i] = centers[i - 1];
            continue;
        }
        centers[i] = vec3(U(), U(), U());
        boxes[i] = box_of(centers[i], U);
    }
    return set;
}

/// The round both plain-rule references below share: elements that are each other's nearest
/// (nn) merge into a new node at the lower position, numbered in order (one batch of `t`); the
/// others carry on unchanged. make(a, b, id) is the new element over a and b.
template <class E, class Make>
static std::vector<E> merge_mutual_round(const std::vector<E>& level, const std::vector<std::size_t>& nn,
                                         detail::MergeTree& t, const Make& make) {
    std::vector<E> next;
    for (std::size_t i = 0; i < level.size(); ++i) {
        const std::size_t j = nn[i];
        if (j == i || nn[j] != i) {
            next.push_back(level[i]);
        } else if (i < j) {
            next.push_back(make(level[i], level[j], t.add(level[i].node, level[j].node)));
        }
    }
    t.close_batch();
    return next;
}

static detail::MergeTree sortaxis_reference(std::span<const AABB> boxes, std::span<const vec3> centers, std::size_t W) {
    AABB cb;
    for (const vec3& c : centers) cb.grow(c);
    const detail::MortonQuantizer mq(cb);
    struct Element {
        AABB box;
        std::uint32_t node, key;
    };
    std::vector<Element> level;
    for (std::size_t i = 0; i < boxes.size(); ++i)
        level.push_back({boxes[i], static_cast<std::uint32_t>(i), mq.code30(centers[i])});
    detail::MergeTree t;
    t.prims = static_cast<std::uint32_t>(boxes.size());
    while (level.size() > 1) {
        std::stable_sort(level.begin(), level.end(), [](const Element& a, const Element& b) { return a.key < b.key; });
        const std::size_t m = level.size();
        std::vector<std::size_t> nn(m);
        for (std::size_t i = 0; i < m; ++i) {
            float best = std::numeric_limits<float>::infinity();
            nn[i] = i;
            for (std::size_t j = i > W ? i - W : 0; j < std::min(m, i + W + 1); ++j) {
                const float d = fused_proof_half_area(merge(level[i].box, level[j].box));
                if (j != i && d < best) best = d, nn[i] = j;
            }
        }
        std::vector<Element> next = merge_mutual_round(level, nn, t, [&](const Element& a, const Element& b, std::uint32_t id) {
            const AABB box = merge(a.box, b.box);
            return Element{box, id, mq.code30(detail::box_centre(box))};
        });
        EXPECT_FALSE(m > SortAxisBuilder::kGreedyFallbackMin && (m - next.size()) * SortAxisBuilder::kMinMutualShare < m)
            << "the reference has no greedy levels";
        level = std::move(next);
    }
    t.root = level.empty() ? 0 : level[0].node;
    return t;
}

TEST(Builders, SortAxisEqualsThePlainRuleWhenNewNodesLandFarFromTheirChildren) {
    // Boxes up to 2 away from their centroids in a unit cube of centroids: a new node's key
    // (its box's centre) then lands far along the sorted order from its children's
    // (centroids). The builder places the new nodes with an insertion sort while that moves
    // at most four elements per element, else with a radix sort (4 or 5 of the 3000 boxes' levels).
    std::mt19937 rng(29);
    for (std::size_t n : {2u, 3u, 100u, 3000u}) {
        const auto [boxes, centers] = random_box_set(rng, n, false, [](const vec3& c, auto& U) {
            const vec3 p = c + vec3(U(), U(), U()) * 4.0f - vec3(2.0f);
            return AABB{p - vec3(0.01f + 0.1f * U()), p + vec3(0.01f + 0.1f * U())};
        });
        for (unsigned W : {1u, 2u, 4u}) {
            SortAxisBuilder::Config cfg;
            cfg.window = W;
            const Bvh built = SortAxisBuilder::build(boxes, centers, cfg);
            detail::MergeTree ref = sortaxis_reference(boxes, centers, W);
            const Bvh want = detail::finish_bottom_up(ref, boxes, centers, cfg.leaf, 1);
            EXPECT_EQ(validate(built, boxes), "") << n << " boxes, W " << W;
            EXPECT_TRUE(same_tree(built, want)) << n << " boxes, W " << W << ": " << built.nodes.size() << " nodes against "
                                                << want.nodes.size();
        }
    }
}

/// Plain PLOC written out (post-pass off): the primitives in Morton order (ties by index); per
/// round every cluster's nearest among the R on each side by merged area, the first smallest;
/// mutual pairs merge into a node at the lower position, numbered in array order; the array is
/// compacted. No chunks, no SIMD, no incremental phase.
static detail::MergeTree ploc_reference(std::span<const AABB> boxes, std::span<const vec3> centers, std::size_t R) {
    AABB cb;
    for (const vec3& c : centers) cb.grow(c);
    const detail::MortonQuantizer mq(cb);
    std::vector<std::uint32_t> order(boxes.size());
    for (std::size_t i = 0; i < order.size(); ++i) order[i] = static_cast<std::uint32_t>(i);
    std::stable_sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) { return mq(centers[a]) < mq(centers[b]); });
    struct Cluster {
        AABB box;
        std::uint32_t node;
    };
    std::vector<Cluster> level;
    for (const std::uint32_t p : order) level.push_back({boxes[p], p});
    detail::MergeTree t;
    t.prims = static_cast<std::uint32_t>(boxes.size());
    while (level.size() > 1) {
        const std::size_t m = level.size();
        std::vector<std::size_t> nn(m);
        for (std::size_t i = 0; i < m; ++i) {
            float best = 0.0f;
            bool any = false;
            for (std::size_t j = i > R ? i - R : 0; j < std::min(m, i + R + 1); ++j) {
                if (j == i) continue;
                const float d = fused_proof_half_area(merge(level[i].box, level[j].box));
                if (!any || d < best) best = d, nn[i] = j, any = true;
            }
        }
        level = merge_mutual_round(level, nn, t, [](const Cluster& a, const Cluster& b, std::uint32_t id) {
            return Cluster{merge(a.box, b.box), id};
        });
    }
    t.root = level.empty() ? 0 : level[0].node;
    return t;
}

TEST(Builders, PlocEqualsThePlainRule) {
    // Random boxes, half of them twice (the same box and centroid: equal distances, so the
    // first smallest decides), against the rule written out; PLOC's search computes each pair
    // once, four at a time, for clusters whose window is whole.
    std::mt19937 rng(31);
    for (std::size_t n : {2u, 3u, 40u, 3000u}) {
        const auto [boxes, centers] = random_box_set(rng, n, n > 3, [](const vec3& c, auto& U) {
            return AABB{c - vec3(0.01f + 0.05f * U()), c + vec3(0.01f + 0.05f * U())};
        });
        for (unsigned R : {1u, 2u, 4u, 9u}) {
            PlocBuilder::Config cfg;
            cfg.radius = R;
            cfg.optimize = OptimizeConfig::off();
            for (unsigned threads : {1u, 2u}) {
                cfg.threads = threads;
                const Bvh built = PlocBuilder::build(boxes, centers, cfg);
                detail::MergeTree ref = ploc_reference(boxes, centers, R);
                const Bvh want = detail::finish_bottom_up(ref, boxes, centers, cfg.leaf, 1);
                EXPECT_EQ(validate(built, boxes), "") << n << " boxes, R " << R;
                EXPECT_TRUE(same_tree(built, want)) << n << " boxes, R " << R << ", " << threads << " threads: "
                                                    << built.nodes.size() << " nodes against " << want.nodes.size();
            }
        }
    }
}

// ---- issue 12: thread counts and generator sizes are bounded ----------------------------------

TEST(Builders, ThreadCountsAboveTheLimitAreRejected) {
    const Mesh m = make_icosphere(2);
    const PrimitiveRefs r = primitive_refs(m);
    for (unsigned threads : {kMaxThreads + 1, 1u << 31, 0xFFFFFFFFu}) {
        BinnedSahBuilder::Config sah;
        sah.threads = threads;
        EXPECT_THROW(BinnedSahBuilder::build(r.boxes, r.centers, sah), std::invalid_argument) << threads;
        PairwiseBuilder::Config pw;
        pw.threads = threads;
        EXPECT_THROW(PairwiseBuilder::build(r.boxes, r.centers, pw), std::invalid_argument) << threads;
        SortAxisBuilder::Config sa;
        sa.threads = threads;
        EXPECT_THROW(SortAxisBuilder::build(r.boxes, r.centers, sa), std::invalid_argument) << threads;
        PlocBuilder::Config pl;
        pl.threads = threads;
        EXPECT_THROW(PlocBuilder::build(r.boxes, r.centers, pl), std::invalid_argument) << threads;
        for (auto b : {BuildOptions::Builder::sah, BuildOptions::Builder::pairwise, BuildOptions::Builder::sortaxis,
                       BuildOptions::Builder::ploc}) {
            BuildOptions o;
            o.builder = b;
            o.threads = threads;
            EXPECT_THROW(build_bvh(MeshView(m), o), std::invalid_argument) << BuildOptions::name(b) << " " << threads;
        }
    }
    // the limit itself is accepted and gives the one-thread tree
    BinnedSahBuilder::Config one, most;
    one.threads = 1;
    most.threads = kMaxThreads;
    const Bvh a = BinnedSahBuilder::build(r.boxes, r.centers, one), b = BinnedSahBuilder::build(r.boxes, r.centers, most);
    EXPECT_EQ(a.prim_ids, b.prim_ids);
    EXPECT_EQ(a.nodes.size(), b.nodes.size());
}

TEST(Builders, ParallelHelpersClampTheThreadCount) {
    EXPECT_EQ(resolve_threads(0xFFFFFFFFu), kMaxThreads);
    EXPECT_EQ(resolve_threads(kMaxThreads + 1), kMaxThreads);
    EXPECT_EQ(resolve_threads(3), 3u);
    EXPECT_GE(resolve_threads(0), 1u);
    EXPECT_LE(resolve_threads(0), kMaxThreads);
    EXPECT_THROW(check_threads(kMaxThreads + 1, "test"), std::invalid_argument);
    EXPECT_NO_THROW(check_threads(kMaxThreads, "test"));
    // an absurd count still visits every index once, on at most kMaxThreads threads
    const std::size_t n = 50000;
    std::vector<std::uint8_t> seen(n, 0);
    std::mutex mu;
    std::set<std::thread::id> ids;
    parallel_for(n, 0xFFFFFFFFu, [&](std::size_t i) {
        seen[i] += 1;
        if (i % 16 == 0) {
            std::lock_guard lock(mu);
            ids.insert(std::this_thread::get_id());
        }
    });
    EXPECT_EQ(std::count(seen.begin(), seen.end(), std::uint8_t(1)), std::ptrdiff_t(n));
    EXPECT_LE(ids.size(), std::size_t(kMaxThreads));
}

TEST(Builders, BlockCacheReusesFreedBlocksAndKeepsAtMostItsLimit) {
    using detail::BlockCache;
    BlockCache& cache = BlockCache::get();
    trim_build_memory();
    EXPECT_EQ(cache.held(), 0u);
    // size classes: eight per power of two from 256 KiB, at most 1/8 wasted; smaller sizes as asked
    std::mt19937_64 rng(7);
    for (int i = 0; i < 10000; ++i) {
        const std::size_t b = std::size_t(1) + rng() % (std::size_t(200) << 20);
        const std::size_t r = BlockCache::rounded(b);
        if (b < BlockCache::kMinBytes) {
            ASSERT_EQ(r, b);
            continue;
        }
        ASSERT_GE(r, b) << b;
        ASSERT_LE(r - b, b / 8) << b;
        ASSERT_EQ(BlockCache::rounded(r), r) << b;  // a class rounds to itself
    }
    // a freed block waits for the next request of its class, and only for that
    const std::size_t mib = std::size_t(1) << 20;
    auto* p = static_cast<unsigned char*>(cache.allocate(mib + 5));
    ASSERT_EQ(reinterpret_cast<std::uintptr_t>(p) % 64, 0u);
    std::memset(p, 0xAB, mib + 5);
    cache.deallocate(p, mib + 5);
    EXPECT_EQ(cache.held(), BlockCache::rounded(mib + 5));
#ifdef RAYKIT_BLOCK_CACHE_ASAN
    EXPECT_TRUE(__asan_address_is_poisoned(p + 100));  // a use after free is still caught
#endif
    void* other = cache.allocate(4 * mib);
    EXPECT_NE(other, static_cast<void*>(p));
    EXPECT_EQ(cache.allocate(mib + 1), static_cast<void*>(p));  // same class: the same block
    EXPECT_EQ(cache.held(), 0u);
#ifdef RAYKIT_BLOCK_CACHE_ASAN
    EXPECT_FALSE(__asan_address_is_poisoned(p + 100));
#endif
    // a block of 2 MiB or more starts on a 2 MiB boundary and, on Linux with transparent huge
    // pages, its mapping carries the huge-page advice (smaps VmFlags "hg")
    ASSERT_EQ(reinterpret_cast<std::uintptr_t>(other) % BlockCache::kHugeBytes, 0u);
    if (test::huge_page_advice_visible()) {
        const std::string flags = test::vm_flags_of(other);
        EXPECT_NE(flags.find(" hg"), std::string::npos) << "the 4 MiB block's mapping: " << flags;
    }
    cache.deallocate(p, mib + 1);
    cache.deallocate(other, 4 * mib);
    // at most build_memory_limit() bytes wait, the oldest leaving first; trim gives them all back
    EXPECT_EQ(build_memory_limit(), BlockCache::kDefaultLimit);
    set_build_memory_limit(64 * mib);
    std::vector<void*> big;
    for (int i = 0; i < 10; ++i) big.push_back(cache.allocate(10 * mib + std::size_t(i)));
    for (void* b : big) cache.deallocate(b, 10 * mib);
    EXPECT_LE(cache.held(), 64 * mib);
    EXPECT_GE(cache.held(), 54 * mib);
    const std::size_t held64 = cache.held();
    set_build_memory_limit(32 * mib);  // a lower limit gives the excess back at once
    EXPECT_LE(cache.held(), 32 * mib);
    EXPECT_GE(cache.held(), 22 * mib);
    EXPECT_LT(cache.held(), held64);
    void* over = cache.allocate(40 * mib);  // a block over the limit is never kept
    const std::size_t before = cache.held();
    cache.deallocate(over, 40 * mib);
    EXPECT_EQ(cache.held(), before);
    set_build_memory_limit(BlockCache::kDefaultLimit);
    trim_build_memory();
    EXPECT_EQ(cache.held(), 0u);
    // trees built into reused (dirty) blocks are the trees built into fresh ones
    const Mesh m = make_bumpy_torus(30000);
    const BlockBvh8 first = BlockBvh8::build(m, 2u);
    for (int round = 0; round < 2; ++round) {
        const BlockBvh8 again = BlockBvh8::build(m, 2u);
        ASSERT_EQ(again.tree.nodes.size(), first.tree.nodes.size());
        ASSERT_EQ(again.blocks.size(), first.blocks.size());
        EXPECT_EQ(std::memcmp(again.tree.nodes.data(), first.tree.nodes.data(), first.tree.nodes.size() * sizeof(first.tree.nodes[0])), 0);
        EXPECT_EQ(std::memcmp(again.blocks.data(), first.blocks.data(), first.blocks.size() * sizeof(first.blocks[0])), 0);
    }
    EXPECT_GT(cache.held(), 0u);  // the builds' scratch waits for the next build
}

TEST(Generate, SizesTheGeneratorsCannotMakeAreRejected) {
    EXPECT_THROW(make_bumpy_torus(std::numeric_limits<std::size_t>::max()), std::length_error);
    EXPECT_THROW(make_bumpy_torus(std::size_t(1) << 40), std::length_error);
    EXPECT_THROW(make_icosphere(-1), std::invalid_argument);
    EXPECT_THROW(make_icosphere(kMaxIcosphereLevel + 1), std::invalid_argument);
    EXPECT_THROW(make_random_soup(std::numeric_limits<std::size_t>::max(), 1), std::length_error);
    EXPECT_THROW(make_random_soup(std::size_t(1) << 31, 1), std::length_error);
    EXPECT_EQ(make_bumpy_torus(1000).triangle_count(), 1024u);
    EXPECT_EQ(make_icosphere(3).triangle_count(), 1280u);
    EXPECT_EQ(make_random_soup(7, 1).triangle_count(), 7u);
    // the icosphere level for a triangle budget: the largest that fits, never a shift past 64 bits
    EXPECT_EQ(icosphere_level_for(0), 0);
    EXPECT_EQ(icosphere_level_for(20), 0);
    EXPECT_EQ(icosphere_level_for(79), 0);
    EXPECT_EQ(icosphere_level_for(80), 1);
    EXPECT_EQ(icosphere_level_for(5119), 3);
    EXPECT_EQ(icosphere_level_for(std::numeric_limits<std::size_t>::max()), kMaxIcosphereLevel);
}
