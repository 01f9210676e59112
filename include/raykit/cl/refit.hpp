// raykit/cl/refit.hpp — refitting BVHs on the device, two ways.
//
//   RefitPlan plan(dev, trees);           // once per topology: level and parent tables
//   plan.run(dev, kernels, RefitMethod::one_pass, buffers);   // per frame
//
// Both methods give boxes bit-identical to raykit::refit on the CPU (same
// floats selected by the same min/max rules, see kernels/raykit/kernels/refit.hpp):
//
//   level_wise  one launch per tree level, deepest level first; the levels of
//               all trees are concatenated (one table; level L of every tree
//               is one contiguous run), so L launches refit any number of trees.
//   one_pass    one launch over the leaves of all trees; each leaf walks up
//               through a parent array and the second child to arrive at a
//               node computes it (atomic counters, reset by that child).
//
// Trees live in one concatenated node buffer at known offsets; the plan keeps
// parent and counter arrays for global node indices [0, node_space), so put
// the refitted trees first in the buffer (DeviceScene does).
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/node.hpp"
#include "raykit/cl/buffer.hpp"
#include "raykit/cl/layout.hpp"
#include "raykit/cl/program.hpp"
#include "raykit/kernels/refit.hpp"

namespace raykit::cl {

enum class RefitMethod { level_wise, one_pass };

inline const char* refit_method_name(RefitMethod m) noexcept {
    return m == RefitMethod::level_wise ? "level-wise" : "one-pass";
}

/// One tree to refit: its nodes sit at node_offset in the node buffer and
/// `object` indexes the ObjectRecord table (for its prim/triangle/vertex offsets).
struct RefitTree {
    const Bvh* bvh = nullptr;
    std::uint32_t object = 0;
    std::uint32_t node_offset = 0;
};

/// Program part with the refit kernels.
inline SourcePart refit_part() { return {"raykit/kernels/refit.hpp", kernels::kRefit}; }

/// The device buffers a refit reads and writes.
struct RefitBuffers {
    Buffer<Node>* nodes;
    const Buffer<std::uint32_t>* prim_ids;
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
        for (const RefitTree& t : trees) space = std::max<std::size_t>(space, std::size_t(t.node_offset) + t.bvh->nodes.size());
        if (space >= 0xFFFFFFFFu) throw std::length_error("raykit::cl::RefitPlan: too many nodes");
        std::vector<std::uint32_t> parents(space, kInvalidIndex);
        std::vector<std::vector<cl_uint2>> levels;
        std::vector<cl_uint2> leaves;
        std::vector<int> depth;
        for (const RefitTree& t : trees) {
            const NodeArray& nodes = t.bvh->nodes;
            depth.assign(nodes.size(), 0);
            for (std::size_t i = 0; i < nodes.size(); ++i) {
                const Node& n = nodes[i];
                const auto g = static_cast<cl_uint>(t.node_offset + i);
                if (levels.size() <= std::size_t(depth[i])) levels.resize(depth[i] + 1);
                levels[depth[i]].push_back(cl_uint2{{g, t.object}});
                if (n.is_leaf()) {
                    leaves.push_back(cl_uint2{{g, t.object}});
                } else {
                    if (n.index + 1 >= nodes.size() || n.index <= i)
                        throw std::invalid_argument("raykit::cl::RefitPlan: tree is not in pre-order");
                    depth[n.index] = depth[n.index + 1] = depth[i] + 1;
                    parents[t.node_offset + n.index] = parents[t.node_offset + n.index + 1] = g;
                }
            }
        }
        // deepest level first, each level one contiguous run
        std::vector<cl_uint2> entries;
        for (std::size_t l = levels.size(); l-- > 0;) {
            level_ranges_.push_back({static_cast<std::uint32_t>(entries.size()), static_cast<std::uint32_t>(levels[l].size())});
            entries.insert(entries.end(), levels[l].begin(), levels[l].end());
        }
        leaf_count_ = leaves.size();
        node_count_ = entries.size();
        entries_ = Buffer<cl_uint2>(dev, entries, CL_MEM_READ_ONLY);
        leaves_ = Buffer<cl_uint2>(dev, leaves, CL_MEM_READ_ONLY);
        parents_ = Buffer<std::uint32_t>(dev, parents, CL_MEM_READ_ONLY);
        counters_ = Buffer<std::uint32_t>(dev, std::vector<std::uint32_t>(space, 0u), CL_MEM_READ_WRITE);
    }

    /// Enqueues the refit; returns the number of kernel launches (0 when there is nothing to refit).
    std::size_t run(Device& dev, RefitKernels& k, RefitMethod method, const RefitBuffers& b) {
        if (node_count_ == 0) return 0;
        std::size_t launches = 0;
        if (method == RefitMethod::level_wise) {
            for (const auto& [first, count] : level_ranges_) {
                set_args(k.level, *b.nodes, *b.prim_ids, *b.triangles, *b.positions, *b.objects, entries_, first, count);
                launches += launch(dev.queue(), k.level, count, kGroup);
            }
        } else {
            set_args(k.one_pass, *b.nodes, *b.prim_ids, *b.triangles, *b.positions, *b.objects, leaves_, parents_,
                     counters_, static_cast<std::uint32_t>(leaf_count_));
            launches += launch(dev.queue(), k.one_pass, leaf_count_, kGroup);
        }
        return launches;
    }

    std::size_t levels() const noexcept { return level_ranges_.size(); }
    std::size_t leaves() const noexcept { return leaf_count_; }
    std::size_t nodes() const noexcept { return node_count_; }

private:
    static constexpr std::size_t kGroup = 64;
    struct Range {
        std::uint32_t first, count;
    };
    std::vector<Range> level_ranges_;
    std::size_t leaf_count_ = 0, node_count_ = 0;
    Buffer<cl_uint2> entries_, leaves_;
    Buffer<std::uint32_t> parents_, counters_;
};

}  // namespace raykit::cl
