// raykit/bvh/depth.hpp — the depth bound every builder keeps.
//
// Proof sketch of the bound: a builder may split however it likes while a
// node's depth is below kMedianDepth = RAYKIT_BVH_MAX_DEPTH − 32; from there on
// it must split at the median (halving the primitive count), and a range of at
// most 2^32 primitives needs at most 32 halvings to reach one primitive. So no
// leaf is deeper than RAYKIT_BVH_MAX_DEPTH, and traversal, which pushes at most
// one node per level, never needs more stack entries than that.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>

#include "raykit/bvh/node.hpp"

namespace raykit {

/// Depth from which builders switch to median splits.
inline constexpr int kMedianDepth = RAYKIT_BVH_MAX_DEPTH - 32;

namespace detail {

/// Sorts ids[begin, end) so that the first half has the smaller centroids on
/// `axis` (ties broken by id, so the result depends on the set, not its order)
/// and returns the split point.
inline std::uint32_t median_partition(std::span<std::uint32_t> ids, std::uint32_t begin, std::uint32_t end,
                                      std::span<const vec3> centers, int axis) {
    const std::uint32_t mid = begin + (end - begin) / 2;
    std::nth_element(ids.begin() + begin, ids.begin() + mid, ids.begin() + end,
                     [&](std::uint32_t a, std::uint32_t b) {
                         const float ca = centers[a][axis], cb = centers[b][axis];
                         return ca < cb || (ca == cb && a < b);
                     });
    return mid;
}

/// Rewrites a tree whose inner node `index` fields point to adjacent child
/// pairs anywhere in `tmp` into depth-first pre-order with no gaps: the one
/// node layout. The builders write it directly; the tests hold them to it.
inline NodeArray compact_preorder(const std::vector<Node>& tmp, std::uint32_t root = 0) {
    NodeArray out;
    if (tmp.empty()) return out;
    out.reserve(tmp.size());
    out.push_back(tmp[root]);
    struct Item {
        std::uint32_t old_idx, new_idx;
    };
    std::vector<Item> stack{{root, 0}};
    while (!stack.empty()) {
        const Item it = stack.back();
        stack.pop_back();
        const Node& n = tmp[it.old_idx];
        if (n.is_leaf()) continue;
        const auto first = static_cast<std::uint32_t>(out.size());
        out.push_back(tmp[n.index]);
        out.push_back(tmp[n.index + 1]);
        out[it.new_idx].index = first;
        stack.push_back({n.index + 1, first + 1});
        stack.push_back({n.index, first});
    }
    return out;
}

}  // namespace detail
}  // namespace raykit
