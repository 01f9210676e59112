// raykit/math/aabb.hpp — axis-aligned bounding box.
#pragma once

#include <algorithm>

#include "raykit/math/types.hpp"

namespace raykit {

/// Axis-aligned box. The default box is empty (min = +inf, max = -inf), so
/// growing it by anything yields that thing; an empty box has area 0.
struct AABB {
    vec3 min{kInf};
    vec3 max{-kInf};

    static AABB empty() noexcept { return {}; }
    static AABB of_point(const vec3& p) noexcept { return {p, p}; }

    /// Grows by a point; NaN coordinates are ignored (comparisons are false).
    RAYKIT_INLINE void grow(const vec3& p) noexcept {
        min.x = robust_min(p.x, min.x), min.y = robust_min(p.y, min.y), min.z = robust_min(p.z, min.z);
        max.x = robust_max(p.x, max.x), max.y = robust_max(p.y, max.y), max.z = robust_max(p.z, max.z);
    }
    RAYKIT_INLINE void grow(const AABB& b) noexcept {
        min.x = robust_min(b.min.x, min.x), min.y = robust_min(b.min.y, min.y), min.z = robust_min(b.min.z, min.z);
        max.x = robust_max(b.max.x, max.x), max.y = robust_max(b.max.y, max.y), max.z = robust_max(b.max.z, max.z);
    }
    bool is_empty() const noexcept { return !(min.x <= max.x && min.y <= max.y && min.z <= max.z); }
    vec3 extent() const noexcept { return is_empty() ? vec3(0.0f) : max - min; }
    vec3 center() const noexcept { return (min + max) * 0.5f; }
    /// Surface area; 0 for an empty box.
    float area() const noexcept {
        const vec3 e = extent();
        return 2.0f * (e.x * e.y + e.y * e.z + e.z * e.x);
    }
    /// Half the surface area (what SAH ratios need).
    float half_area() const noexcept {
        const vec3 e = extent();
        return e.x * e.y + e.y * e.z + e.z * e.x;
    }
    bool contains(const AABB& b) const noexcept {
        if (b.is_empty()) return true;
        return min.x <= b.min.x && min.y <= b.min.y && min.z <= b.min.z && max.x >= b.max.x &&
               max.y >= b.max.y && max.z >= b.max.z;
    }
    bool contains(const vec3& p) const noexcept {
        return min.x <= p.x && min.y <= p.y && min.z <= p.z && max.x >= p.x && max.y >= p.y &&
               max.z >= p.z;
    }
    friend AABB merge(AABB a, const AABB& b) noexcept {
        a.grow(b);
        return a;
    }
    friend bool operator==(const AABB&, const AABB&) = default;
};
static_assert(sizeof(AABB) == 24);

}  // namespace raykit
