// BVH builder and traversal against brute force over all triangles.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <initializer_list>
#include <random>
#include <stdexcept>
#include <string>
#include <type_traits>

#include <glm/gtc/matrix_transform.hpp>

#include "raykit.hpp"
#include "test_support.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/generate.hpp"

using namespace raykit;

namespace {

using raykit::test::random_rays;

/// Asserts closest and any-hit queries equal brute force on every ray
/// (`assert_all` false: only counts and returns the disagreements).
template <class Test = Watertight>
std::size_t expect_matches_brute_force(const Mesh& m, const Bvh& bvh, const std::vector<Ray>& rays,
                                       bool assert_all = true) {
    std::size_t bad = 0;
    // the same tree collapsed to 4-wide nodes must give the same answers
    const WideBvh wide = WideBvh::build(bvh);
    const WideBvh8 wide8 = WideBvh8::build(bvh);
    if (assert_all) {
        EXPECT_EQ(wide.validate(primitive_refs(m).boxes), "");
        EXPECT_EQ(wide8.validate(primitive_refs(m).boxes), "");
    }
    // with the watertight test, also the 4-triangle blocks over the binary,
    // 4- and 8-wide trees (scene/block_bvh.hpp): bit-identical answers
    constexpr bool kBlocks = std::is_same_v<Test, Watertight>;
    const BlockBvh2 blk2 = kBlocks ? BlockBvh2::build(m, bvh) : BlockBvh2{};
    const BlockBvh blk4 = kBlocks ? BlockBvh::build(m, wide) : BlockBvh{};
    const BlockBvh8 blk8 = kBlocks ? BlockBvh8::build(m, wide8) : BlockBvh8{};
    const auto same = [](const Hit& a, const Hit& b) {
        return a.prim == b.prim && a.t == b.t && a.u == b.u && a.v == b.v;
    };
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit h = intersect_closest<Test>(m, bvh, rays[i]);
        const Hit o = brute_force_closest<Test>(m, rays[i]);
        const bool any = intersect_any<Test>(m, bvh, rays[i]);
        const Hit w = intersect_closest<Test>(m, wide, rays[i]);
        const bool wany = intersect_any<Test>(m, wide, rays[i]);
        const Hit w8 = intersect_closest<Test>(m, wide8, rays[i]);
        const bool w8any = intersect_any<Test>(m, wide8, rays[i]);
        bool blocks_ok = true;
        if constexpr (kBlocks)
            blocks_ok = same(intersect_closest(blk2, rays[i]), h) && same(intersect_closest(blk4, rays[i]), h) &&
                        same(intersect_closest(blk8, rays[i]), h) && intersect_any(blk2, rays[i]) == any &&
                        intersect_any(blk4, rays[i]) == any && intersect_any(blk8, rays[i]) == any;
        if (h.prim != o.prim || h.t != o.t || any != o.valid() || w.prim != o.prim || w.t != o.t || w.u != h.u ||
            w.v != h.v || wany != any || w8.prim != o.prim || w8.t != o.t || w8.u != h.u || w8.v != h.v ||
            w8any != any || !blocks_ok) {
            if (++bad <= 5 && assert_all)
                ADD_FAILURE() << "ray " << i << " org (" << rays[i].org.x << ", " << rays[i].org.y << ", "
                              << rays[i].org.z << ") dir (" << rays[i].dir.x << ", " << rays[i].dir.y << ", "
                              << rays[i].dir.z << "): bvh prim " << h.prim << " t " << h.t << " any " << any
                              << ", brute force prim " << o.prim << " t " << o.t << ", blocks agree " << blocks_ok;
        }
    }
    if (assert_all) {
        EXPECT_EQ(bad, 0u) << "of " << rays.size() << " rays";
    }
    return bad;
}

Bvh build(const Mesh& m, unsigned leaf = 8, unsigned threads = 0) {
    BinnedSahBuilder::Config c;
    c.leaf.max_leaf_size = leaf;
    c.threads = threads;
    return build_bvh<BinnedSahBuilder>(m, c);
}

void expect_valid(const Mesh& m, const Bvh& bvh) {
    const std::string err = validate(bvh, primitive_refs(m).boxes);
    EXPECT_EQ(err, "") << "over " << m.triangle_count() << " triangles";
}

}  // namespace

TEST(Bvh, EmptyAndTinyMeshes) {
    Mesh empty;
    const Bvh e = build(empty);
    EXPECT_TRUE(e.nodes.empty());
    EXPECT_FALSE(intersect_closest(empty, e, Ray{}).valid());
    EXPECT_FALSE(intersect_any(empty, e, Ray{}));
    for (std::size_t n : {1u, 2u, 3u, 17u}) {
        const Mesh m = make_random_soup(n, 5 + n, 0.3f);
        for (unsigned leaf : {1u, 4u}) {
            const Bvh bvh = build(m, leaf);
            expect_valid(m, bvh);
            expect_matches_brute_force(m, bvh, random_rays(m, 500, n));
        }
    }
}

TEST(Bvh, RandomSoupsMatchBruteForce) {
    for (std::uint64_t seed = 1; seed <= 4; ++seed) {
        const Mesh m = make_random_soup(3000, seed, 0.05f * float(seed));
        for (unsigned leaf : {1u, 4u, 8u}) {
            const Bvh bvh = build(m, leaf);
            expect_valid(m, bvh);
            expect_matches_brute_force(m, bvh, random_rays(m, 1500, seed * 7));
        }
    }
}

TEST(Bvh, ClosedMeshesMatchBruteForceForAllTests) {
    const Mesh m = make_bumpy_torus(20000);
    const Bvh bvh = build(m);
    expect_valid(m, bvh);
    const auto rays = random_rays(m, 3000, 99);
    expect_matches_brute_force<Watertight>(m, bvh, rays);
    expect_matches_brute_force<MollerTrumbore>(m, bvh, rays);
    // The thesis test's tolerance accepts points just outside a triangle, so
    // it can "hit" outside the triangle's own box, where a BVH never looks.
    const std::size_t leaks = expect_matches_brute_force<ThesisTest>(m, bvh, rays, false);
    std::printf("[ info ] thesis test: %zu of %zu rays differ between BVH and brute force\n", leaks, rays.size());
}

TEST(Bvh, SameTreeForOneAndTwoThreads) {
    const Mesh m = make_bumpy_torus(200000);
    BinnedSahBuilder::Config c;
    c.parallel_threshold = 1000;
    c.threads = 1;
    const Bvh a = build_bvh<BinnedSahBuilder>(m, c);
    c.threads = 2;
    const Bvh b = build_bvh<BinnedSahBuilder>(m, c);
    c.threads = 7;
    const Bvh d = build_bvh<BinnedSahBuilder>(m, c);
    ASSERT_EQ(a.nodes.size(), b.nodes.size());
    ASSERT_EQ(a.nodes.size(), d.nodes.size());
    EXPECT_EQ(std::memcmp(a.nodes.data(), b.nodes.data(), a.nodes.size() * sizeof(Node)), 0);
    EXPECT_EQ(std::memcmp(a.nodes.data(), d.nodes.data(), a.nodes.size() * sizeof(Node)), 0);
    EXPECT_EQ(a.prim_ids, b.prim_ids);
    EXPECT_EQ(a.prim_ids, d.prim_ids);
    expect_valid(m, a);
}

/// Rays from outside a closed mesh aimed exactly at vertices and edge points
/// must hit it. Watertight: zero misses (asserted). Möller–Trumbore and the
/// thesis test: misses counted and printed (data for the accuracy chart).
TEST(Bvh, ExactVertexAndEdgeRaysNeverMissAClosedMesh) {
    for (float scale : {1.0f, 1e3f}) {
        for (float offset : {0.0f, 1e6f}) {
            Mesh m = make_icosphere(4);
            transform_positions(m, scale, vec3(offset, -offset, offset));
            const Bvh bvh = build(m);
            const BlockBvh8 blk = BlockBvh8::build(m, bvh);
            std::mt19937_64 rng(42);
            std::uniform_real_distribution<float> U(-1.0f, 1.0f);
            const vec3 center(offset, -offset, offset);
            std::size_t miss_wt = 0, miss_blk = 0, miss_mt = 0, miss_th = 0, n = 0;
            for (const Triangle& t : m.triangles) {
                const vec3 a = m.positions[t.v[0]], b = m.positions[t.v[1]];
                for (const vec3& target : {a, (a + b) * 0.5f, a + (b - a) * 0.25f}) {
                    vec3 dir(U(rng), U(rng), U(rng));
                    const vec3 o = target - glm::normalize(target - center + dir * 0.5f * scale) * 3.0f * scale;
                    const Ray r{o, 0.0f, target - o, kInf};
                    ++n;
                    miss_wt += !intersect_closest<Watertight>(m, bvh, r).valid();
                    miss_blk += !intersect_closest(blk, r).valid();
                    miss_mt += !intersect_closest<MollerTrumbore>(m, bvh, r).valid();
                    miss_th += !intersect_closest<ThesisTest>(m, bvh, r).valid();
                }
            }
            EXPECT_EQ(miss_wt, 0u) << "scale " << scale << " offset " << offset;
            EXPECT_EQ(miss_blk, 0u) << "4-triangle blocks, scale " << scale << " offset " << offset;
            std::printf("[ info ] vertex/edge rays, scale %g offset %g: misses of %zu: watertight %zu, "
                        "moller-trumbore %zu, thesis %zu\n",
                        scale, offset, n, miss_wt, miss_mt, miss_th);
        }
    }
}

TEST(Bvh, AxisParallelRaysWithSignedZerosHitAGrid) {
    // A closed box made of a fine grid on each face: rays along ±x, ±y, ±z
    // with ±0 in the other components, through grid vertices and edges.
    Mesh m = make_icosphere(3);
    const Bvh bvh = build(m);
    std::size_t miss = 0, n = 0;
    for (int axis = 0; axis < 3; ++axis)
        for (float s : {1.0f, -1.0f})
            for (float z : {0.0f, -0.0f})
                for (const vec3& p : m.positions) {
                    vec3 d(z), o = p * 0.999f;
                    d[axis] = s;
                    o[axis] = -5.0f * s;
                    if (std::fabs(p[axis]) < 0.2f) continue;  // grazing
                    const Ray r{o, 0.0f, d, kInf};
                    const Hit h = intersect_closest(m, bvh, r);
                    const Hit b = brute_force_closest(m, r);
                    ++n;
                    miss += !h.valid();
                    EXPECT_EQ(h.prim, b.prim);
                    EXPECT_EQ(h.t, b.t);
                }
    EXPECT_EQ(miss, 0u) << "of " << n;
}

TEST(Bvh, DegenerateNeedleAndNanTrianglesBuildValidTrees) {
    Mesh m = make_random_soup(2000, 3, 0.1f);
    const float nan = std::numeric_limits<float>::quiet_NaN();
    // needles and zero-area triangles
    for (int i = 0; i < 500; ++i) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        const vec3 p(float(i) / 500.0f, 0.5f, 0.5f);
        m.positions.push_back(p);
        m.positions.push_back(p + vec3(0.3f, 1e-7f, 0.0f));
        m.positions.push_back(i % 2 ? p : p + vec3(0.6f, 2e-7f, 0.0f));
        m.triangles.push_back({{base, base + 1, base + 2}});
    }
    // NaN and inf vertices
    for (int i = 0; i < 50; ++i) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        m.positions.push_back({nan, 0.5f, 0.5f});
        m.positions.push_back({0.2f, i % 2 ? kInf : nan, 0.5f});
        m.positions.push_back({0.5f, 0.5f, 0.5f});
        m.triangles.push_back({{base, base + 1, base + 2}});
    }
    const Bvh bvh = build(m);
    expect_valid(m, bvh);
    const auto rays = random_rays(m, 2000, 5);
    expect_matches_brute_force(m, bvh, rays);
    for (const Ray& r : rays) {
        const Hit h = intersect_closest(m, bvh, r);
        if (h.valid()) {
            EXPECT_LT(h.prim, 2500u) << "a NaN triangle was hit";
        }
    }
}

TEST(Bvh, CoincidentCentroidsAndIdenticalTriangles) {
    Mesh m;
    m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    for (int i = 0; i < 1000; ++i) m.triangles.push_back({{0, 1, 2}});
    const Bvh bvh = build(m, 4);
    expect_valid(m, bvh);
    EXPECT_LE(bvh.depth(), RAYKIT_BVH_MAX_DEPTH);
    const Ray r{{0.2f, 0.2f, 1.0f}, 0.0f, {0, 0, -1}, kInf};
    const Hit h = intersect_closest(m, bvh, r);
    EXPECT_EQ(h.prim, 0u) << "ties must go to the smallest index";
    // rotated copies around one centre: distinct triangles, one centroid
    Mesh s;
    for (int i = 0; i < 300; ++i) {
        const float a = 0.01f * float(i);
        const auto base = static_cast<std::uint32_t>(s.positions.size());
        for (int k = 0; k < 3; ++k) {
            const float b = a + 2.0943951f * float(k);
            s.positions.push_back({std::cos(b), std::sin(b), 0.001f * float(i)});
        }
        s.triangles.push_back({{base, base + 1, base + 2}});
    }
    const Bvh sb = build(s, 2);
    expect_valid(s, sb);
    expect_matches_brute_force(s, sb, random_rays(s, 1000, 3));
}

/// The deepest tree we can provoke: triangles shrinking geometrically towards
/// a point (each half the size and distance of the previous), so every SAH
/// split peels off one triangle. The depth bound must hold and traversal work.
TEST(Bvh, GeometricProgressionStaysWithinTheDepthBound) {
    Mesh m;
    float s = 1.0f;
    for (int i = 0; i < 4000; ++i) {
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        const float x = s;
        m.positions.push_back({x, 0.0f, 0.0f});
        m.positions.push_back({x + s * 0.5f, s * 0.5f, 0.0f});
        m.positions.push_back({x, s * 0.5f, s * 0.5f});
        m.triangles.push_back({{base, base + 1, base + 2}});
        s *= (i < 120 ? 0.5f : 0.999f);
        if (s < 1e-30f) s = 1e-30f;
    }
    for (unsigned leaf : {1u, 8u}) {
        const Bvh bvh = build(m, leaf);
        expect_valid(m, bvh);
        EXPECT_LE(bvh.depth(), RAYKIT_BVH_MAX_DEPTH);
        std::printf("[ info ] geometric progression, leaf %u: depth %d\n", leaf, bvh.depth());
        expect_matches_brute_force(m, bvh, random_rays(m, 1000, 2));
    }
}

TEST(Bvh, RefitMatchesAFreshTreeAndBruteForce) {
    Mesh m = make_bumpy_torus(20000);
    Bvh bvh = build(m);
    for (vec3& p : m.positions) p += vec3(0.2f * std::sin(3.0f * p.y), 0.1f * p.x, 0.0f);
    const MeshView view(m);
    refit(bvh, [&](std::uint32_t i) { return view.bounds(i); });
    expect_valid(m, bvh);
    expect_matches_brute_force(m, bvh, random_rays(m, 2000, 8));
    // a refitted root box equals the exact bounds
    AABB all;
    for (std::size_t i = 0; i < m.triangle_count(); ++i) all.grow(view.bounds(i));
    EXPECT_EQ(bvh.nodes[0].box, all);
}

TEST(Bvh, BinnedSahCostIsNearASweepSahReference) {
    // Reference: the same mesh with 256 bins; 32 bins must be within 2 %.
    const Mesh m = make_bumpy_torus(50000);
    BinnedSahBuilder::Config c;
    c.leaf.max_leaf_size = 4;
    const double c32 = sah_cost(build_bvh<BinnedSahBuilder>(m, c));
    c.bins = 256;
    const double c256 = sah_cost(build_bvh<BinnedSahBuilder>(m, c));
    std::printf("[ info ] SAH cost 32 bins %.3f, 256 bins %.3f\n", c32, c256);
    EXPECT_LT(c32, c256 * 1.02);
}

namespace {

/// Node and block equality by value (float ==, so ±0 planes compare equal: min/max of the same
/// floats may keep either zero depending on merge order), printing the first difference.
template <int W>
::testing::AssertionResult same_blocks(const BlockBvhT<W>& a, const BlockBvhT<W>& b, bool planes = true) {
    if (a.tree.nodes.size() != b.tree.nodes.size() || a.blocks.size() != b.blocks.size())
        return ::testing::AssertionFailure() << "sizes differ: " << a.tree.nodes.size() << "/" << a.blocks.size()
                                             << " vs " << b.tree.nodes.size() << "/" << b.blocks.size();
    for (std::size_t i = 0; i < a.tree.nodes.size(); ++i) {
        const auto &x = a.tree.nodes[i], &y = b.tree.nodes[i];
        if constexpr (W == 2) {
            if (!(x.box.min == y.box.min && x.box.max == y.box.max) || x.index != y.index || x.count != y.count)
                return ::testing::AssertionFailure() << "binary node " << i << " differs";
        } else {
            for (int c = 0; c < W; ++c) {
                if (x.index[c] != y.index[c] || x.count[c] != y.count[c])
                    return ::testing::AssertionFailure() << "node " << i << " slot " << c << " differs";
                for (int r = 0; r < 6 && planes; ++r)
                    if (!(x.planes[r][c] == y.planes[r][c]))
                        return ::testing::AssertionFailure() << "node " << i << " slot " << c << " plane " << r
                                                             << ": " << x.planes[r][c] << " vs " << y.planes[r][c];
            }
        }
    }
    for (std::size_t k = 0; k < a.blocks.size(); ++k)
        for (int l = 0; l < 4; ++l) {
            if (a.blocks[k].prim[l] != b.blocks[k].prim[l])
                return ::testing::AssertionFailure() << "block " << k << " lane " << l << " prim differs";
            for (int r = 0; r < 9; ++r)
                if (!(a.blocks[k].p[r][l] == b.blocks[k].p[r][l]))
                    return ::testing::AssertionFailure() << "block " << k << " lane " << l << " plane " << r;
        }
    return ::testing::AssertionSuccess();
}

/// Every wide slot's box is exactly the union of the bounds of the mesh triangles below it
/// (recomputed from scratch), and the root bounds the union of the root's slots.
template <int W>
::testing::AssertionResult tight_boxes(const BlockBvhT<W>& b, const MeshView& m) {
    const auto below = [&](auto&& self, std::uint32_t node, int c) -> AABB {
        const auto& n = b.tree.nodes[node];
        AABB box;
        if (n.count[c] != 0) {
            for (std::uint32_t k = n.index[c]; k < n.index[c] + n.count[c]; ++k)
                for (int l = 0; l < 4; ++l) box.grow(m.bounds(b.blocks[k].prim[l]));
        } else {
            for (int k = 0; k < W; ++k)
                if (!b.tree.nodes[n.index[c]].unused(k)) box.grow(self(self, n.index[c], k));
        }
        return box;
    };
    AABB root;
    for (std::uint32_t i = 0; i < b.tree.nodes.size(); ++i)
        for (int c = 0; c < W; ++c) {
            if (b.tree.nodes[i].unused(c)) continue;
            const AABB want = below(below, i, c), got = b.tree.nodes[i].box(c);
            if (!(want.min == got.min && want.max == got.max))
                return ::testing::AssertionFailure() << "node " << i << " slot " << c << " is not the tight box";
            if (i == 0) root.grow(want);
        }
    if (!(root.min == b.tree.bounds.min && root.max == b.tree.bounds.max))
        return ::testing::AssertionFailure() << "root bounds are not the union of the root's slots";
    return ::testing::AssertionSuccess();
}

}  // namespace

TEST(Bvh, EveryTreeShapeRefitsInPlaceToTheRemake) {
    // A wave moves the vertices of a torus 10^4 out. Refitting each member of the family in
    // place (binary, 4- and 8-wide indexed trees; blocks under 2-, 4- and 8-wide nodes) must give
    // the blocks made again from the moved mesh over the same topology, with every box the tight
    // union of what lies below it (for binary nodes: exactly the refitted binary tree's), and
    // queries must equal brute force. (Collapsing the refitted binary tree again may choose a
    // different wide topology: it opens the children of largest area.)
    Mesh m = make_bumpy_torus(30000);
    transform_positions(m, 3.0f, vec3(1e4f, 0.0f, 0.0f));
    const Bvh bvh = build_bvh<BinnedSahBuilder>(m, BlockBvh8::sah_config());
    WideBvh wide4 = WideBvh::build(bvh);
    WideBvh8 wide8 = WideBvh8::build(bvh);
    BlockBvh2 b2 = BlockBvh2::build(m, bvh);
    BlockBvh b4 = BlockBvh::build(m, bvh);
    BlockBvh8 b8 = BlockBvh8::build(m, bvh);
    for (vec3& p : m.positions) p.z += 0.1f * std::sin(p.x) + 0.5f * std::cos(0.01f * p.y);
    const MeshView view(m);
    const auto box = [&](std::uint32_t i) { return view.bounds(i); };
    Bvh moved = bvh;
    refit(moved, box);
    refit(wide4, box);
    refit(wide8, box);
    b2.refit(view);
    b4.refit(view);
    b8.refit(view);
    EXPECT_TRUE(same_blocks(b2, BlockBvh2::build(m, moved)));
    EXPECT_TRUE(same_blocks(b4, BlockBvh::build(m, WideBvh::build(bvh)), false));
    EXPECT_TRUE(same_blocks(b8, BlockBvh8::build(m, WideBvh8::build(bvh)), false));
    EXPECT_TRUE(tight_boxes(b4, view));
    EXPECT_TRUE(tight_boxes(b8, view));
    EXPECT_EQ(wide8.validate(primitive_refs(m).boxes), "");
    EXPECT_EQ(wide4.validate(primitive_refs(m).boxes), "");
    EXPECT_EQ(wide8.bounds.min, moved.nodes[0].box.min);
    EXPECT_EQ(wide8.bounds.max, moved.nodes[0].box.max);
    EXPECT_EQ(b8.tree.bounds.min, moved.nodes[0].box.min);
    EXPECT_EQ(b8.tree.bounds.max, moved.nodes[0].box.max);
    std::size_t bad = 0, hits = 0;
    for (const Ray& r : random_rays(m, 2000, 22)) {
        const Hit o = brute_force_closest(m, r);
        hits += o.valid();
        for (const Hit h : {intersect_closest(m, moved, r), intersect_closest(m, wide4, r),
                            intersect_closest(m, wide8, r), intersect_closest(b2, r), intersect_closest(b4, r),
                            intersect_closest(b8, r)})
            bad += h.prim != o.prim || h.t != o.t || h.u != o.u || h.v != o.v;
        const bool any = brute_force_any(m, r);
        bad += intersect_any(m, wide8, r) != any;
        bad += intersect_any(b8, r) != any;
    }
    std::printf("[ info ] after the move: %zu of 2000 rays hit; %zu disagreements with brute force\n", hits, bad);
    EXPECT_GT(hits, 200u);
    EXPECT_EQ(bad, 0u);
}

TEST(Bvh, LeafFiltersSkipRejectedTrianglesInEveryStore) {
    // Rejecting every odd triangle must equal brute force over the even triangles alone,
    // through the indexed and the block store, closest and any hit.
    const Mesh m = make_bumpy_torus(20000);
    Mesh even = m;
    even.triangles.clear();
    std::vector<std::uint32_t> orig;
    for (std::uint32_t t = 0; t < m.triangles.size(); t += 2) {
        even.triangles.push_back(m.triangles[t]);
        orig.push_back(t);
    }
    const Bvh bvh = build_bvh<BinnedSahBuilder>(m, BlockBvh8::sah_config());
    const BlockBvh8 b8 = BlockBvh8::build(m, bvh);
    const auto keep = [](std::uint32_t p, float, float) { return p % 2 == 0; };
    std::size_t bad = 0, hits = 0;
    for (const Ray& r : random_rays(m, 3000, 5)) {
        const Hit o = brute_force_closest(even, r);
        const std::uint32_t want = o.valid() ? orig[o.prim] : kInvalidIndex;
        hits += o.valid();
        const Hit a = intersect_closest(m, bvh, r, nullptr, keep), b = intersect_closest(b8, r, nullptr, keep);
        bad += a.prim != want || b.prim != want || (o.valid() && (a.t != o.t || b.t != o.t));
        const bool any = brute_force_any(even, r);
        bad += intersect_any(m, bvh, r, nullptr, keep) != any;
        bad += intersect_any(b8, r, nullptr, keep) != any;
    }
    std::printf("[ info ] filtered: %zu of 3000 rays hit an even triangle; %zu disagreements\n", hits, bad);
    EXPECT_GT(hits, 300u);
    EXPECT_EQ(bad, 0u);
}

TEST(Bvh, RebuildPolicyFiresWhenNeighbourhoodsBreakNotBefore) {
    const Mesh rest = make_bumpy_torus(20000);
    Mesh m = rest;
    Bvh bvh = build(m);
    RebuildPolicy policy;
    policy.reset(sah_cost(bvh));
    int first_rebuild = -1;
    for (int f = 1; f <= 20; ++f) {
        for (std::size_t i = 0; i < m.positions.size(); ++i) {
            const vec3 p = rest.positions[i];
            vec3 q = p + vec3(0.0f, 0.0f, 0.08f * std::sin(6.0f * p.x + 0.3f * float(f)));
            if (f > 10 && std::atan2(p.y, p.x) > 2.0f) q += vec3(-0.5f, 1.0f, 0.6f) * 0.25f * float(f - 10);
            m.positions[i] = q;
        }
        const MeshView view(m);
        refit(bvh, [&](std::uint32_t i) { return view.bounds(i); });
        const double cost = sah_cost(bvh);
        if (policy.should_rebuild(cost)) {
            if (first_rebuild < 0) first_rebuild = f;
            EXPECT_GT(f, 10) << "wave frames keep neighbourhoods; growth " << policy.growth(cost);
            bvh = build(m);
            policy.reset(sah_cost(bvh));
        }
        expect_valid(m, bvh);
    }
    EXPECT_GT(first_rebuild, 10);
    EXPECT_LE(first_rebuild, 15) << "the thrown sector must trigger a rebuild within 5 frames";
}

TEST(Bvh, RealMeshesMatchBruteForce) {
    const std::string dir = RAYKIT_SHARED_DATA_DIR;
    int tested = 0;
    for (const char* rel : {"/obj/stanford_bunny/stanford-bunny.obj", "/obj/thesis_scene/Scene.obj",
                            "/obj/spot/spot.obj", "/obj/helix/CornellBox-Glossy/CornellBox-Glossy.obj"}) {
        const std::string path = dir + rel;
        if (!std::filesystem::exists(path)) continue;
        const Mesh m = load_obj(path);
        const Bvh bvh = build(m);
        expect_valid(m, bvh);
#if defined(__SANITIZE_ADDRESS__)
        const std::size_t n = 150;
#else
        const std::size_t n = 1200;
#endif
        SCOPED_TRACE(path);
        expect_matches_brute_force(m, bvh, random_rays(m, n, 31));
        ++tested;
    }
    if (tested == 0) GTEST_SKIP() << "shared data not found under " << dir;
}

TEST(WideBvh, CollapseKeepsLeavesAndHalvesTheVisits) {
    const Mesh m = make_bumpy_torus(20000);
    const Bvh bvh = build(m);
    const WideBvh wide = WideBvh::build(bvh);
    EXPECT_EQ(wide.validate(primitive_refs(m).boxes), "");
    EXPECT_EQ(wide.prim_ids, bvh.prim_ids);
    EXPECT_LE(wide.depth(), bvh.depth());
    EXPECT_LT(wide.nodes.size(), bvh.nodes.size() / 2);
    // every binary leaf is a wide leaf slot
    std::size_t bin_leaves = bvh.leaf_count(), wide_leaves = 0;
    for (const WideNode& n : wide.nodes)
        for (int c = 0; c < WideNode::kWidth; ++c) wide_leaves += n.is_leaf(c);
    EXPECT_EQ(wide_leaves, bin_leaves);
    TraversalStats sb, sw;
    std::size_t same = 0;
    const auto rays = random_rays(m, 4000, 17);
    for (const Ray& r : rays) {
        const Hit a = intersect_closest(m, bvh, r, &sb);
        const Hit b = intersect_closest(m, wide, r, &sw);
        same += a.prim == b.prim && a.t == b.t && a.u == b.u && a.v == b.v;
    }
    EXPECT_EQ(same, rays.size());
    std::printf("[ info ] torus 20k: nodes visited per ray binary %.2f, wide %.2f; leaves %.2f / %.2f\n",
                double(sb.nodes) / rays.size(), double(sw.nodes) / rays.size(), double(sb.leaves) / rays.size(),
                double(sw.leaves) / rays.size());
    EXPECT_LT(sw.nodes * 10, sb.nodes * 7) << "a wide node should replace well over one binary node";
    // moving collapse takes the primitive order along
    Bvh copy = bvh;
    const WideBvh moved = WideBvh::build(std::move(copy));
    EXPECT_EQ(moved.prim_ids, bvh.prim_ids);
    EXPECT_EQ(moved.nodes.size(), wide.nodes.size());
}

TEST(WideBvh, EmptyOneTriangleAndLeafRoot) {
    Mesh empty;
    const WideBvh e = WideBvh::build(build(empty));
    EXPECT_TRUE(e.empty());
    EXPECT_FALSE(intersect_closest(empty, e, Ray{{0, 0, -1}, 0.0f, {0, 0, 1}, kInf}).valid());
    Mesh one;
    one.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    one.triangles = {{{0, 1, 2}}};
    const Bvh b1 = build(one);
    ASSERT_TRUE(b1.nodes[0].is_leaf());
    const WideBvh w1 = WideBvh::build(b1);
    EXPECT_EQ(w1.validate(primitive_refs(one).boxes), "");
    const Hit h = intersect_closest(one, w1, Ray{{0.25f, 0.25f, -1.0f}, 0.0f, {0, 0, 1}, kInf});
    EXPECT_EQ(h.prim, 0u);
    EXPECT_EQ(h.t, 1.0f);
    EXPECT_TRUE(intersect_any(one, w1, Ray{{0.25f, 0.25f, -1.0f}, 0.0f, {0, 0, 1}, kInf}));
    EXPECT_FALSE(intersect_any(one, w1, Ray{{0.75f, 0.75f, -1.0f}, 0.0f, {0, 0, 1}, kInf}));
}

/// The SSE box test must make the scalar test's decisions, bit for bit, on
/// the inputs that break slab tests: ±0 and tiny direction components, origins
/// on a box plane (0·inf = NaN), empty and flat boxes, huge coordinates.
template <int W>
void simd_box_test_equals_scalar() {
    std::mt19937_64 rng(99);
    std::uniform_real_distribution<float> U(-2.0f, 2.0f);
    const float specials[] = {0.0f, -0.0f, 1e-30f, -1e-30f, 1.0f, -1.0f, 1e30f};
    std::size_t checked = 0, hits = 0;
    for (int iter = 0; iter < 20000; ++iter) {
        WideNodeT<W> n;
        for (int c = 0; c < W; ++c) {
            AABB b;
            const vec3 p(U(rng), U(rng), U(rng)), q(U(rng), U(rng), U(rng));
            b.min = glm::min(p, q);
            b.max = glm::max(p, q);
            if (iter % 7 == c) b.max.x = b.min.x;               // flat box
            if (iter % 11 == c) b = {vec3(1e6f), vec3(1e6f + 1.0f)};  // far away
            n.set_box(c, b);
            n.index[c] = 1;
            n.count[c] = 1;
            if (iter % 13 == c) n.clear(c);  // unused slot
        }
        Ray r;
        r.org = {U(rng), U(rng), U(rng)};
        for (int a = 0; a < 3; ++a) {
            r.dir[a] = (rng() % 4 == 0) ? specials[rng() % 7] : U(rng);
            if (rng() % 5 == 0) r.org[a] = n.planes[2 * a + (rng() % 2)][rng() % W];  // on a plane
        }
        r.tmin = (rng() % 3 == 0) ? 0.5f : 0.0f;
        r.tmax = (rng() % 3 == 0) ? 1.5f : kInf;
        const WideSlabRay wr(r);
        alignas(32) float ts[W], tv[W];
        const unsigned ms = wr.test_scalar(n, r.tmin, r.tmax, ts);
        const unsigned mv = wr.test(n, r.tmin, r.tmax, tv);
        ASSERT_EQ(ms, mv) << "iteration " << iter;
        for (int c = 0; c < W; ++c) {
            if (ms >> c & 1u) {
                ASSERT_EQ(ts[c], tv[c]) << "iteration " << iter << " child " << c;
                ++hits;
            }
            if (n.unused(c)) continue;
            // and the binary tree's slab test decides the same on this box
            float tb;
            const AABB box = n.box(c);
            const bool bh = slab_test(&box.min.x, &box.max.x, r.org, RayInv(r.dir), r.tmin, r.tmax, tb);
            ASSERT_EQ(bh, bool(ms >> c & 1u)) << "iteration " << iter << " child " << c;
            ASSERT_EQ(bh, wr.test_box(box, r.tmin, r.tmax)) << "root-box test, iteration " << iter << " child " << c;
            if (bh) {
                ASSERT_EQ(tb, ts[c]);
            }
        }
        for (int c = 0; c < W; ++c)
            if (n.unused(c)) {
                ASSERT_FALSE(ms >> c & 1u) << "an unused slot was entered";
            }
        ++checked;
    }
    EXPECT_GT(hits, checked / 10);  // the cases are not all misses
    std::printf("[ info ] %zu boxes entered in %zu %d-wide tests\n", hits, checked, W);
}

TEST(WideBvh, SimdBoxTestEqualsScalarOnHardCases) {
    simd_box_test_equals_scalar<4>();
    simd_box_test_equals_scalar<8>();
}

TEST(WideBvh, EightWideCollapse) {
    const Mesh m = make_bumpy_torus(20000);
    const Bvh bvh = build(m);
    const WideBvh w4 = WideBvh::build(bvh);
    const WideBvh8 w8 = WideBvh8::build(bvh);
    EXPECT_EQ(w8.validate(primitive_refs(m).boxes), "");
    EXPECT_LE(w8.depth(), w4.depth());
    EXPECT_LT(w8.nodes.size(), w4.nodes.size());
    TraversalStats s4, s8;
    for (const Ray& r : random_rays(m, 2000, 23)) {
        const Hit a = intersect_closest(m, w4, r, &s4), b = intersect_closest(m, w8, r, &s8);
        ASSERT_EQ(a.prim, b.prim);
        ASSERT_EQ(a.t, b.t);
    }
    EXPECT_LT(s8.nodes, s4.nodes);
}

// ---------------------------------------------------------------- coordinate range (math/limits.hpp)

namespace {

/// Expects `f` to throw std::domain_error whose message contains every piece of `says`.
template <class F>
void expect_range_error(F&& f, std::initializer_list<const char*> says) {
    try {
        f();
        ADD_FAILURE() << "accepted; expected an error naming " << *says.begin();
    } catch (const std::domain_error& e) {
        for (const char* s : says) EXPECT_NE(std::string(e.what()).find(s), std::string::npos) << e.what();
    }
}

/// One triangle in the z = `z` plane spanning ±`size` around (cx, cy).
Mesh one_triangle(float cx, float cy, float z, float size) {
    Mesh m;
    m.positions = {{cx - size, cy - size, z}, {cx + size, cy - size, z}, {cx, cy + size, z}};
    m.triangles = {{{0, 1, 2}}};
    return m;
}

}  // namespace

TEST(CoordinateRange, TreesRejectVerticesBeyondTheBoundByName) {
    Mesh m = make_random_soup(50, 3, 0.1f);
    m.positions.push_back({0.0f, 0.0f, -1e14f});
    m.triangles.push_back({{0, 1, static_cast<std::uint32_t>(m.positions.size() - 1)}});
    const std::size_t bad = m.positions.size() - 1;
    const std::string vertex = "vertex " + std::to_string(bad) + " coordinate z = -1e+14";
    expect_range_error([&] { build_bvh(m); }, {vertex.c_str(), "2^32"});
    expect_range_error([&] { (void)primitive_refs(m); }, {vertex.c_str()});
    BuildOptions o;
    for (const auto b : {BuildOptions::Builder::sah, BuildOptions::Builder::pairwise, BuildOptions::Builder::sortaxis,
                         BuildOptions::Builder::ploc}) {
        o.builder = b;
        expect_range_error([&] { build_bvh(m, o); }, {vertex.c_str()});
    }
    // the bound itself is inside; one float beyond it is not
    Mesh edge = one_triangle(0.0f, 0.0f, kMaxCoordinate, 1e6f);
    EXPECT_NO_THROW(build_bvh(edge));
    edge.positions[2].y = -next_float_up(kMaxCoordinate);
    expect_range_error([&] { build_bvh(edge); }, {"vertex 2 coordinate y = -4.29496781e+09"});
    // non-finite vertices stay allowed (their triangles are never hit)
    Mesh nan = one_triangle(0.0f, 0.0f, 1.0f, 1.0f);
    nan.positions[1].x = std::numeric_limits<float>::quiet_NaN();
    nan.positions[2].z = -kInf;
    EXPECT_NO_THROW(build_bvh(nan));
}

/// At the bound, through the tree: a far triangle is hit where it is.
TEST(CoordinateRange, TreesAtTheBoundAnswerRight) {
    const float far = kMaxCoordinate, size = 0x1p30f;
    const Mesh m = one_triangle(-far + size, far - size, -far, size);
    const Bvh bvh = build_bvh(m);
    // from the opposite corner of the allowed cube, a direction of 2^-16
    const Ray r{vec3(far, -far, far), 0.0f, vec3(-2.0f * far + size, 2.0f * far - size, -2.0f * far) * 0x1p-49f, kInf};
    ASSERT_TRUE(ray_in_range(r)) << ray_range_error(r);
    const Hit h = intersect_closest(m, bvh, r);
    ASSERT_TRUE(h.valid());
    EXPECT_NEAR(h.t, 0x1p49f, 0x1p49f * 1e-6f);  // the target point is at t = 2^49
    EXPECT_NEAR(h.u, 0.25f, 1e-5f);
    EXPECT_NEAR(h.v, 0.5f, 1e-5f);
    EXPECT_TRUE(intersect_any(m, bvh, r));
}

TEST(CoordinateRange, SceneRejectsObjectsMovesAndInstancesBeyondTheBound) {
    Scene s;
    expect_range_error([&] { s.add_object(one_triangle(0.0f, 0.0f, 5e20f, 1.0f)); },
                       {"Scene::add_object", "coordinate z = 5.0000001e+20"});
    EXPECT_TRUE(s.objects().empty());
    const std::uint32_t stat = s.add_object(one_triangle(0.0f, 0.0f, kMaxCoordinate, 1.0f));
    const std::uint32_t dyn = s.add_object(one_triangle(0.0f, 0.0f, 0.0f, 1.0f), ObjectKind::dynamic);
    s.add_instance(stat);
    const std::uint32_t moved = s.add_instance(dyn);
    EXPECT_NO_THROW(s.update_top_level());  // an object at the bound passes, padding and all
    const Ray down{vec3(0.0f, 0.0f, 10.0f), 0.0f, vec3(0, 0, -1), kInf};
    ASSERT_EQ(s.intersect_closest(down).inst, moved);

    // an instance placed beyond the bound: rejected, naming the instance
    s.set_transform(moved, glm::translate(mat4(1.0f), vec3(3e14f, 0.0f, 0.0f)));
    expect_range_error([&] { s.update_top_level(); }, {"instance 1", "on axis x", "2^32"});
    s.set_transform(moved, mat4(1.0f));
    s.update_top_level();

    // positions set beyond it: rejected, nothing changed
    std::vector<vec3> far = s.objects()[dyn].mesh.positions;
    far[1].y = 1e30f;
    expect_range_error([&] { s.set_positions(dyn, far); }, {"set_positions", "vertex 1 coordinate y = 1.00000002e+30"});
    EXPECT_EQ(s.objects()[dyn].mesh.positions[1].y, -1.0f);
    // moved beyond it: rejected, the object back at rest and consistent
    s.move_vertices(dyn, [](const Vertex& v, std::uint32_t) { return Vertex{v.position + vec3(0.5f, 0.0f, 0.0f), {}, {}}; });
    expect_range_error(
        [&] { s.move_vertices(dyn, [](const Vertex& v, std::uint32_t i) { return Vertex{v.position * (i == 2 ? 1e13f : 1.0f), {}, {}}; }); },
        {"move_vertices", "vertex 2 coordinate y = 9.99999983e+12"});
    EXPECT_EQ(s.objects()[dyn].mesh.positions[0], vec3(-1.0f, -1.0f, 0.0f));
    s.update_top_level();
    const Hit h = s.intersect_closest(down);
    EXPECT_EQ(h.inst, moved);
    EXPECT_EQ(h.t, 10.0f);
    EXPECT_EQ(h.prim, s.brute_force_closest(down).prim);
}
