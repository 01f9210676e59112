// raykit/cl/refit.hpp — refitting the objects' wide trees on the device, two ways.
//
//   RefitPlan plan(dev, trees);           // once per topology: level and parent tables
//   plan.run(dev, kernels, RefitMethod::one_pass, buffers);   // per frame
//
// Both methods give boxes bit-identical to raykit::refit on the CPU (same
// floats selected by the same min/max rules, see kernels/raykit/kernels/refit.hpp):
// the CPU's BlockBvh8 refitted in place, and rewrite the refitted trees'
// blocks from the current vertices.
//
//   level_wise  one launch per tree level, deepest level first; the levels of
//               all trees are concatenated (one table; level L of every tree
//               is one contiguous run), so L launches refit any number of trees.
//   one_pass    one launch over the nodes without inner children of all trees;
//               each walks up through a parent array and the last inner child
//               to arrive at a node computes it (atomic counters, reset by it).
//
// Trees live in one concatenated node buffer at known offsets; the plan keeps
// parent and counter arrays for global node indices [0, node_space), so put
// the refitted trees first in the buffer (DeviceScene does).
//
// A tree with spare capacity (RefitTree::capacity, for device rebuilds) makes the plan
// node-indexed: one one-pass start entry per node of every range, (RK_INVALID, 0) where the
// node has inner children or is unused, so a device build can rewrite its range's tables
// without the host (cl/device_build.hpp). The level-wise method needs the host's level
// tables, so after a device rebuild (mark_rebuilt_on_device) it throws.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/node.hpp"
#include "raykit/cl/device_tree.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/kernels/refit.hpp"

namespace raykit::cl {

enum class RefitMethod { level_wise, one_pass };

inline const char* refit_method_name(RefitMethod m) noexcept {
    return m == RefitMethod::level_wise ? "level-wise" : "one-pass";
}

/// One tree to refit: its nodes (device_tree()'s, as uploaded) sit at node_offset in the node
/// buffer and `object` indexes the ObjectRecord table (for its prim/triangle/vertex offsets).
struct RefitTree {
    std::span<const DeviceNode> nodes;
    std::uint32_t object = 0;
    std::uint32_t node_offset = 0;
    /// Nodes reserved for the tree (0: nodes.size()); more when it may be rebuilt on the
    /// device into a tree of another size (cl/device_build.hpp).
    std::uint32_t capacity = 0;
};

/// The one-pass refit's tables, which a device build rewrites for its object's node range.
struct RefitTables {
    Buffer<std::uint32_t>* parents;  ///< per global node: parent node, or RK_INVALID
    Buffer<std::uint32_t>* needs;    ///< per global node: inner children
    Buffer<cl_uint2>* starts;        ///< per global node (node-indexed plans): (node, object) or (RK_INVALID, 0)
};

/// Program part with the refit kernels.
inline SourcePart refit_part() { return {"raykit/kernels/refit.hpp", kernels::kRefit}; }

/// The device buffers a refit reads and writes.
struct RefitBuffers {
    Buffer<DeviceNode>* nodes;
    Buffer<TriangleBlock4>* blocks;  ///< rewritten for the refitted trees' leaves
    const Buffer<Triangle>* triangles;
    const Buffer<float>* positions;
    const Buffer<ObjectRecord>* objects;
};

/// Kernels of a program that contains refit_part().
struct RefitKernels {
    ::cl::Kernel level, one_pass;
    explicit RefitKernels(const Program& p) : level(p.kernel("rk_refit_level")), one_pass(p.kernel("rk_refit_one_pass")) {}
    RefitKernels() = default;
};

/// Topology tables for refitting a set of trees (valid while their topology holds).
class RefitPlan {
public:
    RefitPlan() = default;
    RefitPlan(Device& dev, std::span<const RefitTree> trees) {
        std::size_t space = 0;
        for (const RefitTree& t : trees) {
            if (t.capacity != 0 && t.capacity < t.nodes.size())
                throw std::invalid_argument("raykit::cl::RefitPlan: a tree's capacity is smaller than the tree");
            space = std::max<std::size_t>(space, std::size_t(t.node_offset) + std::max<std::size_t>(t.capacity, t.nodes.size()));
            node_indexed_ = node_indexed_ || t.capacity > t.nodes.size();
        }
        if (space >= 0xFFFFFFFFu) throw std::length_error("raykit::cl::RefitPlan: too many nodes");
        std::vector<std::uint32_t> parents(space, kInvalidIndex), needs(space, 0u);
        std::vector<std::vector<cl_uint2>> levels;
        std::vector<cl_uint2> starts;
        std::vector<int> depth;
        for (const RefitTree& t : trees) {
            depth.assign(t.nodes.size(), 0);
            for (std::size_t i = 0; i < t.nodes.size(); ++i) {
                const DeviceNode& n = t.nodes[i];
                const auto g = static_cast<cl_uint>(t.node_offset + i);
                if (levels.size() <= std::size_t(depth[i])) levels.resize(std::size_t(depth[i]) + 1);
                levels[std::size_t(depth[i])].push_back(cl_uint2{{g, t.object}});
                for (int c = 0; c < kDeviceWidth; ++c) {
                    if (n.count[c] != 0 || n.unused(c)) continue;
                    if (n.index[c] >= t.nodes.size() || n.index[c] <= i)
                        throw std::invalid_argument("raykit::cl::RefitPlan: a child does not come after its parent");
                    depth[n.index[c]] = depth[i] + 1;
                    parents[t.node_offset + n.index[c]] = g;
                    ++needs[g];
                }
            }
            for (std::size_t i = 0; i < t.nodes.size(); ++i)
                if (needs[t.node_offset + i] == 0) starts.push_back(cl_uint2{{static_cast<cl_uint>(t.node_offset + i), t.object}});
        }
        // deepest level first, each level one contiguous run
        std::vector<cl_uint2> entries;
        for (std::size_t l = levels.size(); l-- > 0;) {
            level_ranges_.push_back({static_cast<std::uint32_t>(entries.size()), static_cast<std::uint32_t>(levels[l].size())});
            entries.insert(entries.end(), levels[l].begin(), levels[l].end());
        }
        if (node_indexed_) {
            std::vector<cl_uint2> by_node(space, cl_uint2{{kInvalidIndex, 0u}});
            for (const cl_uint2& e : starts) by_node[e.s[0]] = e;
            starts = std::move(by_node);
        }
        start_count_ = starts.size();
        node_count_ = entries.size();
        if (node_count_ == 0) return;
        entries_ = Buffer<cl_uint2>(dev, entries, CL_MEM_READ_ONLY);
        starts_ = Buffer<cl_uint2>(dev, starts);
        parents_ = Buffer<std::uint32_t>(dev, parents);
        needs_ = Buffer<std::uint32_t>(dev, needs);
        counters_ = Buffer<std::uint32_t>(dev, std::vector<std::uint32_t>(space, 0u), CL_MEM_READ_WRITE);
    }

    /// Enqueues the refit; returns the number of kernel launches (0 when there is nothing to refit).
    std::size_t run(Device& dev, RefitKernels& k, RefitMethod method, const RefitBuffers& b) {
        if (node_count_ == 0) return 0;
        std::size_t launches = 0;
        if (method == RefitMethod::level_wise) {
            if (rebuilt_)
                throw std::logic_error("raykit::cl::RefitPlan: level-wise refit after a device rebuild (its level tables "
                                       "are the host's); use RefitMethod::one_pass");
            for (const auto& [first, count] : level_ranges_) {
                set_args(k.level, *b.nodes, *b.blocks, *b.triangles, *b.positions, *b.objects, entries_, first, count);
                launches += launch(dev.queue(), k.level, count, kGroup);
            }
        } else {
            set_args(k.one_pass, *b.nodes, *b.blocks, *b.triangles, *b.positions, *b.objects, starts_, parents_, needs_,
                     counters_, static_cast<std::uint32_t>(start_count_));
            launches += launch(dev.queue(), k.one_pass, start_count_, kGroup);
        }
        return launches;
    }

    /// Whether start entries are one per node (some tree has spare capacity).
    bool node_indexed() const noexcept { return node_indexed_; }
    /// The one-pass tables, for a device build to rewrite (node-indexed plans only).
    RefitTables tables() {
        if (!node_indexed_) throw std::logic_error("raykit::cl::RefitPlan::tables: the plan is not node-indexed");
        return {&parents_, &needs_, &starts_};
    }
    /// A device build rewrote some range: the level tables no longer hold.
    void mark_rebuilt_on_device() noexcept { rebuilt_ = true; }
    /// Rewrites the one-pass tables of t's node range [node_offset, node_offset + capacity)
    /// from a host tree (a tree built on the CPU after the plan was made; node-indexed plans).
    void write_tree(Device& dev, const RefitTree& t) {
        if (!node_indexed_) throw std::logic_error("raykit::cl::RefitPlan::write_tree: the plan is not node-indexed");
        const std::size_t cap = t.capacity != 0 ? t.capacity : t.nodes.size();
        if (t.nodes.size() > cap || std::size_t(t.node_offset) + cap > start_count_)
            throw std::invalid_argument("raykit::cl::RefitPlan::write_tree: the tree does not fit its range");
        std::vector<std::uint32_t> parents(cap, kInvalidIndex), needs(cap, 0u);
        std::vector<cl_uint2> starts(cap, cl_uint2{{kInvalidIndex, 0u}});
        for (std::size_t i = 0; i < t.nodes.size(); ++i) {
            const DeviceNode& n = t.nodes[i];
            for (int c = 0; c < kDeviceWidth; ++c) {
                if (n.count[c] != 0 || n.unused(c)) continue;
                if (n.index[c] >= t.nodes.size() || n.index[c] <= i)
                    throw std::invalid_argument("raykit::cl::RefitPlan: a child does not come after its parent");
                parents[n.index[c]] = static_cast<std::uint32_t>(t.node_offset + i);
                ++needs[i];
            }
        }
        for (std::size_t i = 0; i < t.nodes.size(); ++i)
            if (needs[i] == 0) starts[i] = cl_uint2{{static_cast<cl_uint>(t.node_offset + i), t.object}};
        parents_.write(dev, std::span<const std::uint32_t>(parents), t.node_offset);
        needs_.write(dev, std::span<const std::uint32_t>(needs), t.node_offset);
        starts_.write(dev, std::span<const cl_uint2>(starts), t.node_offset);
        rebuilt_ = true;
    }

    /// Launches of the level-wise method (tree levels, node 0 included).
    std::size_t levels() const noexcept { return level_ranges_.size(); }
    /// Work items of the one-pass method: nodes without inner children (node-indexed: all nodes).
    std::size_t leaves() const noexcept { return start_count_; }
    /// Wide nodes refitted.
    std::size_t nodes() const noexcept { return node_count_; }

private:
    static constexpr std::size_t kGroup = 64;
    struct Range {
        std::uint32_t first, count;
    };
    std::vector<Range> level_ranges_;
    std::size_t start_count_ = 0, node_count_ = 0;
    bool node_indexed_ = false, rebuilt_ = false;
    Buffer<cl_uint2> entries_, starts_;
    Buffer<std::uint32_t> parents_, needs_, counters_;
};

}  // namespace raykit::cl
