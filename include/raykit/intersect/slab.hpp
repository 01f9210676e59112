// raykit/intersect/slab.hpp — robust ray/box slab test.
//
// Correct for direction components of +0 and -0 (1/±0 = ±inf) and for tiny
// magnitudes; a NaN — (plane − origin)·inf when the origin lies on the plane — is
// never allowed to decide: robust_max/robust_min keep the current interval then,
// which counts the boundary as inside. The exit distance is widened by
// 1 + 2·gamma(3) (Ize, "Robust BVH Ray Traversal", JCGT 2013), so a box is
// never missed through rounding by a ray that hits a triangle inside it; tmax
// is widened the same way, so a box whose entry equals the current closest hit
// (a tie) is still visited.
//
// SlabRay is compiled once per instruction-set level (scene/trace.hpp): the part of this
// header below RAYKIT_ISA_PASS is its per-level part, included per level by scene/trace_level.inc;
// raykit::SlabRay is the base level's.
#ifndef RAYKIT_INTERSECT_SLAB_HPP
#define RAYKIT_INTERSECT_SLAB_HPP

#include "raykit/math/aabb.hpp"
#include "raykit/math/ray.hpp"
#include "raykit/simd/isa.hpp"

namespace raykit {

inline constexpr float kSlabExitScale = 1.0f + 2.0f * gamma_bound(3);

/// Entry distance of the ray into [bmin, bmax] clipped to [tmin, tmax], or a
/// value > tmax (possibly NaN-free +inf) when the ray misses. `lo`/`hi` are the
/// box corners; `ri` carries 1/d and the octant.
RAYKIT_INLINE bool slab_test(const float* RAYKIT_RESTRICT lo, const float* RAYKIT_RESTRICT hi,
                             const vec3& org, const RayInv& ri, float tmin, float tmax,
                             float& tentry) noexcept {
    float t0 = tmin, t1 = tmax * kSlabExitScale;
    for (int a = 0; a < 3; ++a) {
        const float nearp = ri.octant[a] ? hi[a] : lo[a];
        const float farp = ri.octant[a] ? lo[a] : hi[a];
        const float tn = (nearp - org[a]) * ri.inv[a];
        const float tf = (farp - org[a]) * ri.inv[a] * kSlabExitScale;
        t0 = robust_max(tn, t0);
        t1 = robust_min(tf, t1);
    }
    tentry = t0;
    return t0 <= t1;
}

/// Convenience overload on an AABB.
RAYKIT_INLINE bool slab_test(const AABB& box, const Ray& ray, const RayInv& ri, float& tentry) noexcept {
    return slab_test(&box.min.x, &box.max.x, ray.org, ri, ray.tmin, ray.tmax, tentry);
}

}  // namespace raykit

#endif  // RAYKIT_INTERSECT_SLAB_HPP

#ifdef RAYKIT_ISA_PASS
namespace raykit::RAYKIT_ISA_NS {

/// Per-ray state of the slab test, prepared once per ray. With SSE4.1 the
/// three axes are tested in one 4-wide operation (lane 3 carries tmin/tmax);
/// the result is identical to slab_test() above, including the NaN rules
/// (maxps/minps return their second operand on NaN, which is the current
/// interval end, exactly as robust_max/robust_min do).
struct SlabRay {
    vec3 org;
    RayInv ri;
#if RAYKIT_ISA_SSE41
    __m128 org4, inv4, sign4;
#endif
#if RAYKIT_ISA_AVX
    __m256 org8, inv8, sign8;
#endif
    explicit SlabRay(const Ray& r) noexcept : org(r.org), ri(r.dir) {
#if RAYKIT_ISA_SSE41
        org4 = _mm_setr_ps(org.x, org.y, org.z, 0.0f);
        inv4 = _mm_setr_ps(ri.inv.x, ri.inv.y, ri.inv.z, 0.0f);
        sign4 = _mm_castsi128_ps(_mm_setr_epi32(ri.octant[0] ? -1 : 0, ri.octant[1] ? -1 : 0,
                                                ri.octant[2] ? -1 : 0, 0));
#endif
#if RAYKIT_ISA_AVX
        org8 = _mm256_set_m128(org4, org4);
        inv8 = _mm256_set_m128(inv4, inv4);
        sign8 = _mm256_set_m128(sign4, sign4);
#endif
    }

    /// Tests two boxes stored as consecutive 32-byte records (min.xyz, max.xyz,
    /// two 4-byte words each — a pair of BVH nodes). Returns bit 0 for a hit
    /// of the first, bit 1 for the second, and their entry distances.
    RAYKIT_INLINE unsigned test_pair(const AABB& first, const AABB& second, float tmin, float tmax, float& t0,
                                     float& t1) const noexcept {
#if RAYKIT_ISA_AVX
        const float* a = &first.min.x;
        const float* b = &second.min.x;
        const __m256 zero = _mm256_setzero_ps();
        // lanes 3 and 7 hold max.x (lo) and the next word (hi, an integer):
        // both are replaced before any arithmetic.
        const __m256 lo = _mm256_blend_ps(_mm256_loadu2_m128(b, a), zero, 0x88);
        const __m256 hi = _mm256_blend_ps(_mm256_loadu2_m128(b + 3, a + 3), zero, 0x88);
        const __m256 nearp = _mm256_blendv_ps(lo, hi, sign8);
        const __m256 farp = _mm256_blendv_ps(hi, lo, sign8);
        const __m256 vmin = _mm256_set1_ps(tmin), vmax = _mm256_set1_ps(tmax * kSlabExitScale);
        __m256 tn = _mm256_mul_ps(_mm256_sub_ps(nearp, org8), inv8);
        __m256 tf = _mm256_mul_ps(_mm256_mul_ps(_mm256_sub_ps(farp, org8), inv8), _mm256_set1_ps(kSlabExitScale));
        tn = _mm256_max_ps(_mm256_blend_ps(tn, vmin, 0x88), vmin);  // NaN lanes -> tmin
        tf = _mm256_min_ps(_mm256_blend_ps(tf, vmax, 0x88), vmax);  // NaN lanes -> tmax
        tn = _mm256_max_ps(tn, _mm256_shuffle_ps(tn, tn, _MM_SHUFFLE(2, 3, 0, 1)));
        tn = _mm256_max_ps(tn, _mm256_shuffle_ps(tn, tn, _MM_SHUFFLE(1, 0, 3, 2)));
        tf = _mm256_min_ps(tf, _mm256_shuffle_ps(tf, tf, _MM_SHUFFLE(2, 3, 0, 1)));
        tf = _mm256_min_ps(tf, _mm256_shuffle_ps(tf, tf, _MM_SHUFFLE(1, 0, 3, 2)));
        const unsigned m = static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(tn, tf, _CMP_LE_OQ)));
        t0 = _mm256_cvtss_f32(tn);
        t1 = _mm_cvtss_f32(_mm256_extractf128_ps(tn, 1));
        return (m & 1u) | ((m >> 3) & 2u);
#else
        return unsigned(test(first, tmin, tmax, t0)) | (unsigned(test(second, tmin, tmax, t1)) << 1);
#endif
    }

    /// Slab test of a node's box: `box` points at min.xyz followed by max.xyz
    /// and at least 4 more readable bytes (a Node's index field).
    RAYKIT_INLINE bool test(const AABB& box, float tmin, float tmax, float& tentry) const noexcept {
#if RAYKIT_ISA_SSE41
        // Lane 3 of `hi` holds the bits of the next field (an integer, i.e. a
        // denormal float): zero it before any arithmetic touches it.
        const __m128 zero = _mm_setzero_ps();
        const __m128 lo = _mm_blend_ps(_mm_loadu_ps(&box.min.x), zero, 8);  // minx miny minz 0
        const __m128 hi = _mm_blend_ps(_mm_loadu_ps(&box.max.x), zero, 8);  // maxx maxy maxz 0
        const __m128 nearp = _mm_blendv_ps(lo, hi, sign4);
        const __m128 farp = _mm_blendv_ps(hi, lo, sign4);
        const __m128 vmin = _mm_set1_ps(tmin), vmax = _mm_set1_ps(tmax * kSlabExitScale);
        __m128 tn = _mm_mul_ps(_mm_sub_ps(nearp, org4), inv4);
        __m128 tf = _mm_mul_ps(_mm_mul_ps(_mm_sub_ps(farp, org4), inv4), _mm_set1_ps(kSlabExitScale));
        tn = _mm_max_ps(_mm_blend_ps(tn, vmin, 8), vmin);  // NaN lanes -> tmin
        tf = _mm_min_ps(_mm_blend_ps(tf, vmax, 8), vmax);  // NaN lanes -> tmax
        tn = _mm_max_ps(tn, _mm_shuffle_ps(tn, tn, _MM_SHUFFLE(2, 3, 0, 1)));
        tn = _mm_max_ps(tn, _mm_shuffle_ps(tn, tn, _MM_SHUFFLE(1, 0, 3, 2)));
        tf = _mm_min_ps(tf, _mm_shuffle_ps(tf, tf, _MM_SHUFFLE(2, 3, 0, 1)));
        tf = _mm_min_ps(tf, _mm_shuffle_ps(tf, tf, _MM_SHUFFLE(1, 0, 3, 2)));
        tentry = _mm_cvtss_f32(tn);
        return _mm_comile_ss(tn, tf);
#else
        return slab_test(&box.min.x, &box.max.x, org, ri, tmin, tmax, tentry);
#endif
    }
};

}  // namespace raykit::RAYKIT_ISA_NS
#endif  // RAYKIT_ISA_PASS
