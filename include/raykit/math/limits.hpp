// raykit/math/limits.hpp — the coordinate range inside which the triangle tests answer right.
//
// Rule: every finite vertex coordinate and every ray origin coordinate has
// |x| <= kMaxCoordinate = 2^32 (4.29e9); a ray's direction is finite and its
// largest |component| lies in [2^-16, 2^16]; tmin and tmax are not NaN.
// Vertices that are not finite stay allowed (such triangles are never hit).
// Trees refuse meshes outside the rule (check_positions, called by
// primitive_refs, BlockBvhT::make and Scene), and check_ray is for callers
// that read rays from outside (files, the network): both throw
// std::domain_error naming the value and the limit. Nothing is checked per
// ray while tracing.
//
// Why 2^32: the tests work in float. The watertight test's t numerator
// T = U·Az + V·Bz + W·Cz grows as (triangle size)^2 · distance / |d_kz|, so it
// overflows float (3.4e38) from about 1e13 (cube root of 3.4e38 is 7e12);
// Möller–Trumbore's dot(e2, cross(s, e1)) likewise. Measured before this rule
// with a seeded oracle in long double (rays aimed at barycentric weights
// >= 0.1 inside or <= -0.1 outside a random triangle, grazing rays with
// |cos| < 0.05 left out; "wrong" = hit/miss differs or t off by > 1e-4
// relative; about 18 800 judged rays per magnitude):
//   vertices at distance M from an origin near 0, |d| = 1:
//     Watertight (and Watertight4, bit for bit): 0 wrong up to 1e12; 1e13:
//       2 950 wrong t; 1e14: 36 wrong hit/miss and 9 399 wrong t; 1e20:
//       8 422 wrong hit/miss; from 1e21 every answer wrong.
//     MollerTrumbore: 0 wrong up to 1e12; 1e13: 193 wrong hit/miss (hits
//       reported at t = inf) and 2 571 wrong t.
//     ThesisTest: dot(n, n) overflows from edges of ~4e9 (|n|^2 > 3.4e38) and
//       every outside ray "hit"; fixed (its length falls back to double).
//   origin and vertices anywhere in [-M, M]^3, direction's largest component
//     2^k with k uniform in [-16, 16] (a short d makes T larger; 185 000 rays):
//     Watertight: 0 wrong up to 2^36 (6.9e10); 2^38: 5 wrong hit/miss and
//       3 397 wrong t. With k in [-24, 24] it fails from 2^36, in [-32, 32]
//       from 2^32; direction length alone (2^-120 .. 2^120, geometry ~1)
//       changes nothing.
// So 2^32 with |d_kz| >= 2^-16 stays a factor of 16 in coordinates (2^12 in
// T) below the first measured failure; the 2^16 cap keeps T from underflowing
// on ordinary geometry. tests/test_geometry.cpp runs the oracle (4 000 rays
// per case, t within 1e-3) at 1, 1e3, 1e6, 1e9 and 2^32 and asserts 0 wrong
// answers for all three tests and Watertight4, FMA on and off; it fails at
// 1e14, and at 2^40 if the bound is raised there (383 of 3 663 wrong).
//
// Not covered: tiny scales. Scaling a whole scene down (origin at M, a
// triangle of size 1e-3·M as far from it) underflows T: clean at M = 1e-9,
// from M = 1e-10 t loses accuracy (61 of 18 806 off by > 1e-4), from 1e-14
// every t is wrong; hit/miss (edge functions in double) holds to 1e-14, from
// 1e-15 hits are missed (16 of 18 805), below 1e-16 most. No coordinate bound can
// exclude this (0 is a valid coordinate), so it is the caller's units: keep
// what rays must resolve (triangle sizes and hit distances) above ~1e-11.
#pragma once

#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <sstream>
#include <stdexcept>
#include <string>

#include "raykit/math/ray.hpp"

namespace raykit {

/// Largest |coordinate| of a vertex or ray origin that the triangle tests answer right (2^32).
inline constexpr float kMaxCoordinate = 0x1p32f;
/// Smallest allowed largest-|component| of a ray direction (2^-16).
inline constexpr float kMinDirection = 0x1p-16f;
/// Largest allowed largest-|component| of a ray direction (2^16).
inline constexpr float kMaxDirection = 0x1p16f;

/// True for a finite x with |x| <= kMaxCoordinate (false for NaN and inf).
inline bool coordinate_in_range(float x) noexcept { return std::fabs(x) <= kMaxCoordinate; }

/// Empty when `r` obeys the rule above, else why not (naming the value and the limit).
inline std::string ray_range_error(const Ray& r) {
    std::ostringstream msg;
    msg.precision(9);
    static const char* const axis = "xyz";
    for (int a = 0; a < 3; ++a)
        if (!coordinate_in_range(r.org[a])) {
            msg << "ray origin " << axis[a] << " = " << r.org[a] << " is outside [-2^32, 2^32]: float ray/triangle tests"
                   " give wrong answers there (raykit/math/limits.hpp)";
            return msg.str();
        }
    if (!is_finite(r.dir)) {
        msg << "ray direction (" << r.dir.x << ", " << r.dir.y << ", " << r.dir.z << ") is not finite";
        return msg.str();
    }
    const float m = std::fmax(std::fabs(r.dir.x), std::fmax(std::fabs(r.dir.y), std::fabs(r.dir.z)));
    if (!(m >= kMinDirection && m <= kMaxDirection)) {
        msg << "ray direction (" << r.dir.x << ", " << r.dir.y << ", " << r.dir.z << ") has largest |component| "
            << m << ", outside [2^-16, 2^16] (raykit/math/limits.hpp)";
        return msg.str();
    }
    if (std::isnan(r.tmin) || std::isnan(r.tmax)) {
        msg << "ray tmin = " << r.tmin << ", tmax = " << r.tmax << ": NaN";
        return msg.str();
    }
    return {};
}

/// True when `r` obeys the rule above.
inline bool ray_in_range(const Ray& r) noexcept {
    for (int a = 0; a < 3; ++a)
        if (!coordinate_in_range(r.org[a])) return false;
    if (!is_finite(r.dir)) return false;
    const float m = std::fmax(std::fabs(r.dir.x), std::fmax(std::fabs(r.dir.y), std::fabs(r.dir.z)));
    return m >= kMinDirection && m <= kMaxDirection && !std::isnan(r.tmin) && !std::isnan(r.tmax);
}

/// Throws std::domain_error (the message of ray_range_error) when `r` is outside the rule.
inline void check_ray(const Ray& r) {
    if (ray_in_range(r)) return;
    throw std::domain_error("raykit: " + ray_range_error(r));
}

/// Throws std::domain_error naming `what`, the vertex index, the value and
/// the limit when a finite coordinate of `positions` exceeds kMaxCoordinate.
/// Non-finite vertices pass (their triangles are never hit).
inline void check_positions(std::span<const vec3> positions, const char* what) {
    // one branch-free pass (vectorised: 3M vertices in ~9 ms on a loaded
    // machine, under 1% of a build), the message only on failure. |x| as
    // bits: (2^32, inf) is one unsigned range; NaN and inf fall outside it.
    constexpr std::uint32_t lo = std::bit_cast<std::uint32_t>(kMaxCoordinate) + 1u;
    constexpr std::uint32_t span = std::bit_cast<std::uint32_t>(kInf) - lo;
    const auto out = [](float x) noexcept {
        return static_cast<std::uint32_t>(((std::bit_cast<std::uint32_t>(x) & 0x7fffffffu) - lo) < span);
    };
    std::uint32_t any = 0;
    for (const vec3& p : positions) any |= out(p.x) | out(p.y) | out(p.z);
    if (any == 0) return;
    for (std::size_t i = 0; i < positions.size(); ++i)
        for (int a = 0; a < 3; ++a) {
            const float x = positions[i][a];
            if (std::isfinite(x) && !coordinate_in_range(x)) {
                std::ostringstream msg;
                msg.precision(9);
                msg << what << ": vertex " << i << " coordinate " << "xyz"[a] << " = " << x
                    << " is outside [-2^32, 2^32] = [-4294967296, 4294967296]: float ray/triangle tests give wrong"
                       " answers there (raykit/math/limits.hpp)";
                throw std::domain_error(msg.str());
            }
        }
}

}  // namespace raykit
