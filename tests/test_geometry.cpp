// Slab test, triangle tests, robust offset, SAH cost: hand-computed oracles.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "raykit.hpp"

using namespace raykit;

namespace {

bool slab(const AABB& b, const Ray& r, float* t = nullptr) {
    float te;
    const bool hit = slab_test(b, r, RayInv(r.dir), te);
    if (t) *t = te;
    return hit;
}

Ray make_ray(vec3 o, vec3 d, float tmin = 0.0f, float tmax = kInf) { return Ray{o, tmin, d, tmax}; }

}  // namespace

TEST(Slab, HitsAndMissesAlongEachAxisWithSignedZeros) {
    const AABB box{vec3(-1.0f), vec3(1.0f)};
    for (int axis = 0; axis < 3; ++axis)
        for (float s : {1.0f, -1.0f})
            for (float z : {0.0f, -0.0f}) {
                vec3 d(z), o(0.5f);
                d[axis] = s;
                o[axis] = -5.0f * s;
                float t = 0.0f;
                EXPECT_TRUE(slab(box, make_ray(o, d), &t)) << "axis " << axis << " sign " << s << " zero " << z;
                EXPECT_FLOAT_EQ(t, 4.0f);
                vec3 off = o;
                off[(axis + 1) % 3] = 1.5f;  // outside on another axis, parallel ray
                EXPECT_FALSE(slab(box, make_ray(off, d))) << "axis " << axis;
            }
}

TEST(Slab, OriginOnTheBoundaryPlaneWithZeroComponentCountsAsInside) {
    // (bmin - o) * (1/±0) is NaN here; it must not decide the test.
    const AABB box{vec3(0.0f), vec3(1.0f)};
    for (float z : {0.0f, -0.0f}) {
        EXPECT_TRUE(slab(box, make_ray({0.0f, 0.5f, -1.0f}, {z, 0.0f, 1.0f}))) << z;
        EXPECT_TRUE(slab(box, make_ray({1.0f, 1.0f, -1.0f}, {z, z, 1.0f}))) << z;
        EXPECT_FALSE(slab(box, make_ray({1.0f + 1e-6f, 0.5f, -1.0f}, {z, 0.0f, 1.0f}))) << z;
    }
}

TEST(Slab, TinyAndDenormalDirectionsBehaveLikeZero) {
    const AABB box{vec3(-1.0f), vec3(1.0f)};
    for (float tiny : {1e-30f, -1e-30f, std::numeric_limits<float>::denorm_min(), 1e-45f}) {
        EXPECT_TRUE(slab(box, make_ray({0.0f, 0.0f, -3.0f}, {tiny, tiny, 1.0f}))) << tiny;
        EXPECT_FALSE(slab(box, make_ray({2.0f, 0.0f, -3.0f}, {tiny, tiny, 1.0f}))) << tiny;
    }
}

TEST(Slab, RespectsTminTmaxAndEmptyBoxes) {
    const AABB box{vec3(-1.0f), vec3(1.0f)};
    EXPECT_FALSE(slab(box, make_ray({0, 0, -5}, {0, 0, 1}, 0.0f, 3.9f)));
    EXPECT_TRUE(slab(box, make_ray({0, 0, -5}, {0, 0, 1}, 0.0f, 4.0f)));
    EXPECT_FALSE(slab(box, make_ray({0, 0, -5}, {0, 0, 1}, 6.1f, kInf)));
    EXPECT_FALSE(slab(AABB{}, make_ray({0, 0, -5}, {0, 0, 1})));
}

TEST(Slab, NeverMissesABoxThatContainsAHitTriangle) {
    // Boxes of random far-away triangles; rays through their centroids.
    std::mt19937 rng(7);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    int misses = 0;
    for (int i = 0; i < 20000; ++i) {
        const vec3 c = vec3(U(rng), U(rng), U(rng)) * 1e6f;
        const vec3 p0 = c + vec3(U(rng), U(rng), U(rng)), p1 = c + vec3(U(rng), U(rng), U(rng)),
                   p2 = c + vec3(U(rng), U(rng), U(rng));
        AABB b;
        b.grow(p0), b.grow(p1), b.grow(p2);
        const vec3 o = vec3(U(rng), U(rng), U(rng)) * 10.0f;
        const Ray r = make_ray(o, (p0 + p1 + p2) / 3.0f - o);
        TriHit th;
        if (Watertight::intersect(Watertight::prepare(r), p0, p1, p2, 0.0f, kInf, th) && !slab(b, r)) ++misses;
    }
    EXPECT_EQ(misses, 0);
}

template <class T>
class TriangleTests : public ::testing::Test {};
using AllTests = ::testing::Types<Watertight, MollerTrumbore, ThesisTest>;
TYPED_TEST_SUITE(TriangleTests, AllTests);

TYPED_TEST(TriangleTests, HitsInteriorWithCorrectTAndBarycentrics) {
    const vec3 p0(0, 0, 0), p1(2, 0, 0), p2(0, 2, 0);
    const Ray r = make_ray({0.5f, 0.25f, 3.0f}, {0, 0, -1});
    TriHit h;
    ASSERT_TRUE(TypeParam::intersect(TypeParam::prepare(r), p0, p1, p2, 0.0f, kInf, h));
    EXPECT_NEAR(h.t, 3.0f, 1e-6f);
    EXPECT_NEAR(h.u, 0.25f, 1e-6f);   // weight of p1 = x/2
    EXPECT_NEAR(h.v, 0.125f, 1e-6f);  // weight of p2 = y/2
    EXPECT_FALSE(TypeParam::intersect(TypeParam::prepare(r), p0, p1, p2, 0.0f, 2.9f, h));
    EXPECT_FALSE(TypeParam::intersect(TypeParam::prepare(make_ray({1.5f, 1.5f, 3.0f}, {0, 0, -1})), p0, p1, p2,
                                      0.0f, kInf, h));
    // back side hits too (no culling)
    EXPECT_TRUE(TypeParam::intersect(TypeParam::prepare(make_ray({0.5f, 0.25f, -3.0f}, {0, 0, 1})), p0, p1, p2,
                                     0.0f, kInf, h));
}

TYPED_TEST(TriangleTests, DegenerateAndNanTrianglesNeverHit) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const Ray r = make_ray({0.1f, 0.1f, 3.0f}, {0, 0, -1});
    const auto rd = TypeParam::prepare(r);
    TriHit h;
    EXPECT_FALSE(TypeParam::intersect(rd, {0, 0, 0}, {1, 1, 0}, {2, 2, 0}, 0.0f, kInf, h));  // collinear
    EXPECT_FALSE(TypeParam::intersect(rd, {0, 0, 0}, {0, 0, 0}, {0, 0, 0}, 0.0f, kInf, h));  // point
    EXPECT_FALSE(TypeParam::intersect(rd, {0, 0, 0}, {nan, 0, 0}, {0, 1, 0}, 0.0f, kInf, h));
    EXPECT_FALSE(TypeParam::intersect(rd, {0, 0, 0}, {kInf, 0, 0}, {0, 1, 0}, 0.0f, kInf, h));
    // a ray in the triangle's plane
    EXPECT_FALSE(TypeParam::intersect(TypeParam::prepare(make_ray({-1, 0.1f, 0}, {1, 0, 0})), {0, 0, 0},
                                      {1, 0, 0}, {0, 1, 0}, 0.0f, kInf, h));
}

TYPED_TEST(TriangleTests, CollinearTrianglesNeverHitFromAnyDirection) {
    // Rays through points of a zero-area triangle's line, from random directions, near
    // and far from the origin: rounding in a test's ray-dependent determinant must not
    // turn the line into a hit (the watertight test did before it checked the edges'
    // cross product).
    std::mt19937_64 rng(17);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::size_t hits = 0, n = 0;
    for (float offset : {0.0f, 1e3f}) {
        for (int k = 0; k < 20000; ++k) {
            const vec3 base = vec3(offset, -offset, 0.5f * offset) + vec3(U(rng), U(rng), U(rng));
            const vec3 step = vec3(U(rng), U(rng), U(rng));
            // exactly collinear in float: p0, p0 + s, p0 + 2s with s a power-of-two multiple
            // of an exactly representable step
            const vec3 s = k % 2 ? vec3(0.5f, 0.25f, 0.0f) : vec3(0.25f, 0.5f, 1.0f);
            const vec3 p0 = base, p1 = base + s, p2 = base + 2.0f * s;
            if (!(Watertight::degenerate(p0, p1, p2))) continue;  // rounding made them non-collinear
            const vec3 target = p0 + s * (0.5f * (U(rng) + 1.0f));
            const vec3 o = target + step * 3.0f;
            TriHit h;
            hits += TypeParam::intersect(TypeParam::prepare(make_ray(o, target - o)), p0, p1, p2, 0.0f, kInf, h);
            ++n;
        }
    }
    EXPECT_GT(n, 20000u);
    EXPECT_EQ(hits, 0u) << "of " << n << " rays through collinear triangles";
}

TEST(Watertight, SharedEdgeAndVertexOfAQuadAreNeverMissed) {
    // Two triangles sharing the diagonal of a quad; rays at points exactly on it.
    const vec3 a(0, 0, 0), b(1, 0, 0), c(1, 1, 0), d(0, 1, 0);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    int misses = 0, both = 0, miss_mt = 0, miss_th = 0;
    for (int i = 0; i < 100000; ++i) {
        const float s = U(rng);
        const vec3 target(s, s, 0.0f);  // on the shared edge a-c
        const vec3 o(U(rng) * 4 - 2, U(rng) * 4 - 2, 1.0f + U(rng) * 3);
        const Ray r = make_ray(o, target - o);
        const auto rd = Watertight::prepare(r);
        TriHit h;
        const bool h1 = Watertight::intersect(rd, a, b, c, 0.0f, kInf, h);
        const bool h2 = Watertight::intersect(rd, a, c, d, 0.0f, kInf, h);
        misses += !(h1 || h2);
        both += h1 && h2;
        const auto md = MollerTrumbore::prepare(r);
        miss_mt += !(MollerTrumbore::intersect(md, a, b, c, 0.0f, kInf, h) ||
                     MollerTrumbore::intersect(md, a, c, d, 0.0f, kInf, h));
        const auto td = ThesisTest::prepare(r);
        miss_th += !(ThesisTest::intersect(td, a, b, c, 0.0f, kInf, h) || ThesisTest::intersect(td, a, c, d, 0.0f, kInf, h));
    }
    EXPECT_EQ(misses, 0);
    std::printf("[ info ] shared-edge rays (100000): watertight %d misses (%d hit both), moller-trumbore %d "
                "misses, thesis %d misses\n",
                misses, both, miss_mt, miss_th);
}

TEST(Offset, SecondaryRayDoesNotHitItsOwnTriangle) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f), W(0.0f, 1.0f);
    int self = 0, total = 0;
    for (float scale : {1.0f, 1e3f, 1e6f})
        for (int i = 0; i < 5000; ++i) {
            const vec3 c = vec3(U(rng), U(rng), U(rng)) * scale;
            const vec3 p0 = c + vec3(U(rng), U(rng), U(rng)), p1 = c + vec3(U(rng), U(rng), U(rng)),
                       p2 = c + vec3(U(rng), U(rng), U(rng));
            vec3 n = glm::cross(p1 - p0, p2 - p0);
            if (glm::length(n) < 1e-3f) continue;
            n = glm::normalize(n);
            float bu = W(rng), bv = W(rng);
            if (bu + bv > 1.0f) bu = 1.0f - bu, bv = 1.0f - bv;
            const vec3 p = p0 * (1.0f - bu - bv) + p1 * bu + p2 * bv;
            const vec3 o = offset_ray_origin(p, n);
            const vec3 dir = glm::normalize(n + vec3(U(rng), U(rng), U(rng)) * 0.9f);
            if (glm::dot(dir, n) <= 0.05f) continue;
            TriHit h;
            ++total;
            self += Watertight::intersect(Watertight::prepare(make_ray(o, dir)), p0, p1, p2, 0.0f, kInf, h);
        }
    EXPECT_GT(total, 10000);
    EXPECT_EQ(self, 0);
}

TEST(SahCost, MatchesAHandComputedTree) {
    // root [0,2]^3 (area 24); children [0,1]^3 (area 6, 2 prims) and [1,2]x[0,2]^2 (area 16, 1 prim)
    Bvh bvh;
    bvh.nodes.resize(3);
    bvh.nodes[0] = Node{AABB{vec3(0), vec3(2)}, 1, 0};
    bvh.nodes[1] = Node{AABB{vec3(0), vec3(1)}, 0, 2};
    bvh.nodes[2] = Node{AABB{vec3(1, 0, 0), vec3(2)}, 2, 1};
    bvh.prim_ids = {0, 1, 2};
    EXPECT_NEAR(sah_cost(bvh), 1.0 + 6.0 / 24.0 * 2 + 16.0 / 24.0 * 1, 1e-9);
}

TEST(Slab, SimdPathsEqualTheScalarTest) {
    // SlabRay::test / test_pair (SSE4.1 / AVX when compiled in) against the
    // scalar slab_test on random boxes, including zero and NaN-producing cases.
    std::mt19937 rng(17);
    std::uniform_real_distribution<float> U(-2.0f, 2.0f);
    std::uniform_int_distribution<int> pick(0, 5);
    auto comp = [&]() {
        switch (pick(rng)) {
            case 0: return 0.0f;
            case 1: return -0.0f;
            case 2: return 1e-30f;
            default: return U(rng);
        }
    };
    std::size_t disagreements = 0;
    for (int i = 0; i < 200000; ++i) {
        Node pair[2];
        for (Node& n : pair) {
            vec3 a(std::round(U(rng)), U(rng), U(rng)), b(U(rng), std::round(U(rng)), U(rng));
            n.box = {glm::min(a, b), glm::max(a, b)};
            n.index = 12345;  // an integer behind max.z, as in a real node
            n.count = static_cast<std::uint32_t>(i & 7);
        }
        const vec3 o(std::round(U(rng)), std::round(U(rng)), U(rng));
        const Ray r{o, 0.0f, vec3(comp(), comp(), comp()), i % 3 ? kInf : 2.0f};
        if (r.dir == vec3(0.0f)) continue;
        const SlabRay sr(r);
        const RayInv ri(r.dir);
        float ts[2], tv[2];
        bool hs[2];
        for (int k = 0; k < 2; ++k)
            hs[k] = slab_test(&pair[k].box.min.x, &pair[k].box.max.x, r.org, ri, r.tmin, r.tmax, ts[k]);
        const unsigned m = sr.test_pair(pair[0].box, pair[1].box, r.tmin, r.tmax, tv[0], tv[1]);
        for (int k = 0; k < 2; ++k) {
            float t1;
            const bool h1 = sr.test(pair[k].box, r.tmin, r.tmax, t1);
            const bool h2 = (m >> k) & 1u;
            if (h1 != hs[k] || h2 != hs[k] || (hs[k] && (t1 != ts[k] || tv[k] != ts[k]))) ++disagreements;
        }
    }
    EXPECT_EQ(disagreements, 0u);
}
