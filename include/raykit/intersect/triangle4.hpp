// raykit/intersect/triangle4.hpp — the watertight ray/triangle test on four triangles at once.
//
//   TriangleBlock4 blk;                            // 4 triangles, structure of arrays
//   blk.set(lane, p0, p1, p2, prim);
//   const Watertight4::RayData rd = Watertight4::prepare(ray);
//   alignas(16) float t[4], u[4], v[4];
//   unsigned hits = Watertight4::intersect(rd, blk, tmin, tmax, t, u, v);  // bit per lane
//
// The same operations as Watertight::intersect (intersect/triangle.hpp), lane
// by lane: the vertices shifted by the ray origin and sheared, the three 2-D
// edge functions in double (products of floats are exact in double, so each
// is rounded once), the sign test, the determinant, then t, u, v in float
// with the same explicit multiply-add fusion (Watertight::msub/tnum). So every
// lane returns the scalar test's answer bit for bit — hit or miss, t, u, v —
// and a mesh traced through blocks stays watertight (tested against the
// scalar test on random, edge and vertex rays in tests/test_blocks.cpp).
//
// Being the scalar test, it shares its coordinate range (math/limits.hpp).
//
// With AVX and FMA the edge functions take one 4-lane double operation each; without
// them (or with RAYKIT_NO_SIMD) the lanes run through the scalar test. Watertight4 is
// compiled once per instruction-set level: the part of this header below
// RAYKIT_ISA_PASS is its per-level part (scene/trace_level.inc includes it per level;
// raykit::Watertight4 is the base level's, scene/trace.hpp).
//
// A block is 160 bytes: 9 planes of 4 floats (corner c, axis a at p[3c + a])
// and the 4 triangle indices. Blocks hold copies of vertices: they are made
// for tracing (scene/block_bvh.hpp) and must be remade after vertices move.
// Unused lanes repeat a used lane (same triangle, same index), which changes
// no answer.
#ifndef RAYKIT_INTERSECT_TRIANGLE4_HPP
#define RAYKIT_INTERSECT_TRIANGLE4_HPP

#include <bit>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "raykit/intersect/triangle.hpp"
#include "raykit/simd/isa.hpp"

namespace raykit {

struct alignas(32) TriangleBlock4 {
    float p[9][4];             ///< p[3 * corner + axis][lane]
    std::uint32_t prim[4];     ///< triangle index of each lane

    void set(int lane, const vec3& a, const vec3& b, const vec3& c, std::uint32_t id) noexcept {
        const vec3* v[3] = {&a, &b, &c};
        for (int k = 0; k < 3; ++k)
            for (int ax = 0; ax < 3; ++ax) p[3 * k + ax][lane] = (*v[k])[ax];
        prim[lane] = id;
    }
    vec3 corner(int lane, int k) const noexcept { return {p[3 * k][lane], p[3 * k + 1][lane], p[3 * k + 2][lane]}; }
};
static_assert(sizeof(TriangleBlock4) == 160 && alignof(TriangleBlock4) == 32);
static_assert(std::is_standard_layout_v<TriangleBlock4>);
static_assert(offsetof(TriangleBlock4, p) == 0 && offsetof(TriangleBlock4, prim) == 144);

}  // namespace raykit

#endif  // RAYKIT_INTERSECT_TRIANGLE4_HPP

#ifdef RAYKIT_ISA_PASS
namespace raykit::RAYKIT_ISA_NS {

struct Watertight4 {
    struct RayData {
        Watertight::RayData s;
        int ox, oy, oz;  ///< float offsets of the kx, ky, kz planes of corner 0 in a block
#if RAYKIT_ISA_AVX && (RAYKIT_ISA_FMA || !RAYKIT_FMA)
        __m128 orgx, orgy, orgz, sx, sy, sz;  ///< origin and shear in the sheared frame's axis order
#endif
    };

    RAYKIT_INLINE static RayData prepare(const Ray& r) noexcept {
        RayData d;
        d.s = Watertight::prepare(r);
        d.ox = 4 * d.s.kx;
        d.oy = 4 * d.s.ky;
        d.oz = 4 * d.s.kz;
#if RAYKIT_ISA_AVX && (RAYKIT_ISA_FMA || !RAYKIT_FMA)
        const float* o = &r.org.x;
        d.orgx = _mm_set1_ps(o[d.s.kx]);
        d.orgy = _mm_set1_ps(o[d.s.ky]);
        d.orgz = _mm_set1_ps(o[d.s.kz]);
        d.sx = _mm_set1_ps(d.s.sx);
        d.sy = _mm_set1_ps(d.s.sy);
        d.sz = _mm_set1_ps(d.s.sz);
#endif
        return d;
    }

    /// Tests the four lanes of `b` against [tmin, tmax]; returns a bit per lane
    /// hit and writes t, u, v of every lane (only hit lanes' values mean anything).
    static RAYKIT_INLINE unsigned intersect(const RayData& d, const TriangleBlock4& b, float tmin, float tmax,
                                            float* RAYKIT_RESTRICT t, float* RAYKIT_RESTRICT u,
                                            float* RAYKIT_RESTRICT v) noexcept {
#if RAYKIT_ISA_AVX && (RAYKIT_ISA_FMA || !RAYKIT_FMA)
        const float* P = &b.p[0][0];
        // corner k's plane for sheared axis x is P + 12k + ox, and so on
        const __m128 az = _mm_sub_ps(_mm_load_ps(P + d.oz), d.orgz);
        const __m128 bz = _mm_sub_ps(_mm_load_ps(P + 12 + d.oz), d.orgz);
        const __m128 cz = _mm_sub_ps(_mm_load_ps(P + 24 + d.oz), d.orgz);
        const __m128 ax = msub(_mm_sub_ps(_mm_load_ps(P + d.ox), d.orgx), d.sx, az);
        const __m128 ay = msub(_mm_sub_ps(_mm_load_ps(P + d.oy), d.orgy), d.sy, az);
        const __m128 bx = msub(_mm_sub_ps(_mm_load_ps(P + 12 + d.ox), d.orgx), d.sx, bz);
        const __m128 by = msub(_mm_sub_ps(_mm_load_ps(P + 12 + d.oy), d.orgy), d.sy, bz);
        const __m128 cx = msub(_mm_sub_ps(_mm_load_ps(P + 24 + d.ox), d.orgx), d.sx, cz);
        const __m128 cy = msub(_mm_sub_ps(_mm_load_ps(P + 24 + d.oy), d.orgy), d.sy, cz);
        const __m256d Ax = _mm256_cvtps_pd(ax), Ay = _mm256_cvtps_pd(ay);
        const __m256d Bx = _mm256_cvtps_pd(bx), By = _mm256_cvtps_pd(by);
        const __m256d Cx = _mm256_cvtps_pd(cx), Cy = _mm256_cvtps_pd(cy);
        // exact products, one rounding per difference: Watertight's Ud, Vd, Wd
        const __m256d Ud = _mm256_sub_pd(_mm256_mul_pd(Cx, By), _mm256_mul_pd(Cy, Bx));
        const __m256d Vd = _mm256_sub_pd(_mm256_mul_pd(Ax, Cy), _mm256_mul_pd(Ay, Cx));
        const __m256d Wd = _mm256_sub_pd(_mm256_mul_pd(Bx, Ay), _mm256_mul_pd(By, Ax));
        const __m256d zero = _mm256_setzero_pd();
        const __m256d neg = _mm256_or_pd(_mm256_or_pd(_mm256_cmp_pd(Ud, zero, _CMP_LT_OQ), _mm256_cmp_pd(Vd, zero, _CMP_LT_OQ)),
                                         _mm256_cmp_pd(Wd, zero, _CMP_LT_OQ));
        const __m256d pos = _mm256_or_pd(_mm256_or_pd(_mm256_cmp_pd(Ud, zero, _CMP_GT_OQ), _mm256_cmp_pd(Vd, zero, _CMP_GT_OQ)),
                                         _mm256_cmp_pd(Wd, zero, _CMP_GT_OQ));
        const __m256d detd = _mm256_add_pd(_mm256_add_pd(Ud, Vd), Wd);
        const __m256d reject = _mm256_or_pd(_mm256_and_pd(neg, pos), _mm256_cmp_pd(detd, zero, _CMP_EQ_OQ));
        const int rej = _mm256_movemask_pd(reject);
        if (rej == 0xF) return 0;  // the common case: every lane outside
        const __m128 U = _mm256_cvtpd_ps(Ud), V = _mm256_cvtpd_ps(Vd), W = _mm256_cvtpd_ps(Wd);
        const __m128 det = _mm256_cvtpd_ps(detd);
        const __m128 Az = _mm_mul_ps(d.sz, az), Bz = _mm_mul_ps(d.sz, bz), Cz = _mm_mul_ps(d.sz, cz);
#if RAYKIT_FMA
        const __m128 T = _mm_fmadd_ps(W, Cz, _mm_fmadd_ps(U, Az, _mm_mul_ps(V, Bz)));
#else
        const __m128 T = _mm_add_ps(_mm_add_ps(_mm_mul_ps(U, Az), _mm_mul_ps(V, Bz)), _mm_mul_ps(W, Cz));
#endif
        const __m128 inv = _mm_div_ps(_mm_set1_ps(1.0f), det);
        const __m128 tt = _mm_mul_ps(T, inv);
        const __m128 in_range = _mm_and_ps(_mm_cmpge_ps(tt, _mm_set1_ps(tmin)), _mm_cmple_ps(tt, _mm_set1_ps(tmax)));
        const __m128 ok = _mm_andnot_ps(_mm_cmpeq_ps(det, _mm_setzero_ps()), in_range);
        _mm_store_ps(t, tt);
        _mm_store_ps(u, _mm_mul_ps(V, inv));
        _mm_store_ps(v, _mm_mul_ps(W, inv));
        unsigned m = static_cast<unsigned>(_mm_movemask_ps(ok)) & ~static_cast<unsigned>(rej);
        for (unsigned k = m; k; k &= k - 1) {  // the scalar test's last check, on hit lanes only
            const int i = std::countr_zero(k);
            if (Watertight::degenerate(b.corner(i, 0), b.corner(i, 1), b.corner(i, 2))) m &= ~(1u << i);
        }
        return m;
#else
        unsigned m = 0;
        for (int i = 0; i < 4; ++i) {
            TriHit h{0.0f, 0.0f, 0.0f};
            if (Watertight::intersect(d.s, b.corner(i, 0), b.corner(i, 1), b.corner(i, 2), tmin, tmax, h))
                m |= 1u << i;
            t[i] = h.t;
            u[i] = h.u;
            v[i] = h.v;
        }
        return m;
#endif
    }

  private:
#if RAYKIT_ISA_AVX && (RAYKIT_ISA_FMA || !RAYKIT_FMA)
    /// a − s·b, rounded as Watertight::msub rounds it.
    static RAYKIT_INLINE __m128 msub(__m128 a, __m128 s, __m128 b) noexcept {
#if RAYKIT_FMA
        return _mm_fnmadd_ps(s, b, a);
#else
        return _mm_sub_ps(a, _mm_mul_ps(s, b));
#endif
    }
#endif
};

}  // namespace raykit::RAYKIT_ISA_NS
#endif  // RAYKIT_ISA_PASS
