// raykit/math/offset.hpp — robust origin offset for secondary rays.
//
// Wächter & Binder, "A Fast and Robust Method for Avoiding Self-Intersection",
// Ray Tracing Gems (2019), ch. 6: move the hit point along the geometric normal
// by a fixed number of ulps (integer offset), or by a small absolute amount near
// the origin where ulps are tiny.
#pragma once

#include <bit>
#include <cmath>
#include <cstdint>

#include "raykit/math/types.hpp"

namespace raykit {

/// Returns p pushed off the surface along n (n: geometric normal on the side the
/// new ray leaves from; need not be normalized but should be O(1)).
inline vec3 offset_ray_origin(const vec3& p, const vec3& n) noexcept {
    constexpr float kOrigin = 1.0f / 32.0f;
    constexpr float kFloatScale = 1.0f / 65536.0f;
    constexpr float kIntScale = 256.0f;
    vec3 out;
    for (int a = 0; a < 3; ++a) {
        const auto of = static_cast<std::int32_t>(kIntScale * n[a]);
        const auto bits = std::bit_cast<std::int32_t>(p[a]);
        const float moved = std::bit_cast<float>(bits + (p[a] < 0.0f ? -of : of));
        out[a] = std::fabs(p[a]) < kOrigin ? p[a] + kFloatScale * n[a] : moved;
    }
    return out;
}

}  // namespace raykit
