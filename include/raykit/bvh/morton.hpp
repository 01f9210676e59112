// raykit/bvh/morton.hpp — Morton codes of primitive centres.
//
// The bottom-up builders start from primitives in space-filling-curve order:
// PLOC sorts by the 63-bit code once, pairwise and sort-by-axis (--axis morton)
// use the 30-bit code to order their elements. Both codes quantise the same
// cube around the centroid bounds with one scale on every axis, so that the
// order keeps distances in proportion on flat or long scenes; inputs outside
// the cube (and NaN) clamp to its faces.
#pragma once

#include <algorithm>
#include <cstdint>

#include "raykit/math/aabb.hpp"

namespace raykit::detail {

/// Spreads the low 21 bits of x to every third bit.
inline std::uint64_t spread_bits21(std::uint64_t x) noexcept {
    x &= 0x1FFFFFull;
    x = (x | x << 32) & 0x1F00000000FFFFull;
    x = (x | x << 16) & 0x1F0000FF0000FFull;
    x = (x | x << 8) & 0x100F00F00F00F00Full;
    x = (x | x << 4) & 0x10C30C30C30C30C3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
}

/// Maps points into a cube of 2^21 cells per side around `bounds` (same
/// scale on every axis, so distances keep their proportions) and returns
/// 63-bit Morton codes.
struct MortonQuantizer {
    vec3 lo{0.0f};
    float scale = 0.0f;
    explicit MortonQuantizer(const AABB& bounds) {
        if (bounds.is_empty()) return;
        lo = bounds.min;
        const vec3 e = bounds.extent();
        const float m = std::max(e.x, std::max(e.y, e.z));
        scale = m > 0.0f && m < kInf ? 2097151.0f / m : 0.0f;
    }
    std::uint64_t operator()(const vec3& p) const noexcept {
        auto q = [&](int a) -> std::uint64_t {
            float f = (p[a] - lo[a]) * scale;
            f = f > 0.0f ? f : 0.0f;  // also maps NaN to 0
            f = f < 2097151.0f ? f : 2097151.0f;
            return static_cast<std::uint64_t>(f);
        };
        return spread_bits21(q(0)) << 2 | spread_bits21(q(1)) << 1 | spread_bits21(q(2));
    }
    /// 30-bit code (10 bits per axis, the same cube cut into 1024 cells per side).
    std::uint32_t code30(const vec3& p) const noexcept {
        auto q = [&](int a) -> std::uint32_t {
            float f = (p[a] - lo[a]) * (scale * (1.0f / 2048.0f));
            f = f > 0.0f ? f : 0.0f;
            f = f < 1023.0f ? f : 1023.0f;
            std::uint32_t x = static_cast<std::uint32_t>(f);
            x = (x | x << 16) & 0x030000FFu;
            x = (x | x << 8) & 0x0300F00Fu;
            x = (x | x << 4) & 0x030C30C3u;
            x = (x | x << 2) & 0x09249249u;
            return x;
        };
        return q(0) << 2 | q(1) << 1 | q(2);
    }
};

}  // namespace raykit::detail
