// raykit/bvh/sah.hpp — surface-area-heuristic cost of a finished tree.
#pragma once

#include "raykit/bvh/node.hpp"

namespace raykit {

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
