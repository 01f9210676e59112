// raykit/math/hit.hpp — closest-hit record.
#pragma once

#include <cstddef>
#include <cstdint>

#include "raykit/math/types.hpp"

namespace raykit {

/// Result of a closest-hit query. `prim` is the triangle index in load order
/// (kInvalidIndex on a miss); u, v are the barycentric weights of the
/// triangle's 2nd and 3rd vertex; `inst` is the instance (0 for a single mesh).
/// 20 bytes, crosses to OpenCL unchanged.
struct Hit {
    float t = kInf;
    float u = 0.0f;
    float v = 0.0f;
    std::uint32_t prim = kInvalidIndex;
    std::uint32_t inst = kInvalidIndex;

    bool valid() const noexcept { return prim != kInvalidIndex; }
    /// Deterministic order for ties: smaller t wins, then the smaller
    /// (instance, primitive) pair, so equal-t hits resolve the same every run.
    bool closer_than(const Hit& o) const noexcept {
        if (t != o.t) return t < o.t;
        if (inst != o.inst) return inst < o.inst;
        return prim < o.prim;
    }
};
static_assert(sizeof(Hit) == 20 && alignof(Hit) == 4);
static_assert(offsetof(Hit, t) == 0 && offsetof(Hit, u) == 4 && offsetof(Hit, v) == 8 &&
              offsetof(Hit, prim) == 12 && offsetof(Hit, inst) == 16);

}  // namespace raykit
