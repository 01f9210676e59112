// raykit/bvh/sah.hpp — surface-area-heuristic cost of a finished tree.
#pragma once

#include <bit>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "raykit/bvh/node.hpp"

namespace raykit {

/// Builders' `leaf_block`: primitives tested together (4 for the 4-triangle
/// SIMD blocks of scene/block_bvh.hpp). Valid: a power of two in [1, 16].
inline constexpr bool valid_leaf_block(unsigned leaf_block) noexcept {
    return leaf_block >= 1 && leaf_block <= 16 && std::has_single_bit(leaf_block);
}
/// Throws std::invalid_argument naming `builder` unless valid_leaf_block().
inline void check_leaf_block(unsigned leaf_block, const char* builder) {
    if (!valid_leaf_block(leaf_block))
        throw std::invalid_argument(std::string(builder) + ": leaf_block must be a power of two in [1, 16]");
}
/// The SAH weight of a leaf of n primitives tested leaf_block at a time:
/// ceil(n / leaf_block), i.e. n for one-at-a-time tests. leaf_block must be valid.
inline float leaf_block_weight(std::uint32_t n, unsigned leaf_block) noexcept {
    return float((n + leaf_block - 1) >> std::countr_zero(leaf_block));
}

/// Half surface area ex·ey + ey·ez + ez·ex of a box with extents e, with each
/// product exact (float × float fits a double) and the sum rounded to float at
/// the end, so a compiler's multiply-add fusion cannot change it: the bottom-up
/// builders' merge and leaf decisions and the wide collapse use it, and so does
/// the device builder (kernels/raykit/kernels/build.hpp), which then makes the
/// CPU's trees bit for bit whatever the host's flags.
inline float fused_proof_half_area(float ex, float ey, float ez) noexcept {
    const double x = ex, y = ey, z = ez;
    return static_cast<float>((x * y + y * z) + z * x);
}
/// fused_proof_half_area of a box (0 for an empty box, as AABB::half_area).
inline float fused_proof_half_area(const AABB& b) noexcept {
    const vec3 e = b.extent();
    return fused_proof_half_area(e.x, e.y, e.z);
}

/// The leaf settings of the SAH, one object composed into every builder's
/// Config (member `leaf`) and into BuildOptions, with the cost terms the
/// builders compare. The defaults are every builder's.
struct LeafCost {
    unsigned max_leaf_size = 8;      ///< larger sets never become one leaf (bottom-up builders: 0 acts as 1)
    float traversal_cost = 1.0f;     ///< Ct, cost of visiting an inner node
    float intersection_cost = 1.0f;  ///< Ci, cost of one ray/triangle test (of one block, below)
    /// Primitives tested together: a set of n costs Ci·ceil(n / leaf_block)
    /// in the SAH. 1 (default) for one-at-a-time tests; 4 for trees traced
    /// through 4-triangle SIMD blocks (scene/block_bvh.hpp), whose leaves
    /// then fill their blocks. A power of two, 1..16 (check_leaf_block).
    unsigned leaf_block = 1;

    /// The SAH weight of n primitives in one leaf: ceil(n / leaf_block).
    float blocks(std::uint32_t n) const noexcept { return leaf_block_weight(n, leaf_block); }
    /// Ci·SA·blocks(n): the cost of a leaf of n primitives with surface area sa.
    float leaf_cost(float sa, std::uint32_t n) const noexcept { return intersection_cost * sa * blocks(n); }
    /// Ct·SA + children: the cost of an inner node over children that cost `children`.
    /// The product is exact in double, so multiply-add fusion cannot change the result (the
    /// device builder computes the same float).
    float split_cost(float sa, float children) const noexcept {
        return static_cast<float>(static_cast<double>(traversal_cost) * sa + children);
    }
    /// Largest primitive count of a merged leaf for the bottom-up builders (0 acts as 1).
    std::uint32_t leaf_limit() const noexcept { return max_leaf_size > 1 ? max_leaf_size : 1u; }
};

/// SAH cost with Ct = Ci = 1:
///   cost = Σ_inner SA(n)/SA(root) + Σ_leaf SA(n)/SA(root) · prims(n).
/// Comparable across builders and with other libraries' trees over the same
/// primitives. Returns 0 for an empty tree; when the root box has no area
/// (all primitives on a point or a line) the ratios are taken as 1.
inline double sah_cost(const Bvh& bvh, double traversal_cost = 1.0, double intersection_cost = 1.0) {
    if (bvh.nodes.empty()) return 0.0;
    const double root = bvh.nodes[0].box.area();
    double cost = 0.0;
    for (const Node& n : bvh.nodes) {
        const double ratio = root > 0.0 ? n.box.area() / root : 1.0;
        cost += n.is_leaf() ? ratio * intersection_cost * n.count : ratio * traversal_cost;
    }
    return cost;
}

}  // namespace raykit
