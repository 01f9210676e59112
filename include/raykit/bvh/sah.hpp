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
