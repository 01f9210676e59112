// raykit/cl/device_tree.hpp — an object's tree and triangles in the form the device walks.
//
// The device walks the CPU's fastest form (scene/block_bvh.hpp's BlockBvh8): 8-wide
// nodes whose leaves are runs of TriangleBlock4 (four triangles' vertices copied in
// leaf order, structure of arrays), each block tested in one 4-lane watertight test
// (kernels/raykit/kernels/common.hpp rk_wt4_intersect). The blocks themselves and the
// tree are uploaded as the CPU holds them, so the device's traversal steps equal the
// CPU's node and leaf counts for the same tree (figures: kernels/raykit/kernels/trace.hpp).
//
//   device_tree(blocks)     node 0 holds the root box alone in slot 0 (its inner child
//                           is node 1: the twin of the CPU's first test of
//                           WideBvhT::bounds, refitted like any node); nodes 1.. are the
//                           BlockBvh8's with inner indices + 1; leaves name block runs.
//                           DeviceScene uploads a Scene object's BlockBvh8 (the very
//                           tree the CPU's queries walk, refitted in place since it was
//                           made); MeshTracer makes one from the given Bvh.
// Dynamic objects rewrite their blocks on the device in the refit's leaf step
// (kernels/raykit/kernels/refit.hpp), after the vertex stage: no read-back.
#pragma once

#include <cstdint>
#include <vector>

#include "raykit/bvh/wide.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/scene/block_bvh.hpp"

namespace raykit::cl {

/// A tree in the device's form: nodes (node 0 the root box alone) and the leaves' blocks.
struct DeviceTree {
    std::vector<DeviceNode> nodes;
    std::vector<TriangleBlock4> blocks;
};

/// The device form of `b` (see the header comment); empty for an empty tree.
inline DeviceTree device_tree(const BlockBvhT<kDeviceWidth>& b) {
    DeviceTree out;
    if (b.tree.nodes.empty()) return out;
    out.blocks.assign(b.blocks.begin(), b.blocks.end());
    out.nodes.resize(b.tree.nodes.size() + 1);
    DeviceNode& root = out.nodes[0];
    for (int c = 0; c < kDeviceWidth; ++c) root.clear(c);
    root.set_box(0, b.tree.bounds);
    root.index[0] = 1;
    root.count[0] = 0;
    for (std::size_t i = 0; i < b.tree.nodes.size(); ++i) {
        DeviceNode& n = out.nodes[i + 1];
        n = b.tree.nodes[i];
        for (int c = 0; c < kDeviceWidth; ++c)
            if (n.count[c] == 0 && !b.tree.nodes[i].unused(c)) ++n.index[c];
    }
    return out;
}

}  // namespace raykit::cl
