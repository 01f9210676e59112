// raykit/bvh/validate.hpp — structural check of a tree.
#pragma once

#include <cstdint>
#include <functional>
#include <span>
#include <string>
#include <vector>

#include "raykit/bvh/node.hpp"

namespace raykit {

/// Checks that: the tree is in pre-order (children after their parent, inside
/// the array, reached exactly once), every primitive 0..n-1 appears in exactly
/// one leaf, every box encloses its children's boxes and its primitives' boxes,
/// and the depth is at most `max_depth`. Returns "" when valid, else the first
/// problem found, with the values involved.
inline std::string validate(const Bvh& bvh, std::span<const AABB> prim_boxes,
                            int max_depth = RAYKIT_BVH_MAX_DEPTH) {
    const std::size_t n = prim_boxes.size();
    if (bvh.nodes.empty())
        return n == 0 && bvh.prim_ids.empty() ? "" : "empty tree over " + std::to_string(n) + " primitives";
    if (bvh.prim_ids.size() != n)
        return "prim_ids has " + std::to_string(bvh.prim_ids.size()) + " entries for " + std::to_string(n) +
               " primitives";
    std::vector<std::uint8_t> seen_prim(n, 0), seen_node(bvh.nodes.size(), 0);
    std::vector<int> depth(bvh.nodes.size(), 0);
    seen_node[0] = 1;
    std::size_t slots = 0;
    for (std::size_t i = 0; i < bvh.nodes.size(); ++i) {
        const Node& nd = bvh.nodes[i];
        const std::string at = "node " + std::to_string(i) + ": ";
        if (!seen_node[i]) return at + "not reachable from the root";
        if (depth[i] > max_depth)
            return at + "depth " + std::to_string(depth[i]) + " exceeds " + std::to_string(max_depth);
        if (nd.is_leaf()) {
            if (std::uint64_t(nd.index) + nd.count > bvh.prim_ids.size())
                return at + "leaf range [" + std::to_string(nd.index) + ", +" + std::to_string(nd.count) +
                       ") outside prim_ids";
            slots += nd.count;
            for (std::uint32_t k = 0; k < nd.count; ++k) {
                const std::uint32_t p = bvh.prim_ids[nd.index + k];
                if (p >= n) return at + "primitive id " + std::to_string(p) + " out of range";
                if (seen_prim[p]++) return at + "primitive " + std::to_string(p) + " appears twice";
                if (!nd.box.contains(prim_boxes[p]))
                    return at + "box does not enclose primitive " + std::to_string(p);
            }
        } else {
            if (nd.index <= i || std::uint64_t(nd.index) + 1 >= bvh.nodes.size())
                return at + "children at " + std::to_string(nd.index) + " are not after the node / in range";
            for (std::uint32_t c = nd.index; c <= nd.index + 1; ++c) {
                if (seen_node[c]++) return at + "child " + std::to_string(c) + " reached twice";
                depth[c] = depth[i] + 1;
                if (!nd.box.contains(bvh.nodes[c].box))
                    return at + "box does not enclose child " + std::to_string(c);
            }
        }
    }
    if (slots != n) return "leaves hold " + std::to_string(slots) + " slots for " + std::to_string(n) + " primitives";
    return "";
}

}  // namespace raykit
