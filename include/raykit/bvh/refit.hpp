// raykit/bvh/refit.hpp — bottom-up refit on the CPU, in place.
#pragma once

#include "raykit/bvh/node.hpp"

namespace raykit {

/// Recomputes every box from the primitives' current boxes, keeping the
/// topology. `prim_box(i)` returns the AABB of primitive i. Since children are
/// stored after their parent, one reverse sweep visits children first.
/// Bit-exact and order-independent: boxes are min/max of the same floats.
template <class PrimBoxFn>
void refit(Bvh& bvh, PrimBoxFn&& prim_box) {
    for (std::size_t i = bvh.nodes.size(); i-- > 0;) {
        Node& n = bvh.nodes[i];
        AABB b;
        if (n.is_leaf()) {
            for (std::uint32_t k = 0; k < n.count; ++k) b.grow(prim_box(bvh.prim_ids[n.index + k]));
        } else {
            b = merge(bvh.nodes[n.index].box, bvh.nodes[n.index + 1].box);
        }
        n.box = b;
    }
}

}  // namespace raykit
