// raykit/math/ray.hpp — ray and its precomputed reciprocal direction.
#pragma once

#include <cstddef>

#include "raykit/math/types.hpp"

namespace raykit {

/// A ray o + t·d for t in [tmin, tmax]. `d` need not be normalized; t is in
/// units of |d|. 32 bytes, crosses to OpenCL unchanged (kernels/.../layout.hpp).
struct Ray {
    vec3 org{0.0f};
    float tmin = 0.0f;
    vec3 dir{0.0f, 0.0f, 1.0f};
    float tmax = kInf;
};
static_assert(sizeof(Ray) == 32 && alignof(Ray) == 4);
static_assert(offsetof(Ray, org) == 0 && offsetof(Ray, tmin) == 12 && offsetof(Ray, dir) == 16 &&
              offsetof(Ray, tmax) == 28);

/// Reciprocal direction. 1/±0 is ±inf, which the slab test (intersect/slab.hpp)
/// handles; the signs pick the near/far planes once per ray (octant).
struct RayInv {
    vec3 inv{};
    int octant[3]{};  // 1 when the component's sign bit is set (-0 counts as negative)

    RayInv() = default;
    RAYKIT_INLINE explicit RayInv(const vec3& d) noexcept {
        for (int a = 0; a < 3; ++a) {
            inv[a] = 1.0f / d[a];
            octant[a] = std::signbit(d[a]) ? 1 : 0;
        }
    }
};

}  // namespace raykit
