// raykit/cl/device_tree.hpp — an object's tree and triangles in the form the device walks.
//
// The device walks the CPU's fastest tree shape: the binary Bvh collapsed to
// WideBvhT<kDeviceWidth> (8-wide, bvh/wide.hpp), whose leaves read triangles in
// leaf order. Measured on PoCL (2 cores, bench_render thesis/full, 1 spp): the
// binary walk over prim_ids → triangle → three vertex indices → positions took
// 28.7 ms for camera rays and 17.1 ms for shadow rays; see the README of the
// branch's report for the 8-wide figures.
//
//   device_tree(tree)         node 0 holds the root box alone in slot 0 (its inner
//                             child is node 1: the twin of the CPU's first test of
//                             WideBvhT::bounds, refitted like any node); nodes 1.. are
//                             the wide tree's with inner indices + 1; leaves are slot
//                             ranges of DeviceTree::prims. From a Bvh (collapsed: what
//                             MeshTracer uploads) or from a Scene object's BlockBvh8
//                             (what DeviceScene uploads: the very tree the CPU's
//                             queries walk, so traversal steps agree even after a
//                             refit changed which binary nodes a new collapse would
//                             merge).
//   gather_leaf_positions     per prim_ids slot k, the three vertices of triangle
//                             prim_ids[k] (9 floats): a leaf reads contiguous memory.
//                             Dynamic objects re-gather on the device in the refit's
//                             leaf step (kernels/raykit/kernels/refit.hpp).
#pragma once

#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/node.hpp"
#include "raykit/bvh/wide.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/scene/block_bvh.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit::cl {

/// A tree in the device's form: nodes (node 0 the root box alone) and the triangle of each
/// leaf slot (leaves name slot ranges of `prims`).
struct DeviceTree {
    std::vector<DeviceNode> nodes;
    std::vector<std::uint32_t> prims;
};

/// The device form of a wide tree whose leaves are prim_ids slot ranges.
inline DeviceTree device_tree(const WideBvhT<kDeviceWidth>& w) {
    DeviceTree out;
    if (w.nodes.empty()) return out;
    out.prims = w.prim_ids;
    out.nodes.resize(w.nodes.size() + 1);
    DeviceNode& root = out.nodes[0];
    for (int c = 0; c < kDeviceWidth; ++c) root.clear(c);
    root.set_box(0, w.bounds);
    root.index[0] = 1;
    root.count[0] = 0;
    for (std::size_t i = 0; i < w.nodes.size(); ++i) {
        DeviceNode& n = out.nodes[i + 1];
        n = w.nodes[i];
        for (int c = 0; c < kDeviceWidth; ++c)
            if (n.count[c] == 0 && !w.nodes[i].unused(c)) ++n.index[c];
    }
    return out;
}

/// The device form of a binary tree: collapsed to kDeviceWidth wide (bvh/wide.hpp).
inline DeviceTree device_tree(const Bvh& bvh) { return device_tree(WideBvhT<kDeviceWidth>::collapse(bvh)); }

/// The device form of the tree of `blocks` (the one a Scene's CPU queries walk, refitted in
/// place since it was made): the same nodes and boxes, each leaf's blocks turned back into a
/// slot range of its triangles (the lanes a leaf's last block repeats dropped).
inline DeviceTree device_tree(const BlockBvhT<kDeviceWidth>& blocks) {
    WideBvhT<kDeviceWidth> w;
    w.nodes = blocks.tree.nodes;
    w.bounds = blocks.tree.bounds;
    for (auto& n : w.nodes)
        for (int c = 0; c < kDeviceWidth; ++c) {
            if (n.count[c] == 0) continue;
            const std::uint32_t first = static_cast<std::uint32_t>(w.prim_ids.size());
            if (std::size_t(n.index[c]) + n.count[c] > blocks.blocks.size())
                throw std::invalid_argument("raykit::cl::device_tree: a leaf names blocks outside the tree");
            for (std::uint32_t k = n.index[c]; k < n.index[c] + n.count[c]; ++k) {
                const TriangleBlock4& b = blocks.blocks[k];
                const bool last = k + 1 == n.index[c] + n.count[c];
                for (int i = 0; i < 4; ++i) {
                    if (last && i > 0 && b.prim[i] == b.prim[i - 1]) break;  // the leaf's last triangle, repeated
                    w.prim_ids.push_back(b.prim[i]);
                }
            }
            n.index[c] = first;
            n.count[c] = static_cast<std::uint32_t>(w.prim_ids.size()) - first;
        }
    return device_tree(w);
}

/// Appends the leaf-ordered positions of `mesh`'s triangles prim_ids[0..) (9 floats per slot).
inline void gather_leaf_positions(const MeshView& mesh, std::span<const std::uint32_t> prim_ids,
                                  std::vector<float>& out) {
    out.reserve(out.size() + 9 * prim_ids.size());
    for (const std::uint32_t p : prim_ids) {
        if (p >= mesh.size()) throw std::invalid_argument("raykit::cl::gather_leaf_positions: prim id outside the mesh");
        for (int c = 0; c < 3; ++c) {
            const vec3& v = mesh.vertex(p, c);
            out.insert(out.end(), {v.x, v.y, v.z});
        }
    }
}

}  // namespace raykit::cl
