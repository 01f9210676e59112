// The 4-triangle watertight test (intersect/triangle4.hpp) against the scalar
// test lane by lane, and block trees (scene/block_bvh.hpp) built for it
// against brute force. (Block trees over ordinary trees are also checked in
// every brute-force comparison of test_bvh.cpp.)
#include <gtest/gtest.h>

#include <bit>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/generate.hpp"
#include "test_support.hpp"

using namespace raykit;

namespace {

bool same_bits(float a, float b) { return std::bit_cast<std::uint32_t>(a) == std::bit_cast<std::uint32_t>(b); }

/// Runs the four lanes of `blk` and the scalar test on each triangle; counts
/// lanes that differ in hit/miss or (on a hit) in any bit of t, u, v.
std::size_t lane_differences(const TriangleBlock4& blk, const Ray& r, float tmin, float tmax, std::string* first) {
    const Watertight4::RayData d4 = Watertight4::prepare(r);
    const Watertight::RayData d1 = Watertight::prepare(r);
    alignas(16) float t[4], u[4], v[4];
    const unsigned m = Watertight4::intersect(d4, blk, tmin, tmax, t, u, v);
    std::size_t bad = 0;
    for (int i = 0; i < 4; ++i) {
        TriHit h{};
        const bool hit = Watertight::intersect(d1, blk.corner(i, 0), blk.corner(i, 1), blk.corner(i, 2), tmin, tmax, h);
        const bool lane = (m >> i) & 1u;
        if (hit != lane || (hit && (!same_bits(h.t, t[i]) || !same_bits(h.u, u[i]) || !same_bits(h.v, v[i])))) {
            if (first && first->empty())
                *first = "lane " + std::to_string(i) + ": scalar " + (hit ? "hit" : "miss") + " t " + std::to_string(h.t) +
                         ", block " + (lane ? "hit" : "miss") + " t " + std::to_string(t[i]);
            ++bad;
        }
    }
    return bad;
}

}  // namespace

TEST(Triangle4, LanesEqualTheScalarTestBitForBit) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::size_t hits = 0, lanes = 0, bad = 0;
    std::string first;
    for (float offset : {0.0f, 1e3f, 1e6f}) {
        for (int k = 0; k < 20000; ++k) {
            TriangleBlock4 blk;
            const vec3 c = vec3(offset, -offset, 0.5f * offset) + vec3(U(rng), U(rng), U(rng));
            vec3 corners[4][3];
            for (int i = 0; i < 4; ++i) {
                for (auto& p : corners[i]) p = c + vec3(U(rng), U(rng), U(rng)) * 0.5f;
                blk.set(i, corners[i][0], corners[i][1], corners[i][2], std::uint32_t(i));
            }
            Ray r;
            r.org = c + vec3(U(rng), U(rng), U(rng)) * 3.0f;
            // aim at a lane's vertex, an edge point, or the block's middle: edge cases and hits
            const vec3* tri = corners[k % 4];
            const vec3 target = k % 3 == 0 ? tri[0] : k % 3 == 1 ? (tri[0] + tri[1]) * 0.5f : c;
            r.dir = target - r.org;
            if (k % 7 == 0) r.dir[k % 3] = (k & 8) ? -0.0f : 0.0f;  // axis-parallel components, signed zeros
            if (r.dir == vec3(0.0f)) r.dir = vec3(0.0f, 0.0f, 1.0f);
            const float tmax = k % 5 == 0 ? 0.9f : kInf;
            bad += lane_differences(blk, r, 0.0f, tmax, &first);
            const Watertight4::RayData d4 = Watertight4::prepare(r);
            alignas(16) float t[4], uu[4], vv[4];
            hits += std::popcount(Watertight4::intersect(d4, blk, 0.0f, tmax, t, uu, vv));
            lanes += 4;
        }
    }
    EXPECT_EQ(bad, 0u) << "of " << lanes << " lanes; first: " << first;
    EXPECT_GT(hits, lanes / 20) << "the rays must hit often enough to test t, u, v";
}

TEST(Triangle4, DegenerateNaNAndNeedleLanesNeverHitUnlessTheScalarDoes) {
    const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
    TriangleBlock4 blk;
    blk.set(0, vec3(0, 0, 0), vec3(1, 0, 0), vec3(2, 0, 0), 0);            // zero area (collinear)
    blk.set(1, vec3(0, 0, 0), vec3(nan, 0, 0), vec3(0, 1, 0), 1);          // NaN vertex
    blk.set(2, vec3(0, 0, 0), vec3(inf, 1, 0), vec3(0, 1, 0), 2);          // infinite vertex
    blk.set(3, vec3(-1, -1e-7f, 0), vec3(1, 0, 0), vec3(-1, 1e-7f, 0), 3);  // needle
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::size_t bad = 0, needle_hits = 0;
    std::string first;
    for (int k = 0; k < 20000; ++k) {
        const vec3 target(U(rng), U(rng) * 1e-7f, 0.0f);
        const Ray r{vec3(U(rng), U(rng), 2.0f + U(rng)), 0.0f, target - vec3(0.0f), kInf};
        Ray aimed = r;
        aimed.dir = target - r.org;
        bad += lane_differences(blk, aimed, 0.0f, kInf, &first);
        const Watertight4::RayData d4 = Watertight4::prepare(aimed);
        alignas(16) float t[4], u[4], v[4];
        const unsigned m = Watertight4::intersect(d4, blk, 0.0f, kInf, t, u, v);
        EXPECT_EQ(m & 7u, 0u) << "degenerate, NaN or infinite lane hit";
        needle_hits += (m >> 3) & 1u;
    }
    EXPECT_EQ(bad, 0u) << first;
    EXPECT_GT(needle_hits, 0u) << "rays aimed along the needle must hit it sometimes";
}

TEST(BlockBvh, BuiltForBlocksFillsThemAndMatchesBruteForce) {
    // Trees built with leaf_block 4 (every builder) and traced through blocks:
    // valid, bit-identical to the binary tree's answers, == brute force, and
    // fuller blocks than a tree built for one-at-a-time tests.
    const Mesh m = make_bumpy_torus(20000);
    const std::vector<Ray> rays = raykit::test::random_rays(m, 3000, 11);
    const PrimitiveRefs refs = primitive_refs(m);
    for (auto builder : {BuildOptions::Builder::sah, BuildOptions::Builder::pairwise, BuildOptions::Builder::sortaxis,
                         BuildOptions::Builder::ploc}) {
        SCOPED_TRACE(BuildOptions::name(builder));
        BuildOptions plain;
        plain.builder = builder;
        BuildOptions blocky = plain;
        blocky.leaf.leaf_block = 4;
        blocky.leaf.max_leaf_size = 12;
        const Bvh a = build_bvh(refs.boxes, refs.centers, plain);
        const Bvh b = build_bvh(refs.boxes, refs.centers, blocky);
        EXPECT_EQ(validate(b, refs.boxes), "");
        const BlockBvh8 ba = BlockBvh8::build(m, a), bb = BlockBvh8::build(m, b);
        const double fill_a = double(m.triangle_count()) / (4.0 * double(ba.blocks.size()));
        const double fill_b = double(m.triangle_count()) / (4.0 * double(bb.blocks.size()));
        std::printf("[ info ] %s: block fill %.3f (leaf_block 1, max leaf 8) -> %.3f (leaf_block 4, max leaf 12); "
                    "wide nodes %zu -> %zu\n",
                    BuildOptions::name(builder), fill_a, fill_b, ba.tree.nodes.size(), bb.tree.nodes.size());
        EXPECT_GT(fill_b, fill_a + 0.1);
        EXPECT_LT(bb.tree.nodes.size(), ba.tree.nodes.size());
        std::size_t bad = 0;
        for (const Ray& r : rays) {
            const Hit o = brute_force_closest(m, r);
            const Hit h = intersect_closest(bb, r);
            const Hit hb = intersect_closest(m, b, r);
            bad += h.prim != o.prim || h.t != o.t || h.u != hb.u || h.v != hb.v || h.prim != hb.prim ||
                   intersect_any(bb, r) != o.valid();
        }
        EXPECT_EQ(bad, 0u) << "of " << rays.size() << " rays";
    }
}

TEST(BlockBvh, BuildersRejectABadLeafBlock) {
    const Mesh m = make_random_soup(50, 1);
    const PrimitiveRefs refs = primitive_refs(m);
    for (auto builder : {BuildOptions::Builder::sah, BuildOptions::Builder::pairwise, BuildOptions::Builder::sortaxis,
                         BuildOptions::Builder::ploc}) {
        for (unsigned lb : {0u, 3u, 32u}) {
            BuildOptions o;
            o.builder = builder;
            o.leaf.leaf_block = lb;
            EXPECT_THROW(build_bvh(refs.boxes, refs.centers, o), std::invalid_argument)
                << BuildOptions::name(builder) << " leaf_block " << lb;
        }
    }
}

TEST(BlockBvh, EmptyTinyAndLeafRootTrees) {
    const Mesh empty;
    const BlockBvh8 e = BlockBvh8::build(empty, Bvh{});
    EXPECT_TRUE(e.empty());
    EXPECT_FALSE(intersect_closest(e, Ray{}).valid());
    EXPECT_FALSE(intersect_any(e, Ray{}));
    for (std::size_t n : {1u, 3u, 5u, 9u}) {
        const Mesh m = make_random_soup(n, 40 + n, 0.5f);
        BinnedSahBuilder::Config c;
        c.leaf.max_leaf_size = 16;  // small soups become one leaf: the root is a leaf of n triangles
        c.leaf.leaf_block = 4;
        const Bvh bvh = build_bvh<BinnedSahBuilder>(m, c);
        const BlockBvh8 b = BlockBvh8::build(m, bvh);
        const BlockBvh2 b2 = BlockBvh2::build(m, bvh);
        std::size_t bad = 0;
        for (const Ray& r : raykit::test::random_rays(m, 500, n)) {
            const Hit o = brute_force_closest(m, r);
            const Hit h = intersect_closest(b, r), h2 = intersect_closest(b2, r);
            bad += h.prim != o.prim || h.t != o.t || h2.prim != o.prim || h2.t != o.t ||
                   intersect_any(b, r) != o.valid() || intersect_any(b2, r) != o.valid();
        }
        EXPECT_EQ(bad, 0u) << n << " triangles";
    }
}

TEST(BlockBvh, MakeRejectsATreeThatDoesNotFitTheMesh) {
    const Mesh m = make_random_soup(20, 2);
    Bvh bvh = build_bvh<BinnedSahBuilder>(m, BinnedSahBuilder::Config{});
    Bvh bad_id = bvh;
    bad_id.prim_ids[0] = 1000;
    EXPECT_THROW(BlockBvh8::build(m, bad_id), std::invalid_argument);
    Bvh bad_range = bvh;
    for (Node& n : bad_range.nodes)
        if (n.is_leaf()) n.count = 1000;
    EXPECT_THROW(BlockBvh2::build(m, bad_range), std::invalid_argument);
}

TEST(BlockBvh, RealMeshesMatchBruteForce) {
    const std::filesystem::path bunny =
        std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / "obj" / "stanford_bunny" / "stanford-bunny.obj";
    if (!std::filesystem::exists(bunny)) GTEST_SKIP() << bunny << " not present";
    const Mesh m = load_obj(bunny);
    BuildOptions o;
    o.leaf.leaf_block = 4;
    o.leaf.max_leaf_size = 12;
    const BlockBvh8 b = BlockBvh8::build(m, build_bvh(MeshView(m), o));
    std::size_t bad = 0;
    const std::vector<Ray> rays = raykit::test::random_rays(m, 400, 5);
    for (const Ray& r : rays) {
        const Hit o2 = brute_force_closest(m, r);
        const Hit h = intersect_closest(b, r);
        bad += h.prim != o2.prim || h.t != o2.t || intersect_any(b, r) != o2.valid();
    }
    EXPECT_EQ(bad, 0u) << "of " << rays.size();
}

TEST(BlockBvh, BuildAndMakeRejectVerticesBeyondTheCoordinateBound) {
    Mesh m = make_random_soup(40, 4);
    m.positions[7].x = -2e19f;
    const auto says = [](const std::domain_error& e, const char* who) {
        const std::string w = e.what();
        EXPECT_NE(w.find(who), std::string::npos) << w;
        EXPECT_NE(w.find("vertex 7 coordinate x = -2e+19"), std::string::npos) << w;
        EXPECT_NE(w.find("2^32"), std::string::npos) << w;
    };
    try {
        (void)BlockBvh8::build(m);
        ADD_FAILURE() << "BlockBvh8::build accepted a vertex at -2e19";
    } catch (const std::domain_error& e) {
        says(e, "raykit: mesh");
    }
    // a tree built without primitive_refs (boxes from elsewhere): build(mesh, tree) checks on its own
    std::vector<AABB> boxes(m.triangles.size(), AABB{vec3(0.0f), vec3(1.0f)});
    std::vector<vec3> centers(m.triangles.size(), vec3(0.5f));
    const Bvh bvh = BinnedSahBuilder::build(boxes, centers, BinnedSahBuilder::Config{});
    for (int w : {2, 8}) {
        try {
            if (w == 2) (void)BlockBvh2::build(m, bvh);
            else (void)BlockBvh8::build(m, bvh);
            ADD_FAILURE() << "BlockBvh build(mesh, tree) accepted a vertex at -2e19, width " << w;
        } catch (const std::domain_error& e) {
            says(e, "BlockBvh::build");
        }
    }
    m.positions[7].x = -kMaxCoordinate;  // the bound itself is inside
    EXPECT_NO_THROW((void)BlockBvh8::build(m));
}

// ---------------------------------------------------------------- batches: packets of rays

namespace {

/// Differences between batch answers and single-ray answers (prim, inst, t, u, v bit for bit;
/// any-hit flag), printing the first.
std::size_t batch_differences(const std::vector<Hit>& batch, const std::vector<std::uint8_t>& any,
                              const std::vector<Hit>& single, const std::vector<bool>& single_any) {
    std::size_t bad = 0;
    for (std::size_t i = 0; i < single.size(); ++i) {
        const Hit &a = batch[i], &b = single[i];
        const bool diff = a.prim != b.prim || a.inst != b.inst || !same_bits(a.t, b.t) || !same_bits(a.u, b.u) ||
                          !same_bits(a.v, b.v) || bool(any[i]) != single_any[i];
        if (diff && bad++ == 0)
            std::printf("[ info ] first difference, ray %zu: batch prim %u t %a, single prim %u t %a; any %d / %d\n", i,
                        a.prim, double(a.t), b.prim, double(b.t), int(any[i]), int(single_any[i]));
    }
    return bad;
}

}  // namespace

TEST(Batch, BlockTreePacketsEqualSingleRaysBitForBit) {
    const Mesh m = make_bumpy_torus(20000);
    const BlockBvh8 b = BlockBvh8::build(m);
    const BlockBvh blocks4 = BlockBvh::build(m, build_bvh(MeshView(m), BuildOptions{}));
    const std::vector<Ray> rays = raykit::test::packet_test_rays(m, 3001, 21);
    std::vector<Hit> single(rays.size());
    std::vector<bool> single_any(rays.size());
    std::size_t hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        single[i] = intersect_closest(b, rays[i]);
        single_any[i] = intersect_any(b, rays[i]);
        hits += single[i].valid();
        // the single-ray answer is brute force's (so the batch is too)
        const Hit o = brute_force_closest(m, rays[i]);
        ASSERT_TRUE(o.prim == single[i].prim && same_bits(o.t, single[i].t)) << "ray " << i;
    }
    for (unsigned threads : {1u, 2u}) {
        SCOPED_TRACE(threads);
        std::vector<Hit> batch(rays.size());
        std::vector<std::uint8_t> any(rays.size());
        intersect_closest(b, rays, batch, threads);
        intersect_any(b, rays, any, threads);
        EXPECT_EQ(batch_differences(batch, any, single, single_any), 0u) << "of " << rays.size();
        // 4-wide nodes walk as packets too
        intersect_closest(blocks4, rays, batch, threads);
        intersect_any(blocks4, rays, any, threads);
        EXPECT_EQ(batch_differences(batch, any, single, single_any), 0u) << "4-wide, of " << rays.size();
    }
    EXPECT_GT(hits, rays.size() / 4);
    std::printf("[ info ] %zu rays (%zu hit), packets of %d\n", rays.size(), hits, kPacketWidth);
}

TEST(Batch, LeafFilterAppliesToEveryLane) {
    const Mesh m = make_bumpy_torus(8000);
    const BlockBvh8 b = BlockBvh8::build(m);
    const auto keep = [](std::uint32_t p, float u, float) { return p % 3 != 0 && u < 0.8f; };
    const std::vector<Ray> rays = raykit::test::batch_test_rays(m, 1500, 4);
    std::vector<Hit> batch(rays.size());
    std::vector<std::uint8_t> any(rays.size());
    intersect_closest(b, rays, batch, 1, keep);
    intersect_any(b, rays, any, 1, keep);
    std::vector<Hit> single(rays.size());
    std::vector<bool> single_any(rays.size());
    std::size_t filtered = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        single[i] = intersect_closest(b, rays[i], nullptr, keep);
        single_any[i] = intersect_any(b, rays[i], nullptr, keep);
        filtered += single[i].prim != intersect_closest(b, rays[i]).prim;
    }
    EXPECT_GT(filtered, rays.size() / 20);  // the filter changed answers, and the batch followed
    EXPECT_EQ(batch_differences(batch, any, single, single_any), 0u) << "of " << rays.size();
}

TEST(Batch, SceneBatchesEqualSingleRays) {
    // one-leaf top levels (packets through identity and transformed instances, rotations past
    // pi) and a top level with a walk (ray by ray)
    for (int instances : {1, 3, 7}) {
        SCOPED_TRACE(instances);
        Scene s;
        const std::uint32_t torus = s.add_object(make_bumpy_torus(6000));
        const std::uint32_t ball = s.add_object(make_icosphere(3));
        s.add_instance(torus);
        for (int k = 1; k < instances; ++k) {
            mat4 t = glm::translate(mat4(1.0f), vec3(1.5f * float(k), 0.3f * float(k), -0.5f));
            t = glm::rotate(t, 1.3f * float(k) + 2.0f, glm::normalize(vec3(1.0f, float(k), 0.5f)));
            s.add_instance(k % 2 ? ball : torus, glm::scale(t, vec3(0.4f + 0.2f * float(k))));
        }
        s.update_top_level();
        const auto [w, origin] = s.world_mesh();
        const std::vector<Ray> rays = raykit::test::batch_test_rays(w, 2000, 8 + std::uint64_t(instances));
        std::vector<Hit> batch(rays.size()), single(rays.size());
        std::vector<std::uint8_t> any(rays.size());
        std::vector<bool> single_any(rays.size());
        s.intersect_closest(rays, batch);
        s.intersect_any(rays, any);
        std::size_t hits = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            single[i] = s.intersect_closest(rays[i]);
            single_any[i] = s.intersect_any(rays[i]);
            hits += single[i].valid();
        }
        EXPECT_EQ(batch_differences(batch, any, single, single_any), 0u) << "of " << rays.size();
        EXPECT_GT(hits, rays.size() / 5);
    }
}

TEST(Batch, ShortResultSpansAreRefused) {
    const Mesh m = make_icosphere(1);
    const BlockBvh8 b = BlockBvh8::build(m);
    const std::vector<Ray> rays(10);
    std::vector<Hit> hits(9);
    std::vector<std::uint8_t> any(9);
    EXPECT_THROW(intersect_closest(b, rays, hits), std::invalid_argument);
    EXPECT_THROW(intersect_any(b, rays, any), std::invalid_argument);
    Scene s;
    s.add_instance(s.add_object(make_icosphere(1)));
    s.update_top_level();
    EXPECT_THROW(s.intersect_closest(rays, hits), std::invalid_argument);
    // empty batches are fine
    intersect_closest(b, std::span<const Ray>{}, std::span<Hit>{});
    s.intersect_any(std::span<const Ray>{}, std::span<std::uint8_t>{});
}
