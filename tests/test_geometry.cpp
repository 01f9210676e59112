// Slab test, triangle tests, robust offset, SAH cost: hand-computed oracles.
#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cstdint>
#include <cstdio>
#include <cmath>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "raykit.hpp"
#include "raykit/math/limits.hpp"

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

// ---------------------------------------------------------------- coordinate range (math/limits.hpp)

namespace {

/// Wrong answers of each test (Watertight, MollerTrumbore, ThesisTest,
/// Watertight4) against an oracle in long double computed from the same
/// float inputs: hit/miss, and t within 1e-3 relative.
struct RangeTally {
    std::size_t rays = 0;
    std::size_t wrong[4] = {};
};

/// Möller–Trumbore in long double (64-bit significand, range to 1e4932):
/// 1 = hit (every barycentric weight >= 0.05, t > 0), 0 = miss (a weight
/// <= -0.05 or t <= 0), -1 = too close to an edge or grazing to judge.
int oracle_hit(const Ray& r, const vec3 (&p)[3], long double& t) {
    using LD = long double;
    LD e1[3], e2[3], s[3], d[3];
    for (int a = 0; a < 3; ++a) {
        e1[a] = LD(p[1][a]) - LD(p[0][a]);
        e2[a] = LD(p[2][a]) - LD(p[0][a]);
        s[a] = LD(r.org[a]) - LD(p[0][a]);
        d[a] = r.dir[a];
    }
    const auto cross = [](const LD* x, const LD* y, LD* o) {
        o[0] = x[1] * y[2] - x[2] * y[1];
        o[1] = x[2] * y[0] - x[0] * y[2];
        o[2] = x[0] * y[1] - x[1] * y[0];
    };
    const auto dot = [](const LD* x, const LD* y) { return x[0] * y[0] + x[1] * y[1] + x[2] * y[2]; };
    LD n[3], pv[3], qv[3];
    cross(e1, e2, n);
    const LD cosine = std::fabs(dot(n, d)) / std::sqrt(dot(n, n) * dot(d, d));
    if (!(cosine >= 0.05L)) return -1;
    cross(d, e2, pv);
    const LD det = dot(e1, pv);
    cross(s, e1, qv);
    const LD u = dot(s, pv) / det, v = dot(d, qv) / det;
    t = dot(e2, qv) / det;
    const LD w = 1.0L - u - v, lo = std::min(u, std::min(v, w));
    if (t <= 0.0L || lo <= -0.05L) return 0;
    return lo >= 0.05L ? 1 : -1;
}

/// `n` seeded rays at magnitude M. layout 0: origin within 1 of 0, triangle
/// vertices ~M from it; 1: origin and vertices anywhere in [-M, M]^3, the
/// direction's largest component 2^k, k uniform in [-16, 16]; 2: origin at
/// ~M, a triangle of size 1e-3·M at distance ~1e-3·M. Half the rays aim
/// inside (weights >= 0.1), half outside (a weight <= -0.1).
RangeTally range_oracle(double M, int layout, int n, std::uint64_t seed, bool thesis) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<double> U(-1.0, 1.0), P(0.0, 1.0);
    std::uniform_int_distribution<int> K(-16, 16);
    RangeTally tally;
    for (int it = 0; it < n; ++it) {
        const double mo = layout == 0 ? 1.0 : M, mr = layout == 2 ? 1e-3 * M : M;
        vec3 o;
        for (int a = 0; a < 3; ++a) o[a] = static_cast<float>(mo * U(rng));
        vec3 p[3];
        double c[3];
        for (int a = 0; a < 3; ++a) c[a] = double(o[a]) + 1.5 * mr * U(rng);
        for (auto& q : p)
            for (int a = 0; a < 3; ++a)  // within [-M, M], as the rule asks
                q[a] = static_cast<float>(std::clamp(layout == 1 ? M * U(rng) : c[a] + 0.5 * mr * U(rng), -M, M));
        double b[3];
        const bool inside = it % 2 == 0;
        do {
            b[0] = inside ? P(rng) : 2.0 * U(rng);
            b[1] = inside ? P(rng) : 2.0 * U(rng);
            b[2] = 1.0 - b[0] - b[1];
        } while (inside ? std::min({b[0], b[1], b[2]}) < 0.1 : std::min({b[0], b[1], b[2]}) > -0.1);
        double dd[3], big = 0.0;
        for (int a = 0; a < 3; ++a) {
            dd[a] = b[0] * p[0][a] + b[1] * p[1][a] + b[2] * p[2][a] - double(o[a]);
            big = std::max(big, std::fabs(dd[a]));
        }
        const double scale = (layout == 1 ? std::ldexp(1.0, K(rng)) : 1.0) / big;
        const Ray r{o, 0.0f, vec3(dd[0] * scale, dd[1] * scale, dd[2] * scale), kInf};
        EXPECT_TRUE(ray_in_range(r)) << ray_range_error(r);  // the rule is what is tested
        for (const vec3& q : p)
            for (int a = 0; a < 3; ++a) EXPECT_TRUE(coordinate_in_range(q[a])) << q[a];
        long double t_true = 0.0L;
        const int expect = oracle_hit(r, p, t_true);
        if (expect < 0) continue;
        ++tally.rays;
        TriHit h[4]{};
        bool got[4];
        got[0] = Watertight::intersect(Watertight::prepare(r), p[0], p[1], p[2], r.tmin, r.tmax, h[0]);
        got[1] = MollerTrumbore::intersect(MollerTrumbore::prepare(r), p[0], p[1], p[2], r.tmin, r.tmax, h[1]);
        got[2] = ThesisTest::intersect(ThesisTest::prepare(r), p[0], p[1], p[2], r.tmin, r.tmax, h[2]);
        TriangleBlock4 blk;
        for (int l = 0; l < 4; ++l) blk.set(l, p[0], p[1], p[2], 0);
        alignas(16) float t4[4], u4[4], v4[4];
        got[3] = (Watertight4::intersect(Watertight4::prepare(r), blk, r.tmin, r.tmax, t4, u4, v4) & 1u) != 0;
        h[3].t = t4[0];
        for (int k = 0; k < 4; ++k) {
            if (k == 2 && !thesis) continue;
            // 1e-3: Möller–Trumbore's cancellation reaches 2e-4 on some judged
            // rays at every scale (seen without FMA); overflow and underflow
            // give inf, 0 or errors near 100%
            const bool bad = got[k] != (expect == 1) ||
                             (got[k] && !(std::fabs(static_cast<long double>(h[k].t) - t_true) <= 1e-3L * t_true));
            tally.wrong[k] += bad;
        }
    }
    return tally;
}

}  // namespace

TEST(CoordinateRange, EveryTriangleTestAgreesWithALongDoubleOracleUpToTheBound) {
    const char* const names[4] = {"Watertight", "MollerTrumbore", "ThesisTest", "Watertight4"};
    const double mags[] = {1.0, 1e3, 1e6, 1e9, double(kMaxCoordinate)};
    std::uint64_t seed = 2024;
    for (const double M : mags)
        for (int layout = 0; layout < 3; ++layout) {
            // ThesisTest's fixed tolerance (1e-7 length^2) is meant for
            // triangles of size >= ~1: layout 2 at M = 1 has size 1e-3
            const bool thesis = !(layout == 2 && M < 1e3);
            const RangeTally t = range_oracle(M, layout, 4000, ++seed, thesis);
            EXPECT_GT(t.rays, 3000u) << "the oracle judged too few rays at " << M;
            for (int k = 0; k < 4; ++k)
                EXPECT_EQ(t.wrong[k], 0u) << names[k] << " at magnitude " << M << ", layout " << layout << " (" << t.rays
                                          << " rays)";
        }
}

TEST(CoordinateRange, RaysOutsideTheRuleAreRejectedByName) {
    const Ray ok{vec3(kMaxCoordinate, -kMaxCoordinate, 0.0f), 0.0f, vec3(0.0f, kMinDirection, 0.0f), kInf};
    EXPECT_TRUE(ray_in_range(ok));
    EXPECT_NO_THROW(check_ray(ok));
    EXPECT_EQ(ray_range_error(ok), "");
    EXPECT_TRUE(ray_in_range(Ray{vec3(0.0f), 0.0f, vec3(-kMaxDirection, 1.0f, 0.0f), 1.0f}));
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const struct {
        Ray r;
        const char* says;
    } bad[] = {
        {{vec3(0.0f, 1e14f, 0.0f), 0.0f, vec3(0, 0, 1), kInf}, "origin y = 1e+14"},
        {{vec3(next_float_up(kMaxCoordinate), 0.0f, 0.0f), 0.0f, vec3(0, 0, 1), kInf}, "origin x = 4.29496781e+09"},
        {{vec3(0.0f, 0.0f, -kInf), 0.0f, vec3(0, 0, 1), kInf}, "origin z = -inf"},
        {{vec3(nan, 0.0f, 0.0f), 0.0f, vec3(0, 0, 1), kInf}, "origin x = nan"},
        {{vec3(0.0f), 0.0f, vec3(0.0f), kInf}, "largest |component| 0"},
        {{vec3(0.0f), 0.0f, vec3(1e-20f, 0.0f, 0.0f), kInf}, "largest |component| 9.99999968e-21"},
        {{vec3(0.0f), 0.0f, vec3(0.0f, 0.0f, 3e38f), kInf}, "largest |component| 3.00000001e+38"},
        {{vec3(0.0f), 0.0f, vec3(0.0f, kInf, 1.0f), kInf}, "not finite"},
        {{vec3(0.0f), nan, vec3(0, 0, 1), kInf}, "NaN"},
        {{vec3(0.0f), 0.0f, vec3(0, 0, 1), nan}, "NaN"},
    };
    for (const auto& b : bad) {
        EXPECT_FALSE(ray_in_range(b.r)) << b.says;
        EXPECT_NE(ray_range_error(b.r).find(b.says), std::string::npos) << ray_range_error(b.r);
        try {
            check_ray(b.r);
            ADD_FAILURE() << "accepted: " << b.says;
        } catch (const std::domain_error& e) {
            EXPECT_NE(std::string(e.what()).find(b.says), std::string::npos) << e.what();
        }
    }
}

TEST(CoordinateRange, CheckPositionsDrawsTheLineAtTheBoundAndLetsNonFiniteThrough) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float up = next_float_up(kMaxCoordinate);
    std::vector<vec3> p = {{0.0f, -0.0f, 1e-45f}, {kMaxCoordinate, -kMaxCoordinate, nan}, {kInf, -kInf, -nan}};
    EXPECT_NO_THROW(check_positions(p, "test"));
    for (const float bad : {up, -up, 1e20f, -std::numeric_limits<float>::max()})
        for (int a = 0; a < 3; ++a) {
            std::vector<vec3> q = p;
            q.push_back(vec3(0.0f));
            q.back()[a] = bad;
            try {
                check_positions(q, "test");
                ADD_FAILURE() << "accepted " << bad;
            } catch (const std::domain_error& e) {
                const std::string w = e.what();
                EXPECT_EQ(w.rfind("test: vertex 3 coordinate ", 0), 0u) << w;
                EXPECT_NE(w.find(std::string(1, "xyz"[a]) + " = "), std::string::npos) << w;
            }
            EXPECT_EQ(coordinate_in_range(bad), false);
        }
}

namespace {

/// Watertight::intersect written out with a chosen rounding of its two multiply-adds
/// (volatile keeps the compiler from fusing the unfused forms): the oracle for the rounding
/// the library claims through RAYKIT_FMA, which the OpenCL device is told to copy.
bool watertight_rounded(const Ray& r, const vec3& p0, const vec3& p1, const vec3& p2, bool fuse, TriHit& out) {
    const Watertight::RayData d = Watertight::prepare(r);
    const vec3 A = p0 - d.org, B = p1 - d.org, C = p2 - d.org;
    auto msub = [&](float a, float s, float b) {
        if (fuse) return std::fma(-s, b, a);
        volatile float m = s * b;
        return a - m;
    };
    const float Ax = msub(A[d.kx], d.sx, A[d.kz]), Ay = msub(A[d.ky], d.sy, A[d.kz]);
    const float Bx = msub(B[d.kx], d.sx, B[d.kz]), By = msub(B[d.ky], d.sy, B[d.kz]);
    const float Cx = msub(C[d.kx], d.sx, C[d.kz]), Cy = msub(C[d.ky], d.sy, C[d.kz]);
    const double Ud = double(Cx) * double(By) - double(Cy) * double(Bx);
    const double Vd = double(Ax) * double(Cy) - double(Ay) * double(Cx);
    const double Wd = double(Bx) * double(Ay) - double(By) * double(Ax);
    if ((Ud < 0.0 || Vd < 0.0 || Wd < 0.0) && (Ud > 0.0 || Vd > 0.0 || Wd > 0.0)) return false;
    const double detd = Ud + Vd + Wd;
    if (!(detd != 0.0)) return false;
    const float U = float(Ud), V = float(Vd), W = float(Wd), det = float(detd);
    if (!(det != 0.0f)) return false;
    const float Az = d.sz * A[d.kz], Bz = d.sz * B[d.kz], Cz = d.sz * C[d.kz];
    float T;
    if (fuse) {
        T = std::fma(W, Cz, std::fma(U, Az, V * Bz));
    } else {
        volatile float a = U * Az, b = V * Bz, c = W * Cz;
        volatile float ab = a + b;
        T = ab + c;
    }
    const float inv = 1.0f / det;
    out = {T * inv, V * inv, W * inv};
    return true;
}

}  // namespace

// RAYKIT_FMA says whether Watertight fuses its two multiply-adds; the device copies that
// choice (cl/layout.hpp host_float_config) to return the CPU's t, u, v bit for bit. This checks
// the claim against both roundings written out, on rays where the two differ.
TEST(Watertight, RoundsAsRaykitFmaSays) {
    std::mt19937_64 rng(7);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    auto bits = [](float x) { return std::bit_cast<std::uint32_t>(x); };
    int decisive = 0, agree_claim = 0, agree_other = 0;
    for (int i = 0; i < 20000 && decisive < 200; ++i) {
        const vec3 c(U(rng), U(rng), U(rng));
        const vec3 p0 = c + vec3(U(rng), U(rng), U(rng)) * 0.3f, p1 = c + vec3(U(rng), U(rng), U(rng)) * 0.3f,
                   p2 = c + vec3(U(rng), U(rng), U(rng)) * 0.3f;
        const vec3 o(U(rng) * 3.0f, U(rng) * 3.0f, U(rng) * 3.0f);
        const Ray r{o, 0.0f, (p0 + p1 + p2) * (1.0f / 3.0f) - o + vec3(U(rng), U(rng), U(rng)) * 0.01f, kInf};
        TriHit lib{}, fused{}, plain{};
        const bool hl = Watertight::intersect(Watertight::prepare(r), p0, p1, p2, 0.0f, kInf, lib);
        const bool hf = watertight_rounded(r, p0, p1, p2, true, fused);
        const bool hp = watertight_rounded(r, p0, p1, p2, false, plain);
        auto same = [&](bool ha, const TriHit& a, bool hb, const TriHit& b) {
            return ha == hb && (!ha || (bits(a.t) == bits(b.t) && bits(a.u) == bits(b.u) && bits(a.v) == bits(b.v)));
        };
        if (same(hf, fused, hp, plain)) continue;  // both roundings agree: says nothing
        ++decisive;
        const bool claim = RAYKIT_FMA != 0;
        agree_claim += same(hl, lib, claim ? hf : hp, claim ? fused : plain);
        agree_other += same(hl, lib, claim ? hp : hf, claim ? plain : fused);
    }
    std::printf("[ info ] RAYKIT_FMA %d: %d rays where the roundings differ; library agrees with it on %d, "
                "with the other on %d\n",
                RAYKIT_FMA, decisive, agree_claim, agree_other);
    ASSERT_GT(decisive, 50);
    EXPECT_EQ(agree_claim, decisive);
    EXPECT_EQ(agree_other, 0);
}

// Mesh::bounds() against a box grown by hand over the vertices of the finite triangles: a
// triangle with a NaN or infinite vertex adds nothing (a tree never needs room for it), and
// a vertex no triangle uses adds nothing either.
TEST(Mesh, BoundsCoverTheFiniteTrianglesOnly) {
    std::mt19937 rng(1234);
    std::uniform_real_distribution<float> u(-100.0f, 100.0f);
    Mesh m;
    for (int i = 0; i < 60; ++i) m.positions.push_back({u(rng), u(rng), u(rng)});
    m.positions.push_back({1e6f, 0.0f, 0.0f});                                      // 60: unused
    m.positions.push_back({std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f});   // 61
    m.positions.push_back({0.0f, std::numeric_limits<float>::infinity(), 0.0f});    // 62
    for (std::uint32_t t = 0; t < 18; ++t) m.triangles.push_back({{3 * t, 3 * t + 1, 3 * t + 2}});
    m.triangles.push_back({{0, 61, 1}});
    m.triangles.push_back({{62, 2, 3}});
    vec3 lo(std::numeric_limits<float>::max()), hi(-std::numeric_limits<float>::max());
    for (std::uint32_t i = 0; i < 54; ++i) {
        lo = glm::min(lo, m.positions[i]);
        hi = glm::max(hi, m.positions[i]);
    }
    const AABB b = m.bounds();
    EXPECT_EQ(b.min, lo);
    EXPECT_EQ(b.max, hi);
    EXPECT_EQ(MeshView(m).bounds().min, lo);
    EXPECT_EQ(m.triangle_count(), MeshView(m).triangle_count());
    EXPECT_EQ(m.vertex_count(), MeshView(m).vertex_count());
    Mesh none;
    EXPECT_TRUE(none.bounds().is_empty());
}

// max_axis and Watertight::prepare pick axes without branches (random rays mispredicted the
// branches in a quarter of a ray's setup); their picks must stay those of the rule they replace,
// with its ties (x before y before z), signed zeros and NaNs (a NaN compares false), since the
// device kernels and the packet walks make the same picks from the same rule.
TEST(Watertight, AxisPicksFollowTheRuleOnTiesZerosAndNaNs) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    const float values[] = {-2.0f, -1.0f, -0.0f, 0.0f, 1.0f, 2.0f, nan, kInf};
    int checked = 0;
    for (float x : values)
        for (float y : values)
            for (float z : values) {
                const vec3 v(x, y, z);
                const int rule = v.x >= v.y ? (v.x >= v.z ? 0 : 2) : (v.y >= v.z ? 1 : 2);
                ASSERT_EQ(max_axis(v), rule) << x << " " << y << " " << z;
                const Ray r = make_ray(vec3(0.5f), v);
                const Watertight::RayData d = Watertight::prepare(r);
                const vec3 ad = glm::abs(v);
                const int kz = ad.x >= ad.y ? (ad.x >= ad.z ? 0 : 2) : (ad.y >= ad.z ? 1 : 2);
                int kx = kz == 2 ? 0 : kz + 1, ky = kx == 2 ? 0 : kx + 1;
                if (v[kz] < 0.0f) std::swap(kx, ky);
                ASSERT_EQ(d.kz, kz) << x << " " << y << " " << z;
                ASSERT_EQ(d.kx, kx) << x << " " << y << " " << z;
                ASSERT_EQ(d.ky, ky) << x << " " << y << " " << z;
                ++checked;
            }
    EXPECT_EQ(checked, 512);
}
