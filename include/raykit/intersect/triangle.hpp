// raykit/intersect/triangle.hpp — ray/triangle tests as tag types.
//
// Each test is a type with
//   struct RayData;                               // per-ray precomputation
//   static RayData prepare(const Ray&);
//   static bool intersect(const RayData&, p0, p1, p2, tmin, tmax, TriHit&);
// so traversal is templated on the test and pays only for what it uses.
//
//  - Watertight (default): Woop, Benthin, Wald, "Watertight Ray/Triangle
//    Intersection", JCGT 2013. Never misses through a shared edge or vertex of a
//    closed mesh; its 2-D edge functions are evaluated in double (exact products).
//  - MollerTrumbore: the classic test (Möller & Trumbore 1997). Fast; can miss
//    rays through shared edges/vertices (rounding of u, v against 0 and 1).
//  - ThesisTest: the thesis's method: hit the supporting plane, then check the
//    point against each edge with a cross product and a fixed tolerance. The
//    tolerance is absolute, so it leaks (misses) on large triangles and admits
//    false hits next to tiny ones; kept as an accuracy baseline.
// Every multiply-add of the three is written out and rounded by the one FMA rule
// (RAYKIT_FMA, config.hpp: fused), so a test answers the same in every build and at
// every instruction-set level the walks dispatch to.
//
// All three return no hit for degenerate (zero-area) triangles and for any
// NaN/inf vertex. u, v are the barycentric weights of p1 and p2.
//
// Range: the answers are right only inside math/limits.hpp's rule (vertex
// and origin coordinates within ±2^32, the direction's largest component in
// [2^-16, 2^16]). Beyond it the float t numerators overflow: measured against
// a long-double oracle, Watertight's t goes wrong from coordinates ~1e13 from
// the origin and its hits from ~1e14; Möller–Trumbore reports hits at t = inf
// from ~1e13. Trees refuse such meshes; callers check rays with check_ray.
#pragma once

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "raykit/math/ray.hpp"

namespace raykit {

struct TriHit {
    float t, u, v;
};

struct Watertight {
    /// The two multiply-adds of the test, rounded as config.hpp's RAYKIT_FMA
    /// says (fused by default, on every target). Written out, not left to the
    /// compiler's contraction, so answers do not depend on flags, -O or
    /// -ffp-contract; the 4-wide test (intersect/triangle4.hpp) and the
    /// device (kernels/raykit/kernels/common.hpp) round the same way.
    static RAYKIT_INLINE float msub(float a, float s, float b) noexcept {  // a − s·b
#if RAYKIT_FMA
        return std::fma(-s, b, a);
#else
        return a - s * b;
#endif
    }
    static RAYKIT_INLINE float tnum(float U, float Az, float V, float Bz, float W, float Cz) noexcept {
#if RAYKIT_FMA
        return std::fma(W, Cz, std::fma(U, Az, V * Bz));
#else
        return U * Az + V * Bz + W * Cz;
#endif
    }

    /// Zero area: every component of the edges' cross product, in double
    /// from the float vertices, is zero (its two products compare equal):
    /// collinear or repeated vertices. Checked
    /// only on the way to reporting a hit, because the sheared 2-D edge
    /// functions of a zero-area triangle are rounded independently and can
    /// leave a nonzero determinant for a ray through its line.
    static bool degenerate(const vec3& p0, const vec3& p1, const vec3& p2) noexcept {
        const double e1x = double(p1.x) - double(p0.x), e1y = double(p1.y) - double(p0.y), e1z = double(p1.z) - double(p0.z);
        const double e2x = double(p2.x) - double(p0.x), e2y = double(p2.y) - double(p0.y), e2z = double(p2.z) - double(p0.z);
        return e1y * e2z == e1z * e2y && e1z * e2x == e1x * e2z && e1x * e2y == e1y * e2x;  // compared, not subtracted: nothing to fuse
    }

    struct RayData {
        vec3 org;
        int kx, ky, kz;
        float sx, sy, sz;
    };
    RAYKIT_INLINE static RayData prepare(const Ray& r) noexcept {
        RayData d;
        d.org = r.org;
        const vec3 ad = glm::abs(r.dir);
        d.kz = max_axis(ad);
        d.kx = d.kz + 1 - 3 * int(d.kz == 2);
        d.ky = d.kx + 1 - 3 * int(d.kx == 2);
        const float* dir = &r.dir.x;
        // swap kx, ky when dir[kz] < 0, without a branch (random rays take it half the time)
        const int swap = (d.kx ^ d.ky) & -int(dir[d.kz] < 0.0f);
        d.kx ^= swap;
        d.ky ^= swap;
        d.sx = dir[d.kx] / dir[d.kz];
        d.sy = dir[d.ky] / dir[d.kz];
        d.sz = 1.0f / dir[d.kz];
        return d;
    }
    static RAYKIT_INLINE bool intersect(const RayData& d, const vec3& p0, const vec3& p1,
                                        const vec3& p2, float tmin, float tmax, TriHit& out) noexcept {
        const vec3 A = p0 - d.org, B = p1 - d.org, C = p2 - d.org;
        // component access through pointers: run-time indices, no GLM debug check
        const float* a = &A.x;
        const float* b = &B.x;
        const float* c = &C.x;
        const float Ax = msub(a[d.kx], d.sx, a[d.kz]), Ay = msub(a[d.ky], d.sy, a[d.kz]);
        const float Bx = msub(b[d.kx], d.sx, b[d.kz]), By = msub(b[d.ky], d.sy, b[d.kz]);
        const float Cx = msub(c[d.kx], d.sx, c[d.kz]), Cy = msub(c[d.ky], d.sy, c[d.kz]);
        // Edge functions in double: a product of two floats is exact in double,
        // so each is rounded once, the same way in both triangles that share
        // the edge (watertight), even when the compiler fuses multiply-adds.
        const double Ud = double(Cx) * double(By) - double(Cy) * double(Bx);
        const double Vd = double(Ax) * double(Cy) - double(Ay) * double(Cx);
        const double Wd = double(Bx) * double(Ay) - double(By) * double(Ax);
        // one branch, not six: random rays make each sign unpredictable
        const bool neg = (Ud < 0.0) | (Vd < 0.0) | (Wd < 0.0);
        const bool pos = (Ud > 0.0) | (Vd > 0.0) | (Wd > 0.0);
        if (neg & pos) return false;
        const double detd = Ud + Vd + Wd;
        if (!(detd != 0.0)) return false;  // degenerate, or NaN
        const float U = static_cast<float>(Ud), V = static_cast<float>(Vd), W = static_cast<float>(Wd);
        const float det = static_cast<float>(detd);
        if (!(det != 0.0f)) return false;  // below float range: treat as degenerate
        const float Az = d.sz * a[d.kz], Bz = d.sz * b[d.kz], Cz = d.sz * c[d.kz];
        const float T = tnum(U, Az, V, Bz, W, Cz);
        const float inv = 1.0f / det;
        const float t = T * inv;
        if (!(t >= tmin && t <= tmax)) return false;  // also rejects NaN
        if (degenerate(p0, p1, p2)) return false;
        out = {t, V * inv, W * inv};
        return true;
    }
};

namespace detail {
/// a·b + c rounded by the one FMA rule (config.hpp's RAYKIT_FMA): fused, written out, so no
/// test's answer depends on what the compiler contracts (it contracts inside the per-level
/// copies of the walks that have FMA, scene/trace.hpp, and not in a default build's base code).
RAYKIT_INLINE float madd(float a, float b, float c) noexcept {
#if RAYKIT_FMA
    return std::fma(a, b, c);
#else
    return a * b + c;
#endif
}
/// dot(a, b) as madd(ax, bx, madd(ay, by, az·bz)).
RAYKIT_INLINE float mdot(const vec3& a, const vec3& b) noexcept { return madd(a.x, b.x, madd(a.y, b.y, a.z * b.z)); }
/// cross(a, b), each component one madd.
RAYKIT_INLINE vec3 mcross(const vec3& a, const vec3& b) noexcept {
    return {madd(a.y, b.z, -(a.z * b.y)), madd(a.z, b.x, -(a.x * b.z)), madd(a.x, b.y, -(a.y * b.x))};
}
}  // namespace detail

struct MollerTrumbore {
    struct RayData {
        vec3 org, dir;
    };
    static RayData prepare(const Ray& r) noexcept { return {r.org, r.dir}; }
    static RAYKIT_INLINE bool intersect(const RayData& d, const vec3& p0, const vec3& p1,
                                        const vec3& p2, float tmin, float tmax, TriHit& out) noexcept {
        using detail::mcross, detail::mdot;
        const vec3 e1 = p1 - p0, e2 = p2 - p0;
        const vec3 pv = mcross(d.dir, e2);
        const float det = mdot(e1, pv);
        if (!(det != 0.0f)) return false;
        const float inv = 1.0f / det;
        const vec3 tv = d.org - p0;
        const float u = mdot(tv, pv) * inv;
        if (!(u >= 0.0f && u <= 1.0f)) return false;
        const vec3 qv = mcross(tv, e1);
        const float v = mdot(d.dir, qv) * inv;
        if (!(v >= 0.0f && u + v <= 1.0f)) return false;
        const float t = mdot(e2, qv) * inv;
        if (!(t >= tmin && t <= tmax)) return false;
        if (Watertight::degenerate(p0, p1, p2)) return false;  // det from the ray can round away from 0
        out = {t, u, v};
        return true;
    }
};

struct ThesisTest {
    /// Absolute tolerance of the inside test, in the units of
    /// dot(cross(edge, p − vertex), n̂) (length², n̂ the unit normal): the
    /// thesis's fixed epsilon. Fixed, hence scale-dependent: it admits points
    /// just outside small triangles and is lost in rounding on large ones.
    static constexpr float kTolerance = 1e-7f;
    struct RayData {
        vec3 org, dir;
    };
    static RayData prepare(const Ray& r) noexcept { return {r.org, r.dir}; }
    static RAYKIT_INLINE bool intersect(const RayData& d, const vec3& p0, const vec3& p1,
                                        const vec3& p2, float tmin, float tmax, TriHit& out) noexcept {
        using detail::madd, detail::mcross, detail::mdot;
        const vec3 n = mcross(p1 - p0, p2 - p0);
        const float len2 = mdot(n, n);
        // |n|^2 leaves float range for edges beyond ~4e9 (every outside ray
        // then "hit", nu being 0) or below ~1e-10: only then take it in double
        const float len = len2 > 0.0f && len2 <= std::numeric_limits<float>::max()
                              ? std::sqrt(len2)
                              : static_cast<float>(std::min(std::sqrt(double(n.x) * n.x + double(n.y) * n.y + double(n.z) * n.z),
                                                            double(std::numeric_limits<float>::max())));
        const float denom = mdot(n, d.dir);
        if (!(denom != 0.0f) || !(len > 0.0f)) return false;
        const float t = mdot(n, p0 - d.org) / denom;
        if (!(t >= tmin && t <= tmax)) return false;
        const vec3 p(madd(t, d.dir.x, d.org.x), madd(t, d.dir.y, d.org.y), madd(t, d.dir.z, d.org.z));
        const vec3 nu = n / len;
        const float c0 = mdot(mcross(p1 - p0, p - p0), nu);
        const float c1 = mdot(mcross(p2 - p1, p - p1), nu);
        const float c2 = mdot(mcross(p0 - p2, p - p2), nu);
        if (!(c0 >= -kTolerance && c1 >= -kTolerance && c2 >= -kTolerance)) return false;
        // c1 ~ weight of p0, c2 ~ weight of p1, c0 ~ weight of p2 (each times |n|)
        out = {t, c2 / len, c0 / len};
        return true;
    }
};

/// The default test.
using DefaultTriangleTest = Watertight;

}  // namespace raykit
