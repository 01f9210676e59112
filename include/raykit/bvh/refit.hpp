// raykit/bvh/refit.hpp — bottom-up refit on the CPU, in place, for every tree shape.
//
// Children are stored after their parent (binary and wide trees alike), so one reverse sweep
// visits children first. Bit-exact and order-independent: boxes are min/max of the same floats,
// so a refitted wide tree equals the wide tree collapsed from the refitted binary one.
#pragma once

#include <cstdint>

#include "raykit/bvh/node.hpp"
#include "raykit/bvh/wide.hpp"

namespace raykit {

/// Recomputes every box from the primitives' current boxes, keeping the
/// topology. `prim_box(i)` returns the AABB of primitive i.
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

namespace detail {

/// The wide sweep: `leaf_box(index, count)` is the box of a leaf slot's contents. Returns the root box.
template <class NodeVec, class LeafBoxFn>
AABB refit_wide_nodes(NodeVec& nodes, LeafBoxFn&& leaf_box) {
    constexpr int W = std::remove_reference_t<decltype(nodes[0])>::kWidth;
    AABB root;
    for (std::size_t i = nodes.size(); i-- > 0;) {
        auto& n = nodes[i];
        AABB all;
        for (int c = 0; c < W; ++c) {
            if (n.unused(c)) continue;
            AABB b;
            if (n.count[c] != 0) {
                b = leaf_box(n.index[c], n.count[c]);
            } else {
                const auto& child = nodes[n.index[c]];
                for (int k = 0; k < W; ++k)
                    if (!child.unused(k)) b.grow(child.box(k));
            }
            n.set_box(c, b);
            all.grow(b);
        }
        root = all;
    }
    return root;
}

}  // namespace detail

/// The same for a 4- or 8-wide tree (and its root `bounds`).
template <int W, class PrimBoxFn>
void refit(WideBvhT<W>& wide, PrimBoxFn&& prim_box) {
    if (wide.nodes.empty()) return;
    wide.bounds = detail::refit_wide_nodes(wide.nodes, [&](std::uint32_t first, std::uint32_t count) {
        AABB b;
        for (std::uint32_t k = first; k < first + count; ++k) b.grow(prim_box(wide.prim_ids[k]));
        return b;
    });
}

}  // namespace raykit
