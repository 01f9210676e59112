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
#pragma once

#include "raykit/math/aabb.hpp"
#include "raykit/math/ray.hpp"

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
