// raykit/bvh/wide.hpp — a 4- or 8-wide BVH collapsed from a binary one, for CPU traversal.
//
//   Bvh bvh = BinnedSahBuilder::build(boxes, centers);   // any builder
//   WideBvh wide = WideBvh::build(bvh);                   // 4-wide, collapsed; or build(std::move(bvh))
//   WideBvh8 wide8 = WideBvh8::build(bvh);                // 8-wide (one AVX test per node)
//   Hit h = intersect_closest(mesh, wide, ray);           // scene/trace.hpp
//
// The binary Bvh (bvh/node.hpp) stays the canonical tree: every builder makes
// one, refit updates it, the OpenCL path uploads it. A WideBvh is derived from
// it in one O(nodes) pass for the CPU's single-ray traversal, where testing
// 4 (SSE) or 8 (AVX) boxes in one operation and walking a shallower tree pays:
// every inner node of the binary tree with inner children is merged with them,
// the child of largest surface area opened first, until a node has W children
// or only leaves. Leaves are the binary tree's leaves unchanged (same
// prim_ids ranges), so both trees return the same hits. After a binary refit,
// collapse again (linear, no SAH work).
//
// WideNode (W = 4) is 128 bytes on a 64-byte boundary (two cache lines),
// WideNode8 256 bytes: the six box planes of the W children as
// structure-of-arrays (lo.x[W], hi.x[W], lo.y[W], ...), then per child an index (a WideNode for inner children, the first
// prim_ids slot for leaves) and a primitive count (0 = inner child). Unused
// slots have an empty box (lo = +inf, hi = -inf) that no ray can enter, so the
// traversal needs no per-slot validity check. The wide tree is no deeper than
// the binary one, so its stack bound follows from RAYKIT_BVH_MAX_DEPTH.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <new>
#include <span>
#include <string>
#include <stdexcept>
#include <type_traits>
#include <utility>
#include <vector>

#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/util/block_cache.hpp"

namespace raykit {

template <int W>
struct alignas(64) WideNodeT {
    static_assert(W == 4 || W == 8, "wide nodes have 4 or 8 children");
    static constexpr int kWidth = W;
    /// Planes as [axis*2 + (0 = lo, 1 = hi)][child].
    float planes[6][std::size_t(kWidth)];
    std::uint32_t index[std::size_t(kWidth)];  ///< inner child: WideNode index; leaf: first prim_ids slot
    std::uint32_t count[std::size_t(kWidth)];  ///< 0: inner child (or unused slot); > 0: leaf primitive count

    bool is_leaf(int i) const noexcept { return count[i] != 0; }
    /// An unused slot: no leaf, no inner child (inner children are never node 0).
    bool unused(int i) const noexcept { return count[i] == 0 && index[i] == 0; }
    AABB box(int i) const noexcept {
        return {{planes[0][i], planes[2][i], planes[4][i]}, {planes[1][i], planes[3][i], planes[5][i]}};
    }
    void set_box(int i, const AABB& b) noexcept {
        for (int a = 0; a < 3; ++a) {
            planes[2 * a][i] = b.min[a];
            planes[2 * a + 1][i] = b.max[a];
        }
    }
    void clear(int i) noexcept {
        for (int a = 0; a < 3; ++a) {
            planes[2 * a][i] = std::numeric_limits<float>::infinity();
            planes[2 * a + 1][i] = -std::numeric_limits<float>::infinity();
        }
        index[i] = 0;
        count[i] = 0;
    }
};
using WideNode = WideNodeT<4>;   ///< 128 bytes: 4 children, one SSE box test
using WideNode8 = WideNodeT<8>;  ///< 256 bytes: 8 children, one AVX box test
static_assert(sizeof(WideNode) == 128 && alignof(WideNode) == 64);
static_assert(std::is_standard_layout_v<WideNode>);
static_assert(offsetof(WideNode, planes) == 0 && offsetof(WideNode, index) == 96 && offsetof(WideNode, count) == 112);
static_assert(sizeof(WideNode8) == 256 && alignof(WideNode8) == 64);
static_assert(std::is_standard_layout_v<WideNode8>);
static_assert(offsetof(WideNode8, planes) == 0 && offsetof(WideNode8, index) == 192 && offsetof(WideNode8, count) == 224);

/// Allocator that aligns to 64 bytes (one WideNode starts each cache line pair); large arrays
/// come from and go back to detail::BlockCache (util/block_cache.hpp).
template <class T>
struct CacheLineAllocator {
    static_assert(alignof(T) <= 64);
    using value_type = T;
    CacheLineAllocator() = default;
    template <class U>
    CacheLineAllocator(const CacheLineAllocator<U>&) noexcept {}  // NOLINT implicit
    T* allocate(std::size_t n) { return static_cast<T*>(detail::BlockCache::get().allocate(n * sizeof(T))); }
    void deallocate(T* p, std::size_t n) noexcept { detail::BlockCache::get().deallocate(p, n * sizeof(T)); }
    template <class U>
    bool operator==(const CacheLineAllocator<U>&) const noexcept {
        return true;
    }
};

template <int W>
struct WideBvhT {
    using NodeType = WideNodeT<W>;
    static constexpr int kWidth = W;
    std::vector<NodeType, CacheLineAllocator<NodeType>> nodes;  ///< node 0 is the root
    std::vector<std::uint32_t> prim_ids;                        ///< as in the binary tree
    AABB bounds;  ///< the root's box: tested first, so rays that miss the scene touch no node

    bool empty() const noexcept { return nodes.empty(); }
    std::size_t memory_bytes() const noexcept {
        return nodes.size() * sizeof(NodeType) + prim_ids.size() * sizeof(std::uint32_t);
    }

    /// Builds the wide tree of a binary one by collapsing it (copies its prim_ids, 4 bytes per
    /// primitive).
    static WideBvhT build(const Bvh& bvh) {
        WideBvhT w;
        w.prim_ids = bvh.prim_ids;
        w.build_nodes(bvh);
        return w;
    }
    /// Builds from a binary tree that is no longer needed (takes its prim_ids).
    static WideBvhT build(Bvh&& bvh) {
        WideBvhT w;
        w.build_nodes(bvh);
        w.prim_ids = std::move(bvh.prim_ids);
        bvh.nodes.clear();
        return w;
    }
    /// The name build() had before 0.2 (every raykit tree is now made by a `build`).
    [[deprecated("raykit: use WideBvhT::build")]] static WideBvhT collapse(const Bvh& bvh) { return build(bvh); }
    [[deprecated("raykit: use WideBvhT::build")]] static WideBvhT collapse(Bvh&& bvh) { return build(std::move(bvh)); }

    /// Depth of the deepest wide node (root = 0).
    int depth() const {
        int best = 0;
        std::vector<int> d(nodes.size(), 0);
        for (std::size_t i = 0; i < nodes.size(); ++i) {
            best = std::max(best, d[i]);
            for (int c = 0; c < W; ++c)
                if (nodes[i].count[c] == 0 && !nodes[i].unused(c)) d[nodes[i].index[c]] = d[i] + 1;
        }
        return best;
    }

    /// Structural check against the primitives' boxes: "" when every prim_ids
    /// slot is in exactly one leaf, every child box encloses everything below
    /// it, inner children come after their parent and unused slots are empty;
    /// otherwise what is wrong first.
    std::string validate(std::span<const AABB> prim_boxes) const {
        if (nodes.empty()) return prim_ids.empty() ? "" : "no nodes but primitives";
        std::vector<std::uint8_t> seen(prim_ids.size(), 0);
        std::string err;
        // bounds of everything below slot c of node i, checked against its box
        const auto below = [&](auto&& self, std::uint32_t i, int c) -> AABB {
            const NodeType& n = nodes[i];
            AABB b;
            if (n.count[c] != 0) {
                if (std::size_t(n.index[c]) + n.count[c] > prim_ids.size()) {
                    err = "leaf range out of bounds";
                    return b;
                }
                for (std::uint32_t k = n.index[c]; k < n.index[c] + n.count[c]; ++k) {
                    if (seen[k]++) err = "prim_ids slot " + std::to_string(k) + " in two leaves";
                    if (prim_ids[k] >= prim_boxes.size()) {
                        err = "prim id out of range";
                        return b;
                    }
                    b.grow(prim_boxes[prim_ids[k]]);
                }
            } else {
                if (n.index[c] <= i || n.index[c] >= nodes.size()) {
                    err = "inner child index " + std::to_string(n.index[c]) + " of node " + std::to_string(i);
                    return b;
                }
                const NodeType& child = nodes[n.index[c]];
                for (int k = 0; k < W && err.empty(); ++k) {
                    if (child.unused(k)) {
                        if (!child.box(k).is_empty()) err = "unused slot with a box";
                        continue;
                    }
                    b.grow(self(self, n.index[c], k));
                }
            }
            const AABB box = n.box(c);
            if (!b.is_empty() && !box.contains(b))
                err = "box of node " + std::to_string(i) + " slot " + std::to_string(c) + " does not enclose its children";
            return b;
        };
        for (int c = 0; c < W && err.empty(); ++c) {
            const NodeType& root = nodes[0];
            if (root.unused(c)) {
                if (!root.box(c).is_empty()) err = "unused slot with a box";
                continue;
            }
            below(below, 0, c);
        }
        if (err.empty())
            for (std::size_t k = 0; k < seen.size(); ++k)
                if (!seen[k]) return "prim_ids slot " + std::to_string(k) + " in no leaf";
        return err;
    }

private:
    void build_nodes(const Bvh& bvh) {
        nodes.clear();
        bounds = AABB{};
        if (bvh.nodes.empty()) return;
        bounds = bvh.nodes[0].box;
        const std::size_t n = bvh.nodes.size();
        nodes.reserve(n / 2 + 1);
        const auto check = [&](std::uint32_t i) {
            if (i >= n) throw std::invalid_argument("raykit::WideBvh::build: child index out of range");
        };
        struct Task {
            std::uint32_t binary;  // binary inner node whose subtree becomes wide node `wide`
            std::uint32_t wide;
        };
        std::vector<Task> todo;
        nodes.emplace_back();
        const Node& root = bvh.nodes[0];
        if (root.is_leaf()) {
            for (int c = 0; c < W; ++c) nodes[0].clear(c);
            nodes[0].set_box(0, root.box);
            nodes[0].index[0] = root.index;
            nodes[0].count[0] = root.count;
            return;
        }
        todo.push_back({0, 0});
        while (!todo.empty()) {
            const Task task = todo.back();
            todo.pop_back();
            // open the children of largest area until 4 or only leaves
            std::uint32_t kids[std::size_t(W) + 1];
            int k = 0;
            const Node& b = bvh.nodes[task.binary];
            check(b.index + 1);
            kids[k++] = b.index;
            kids[k++] = b.index + 1;
            while (k < W) {
                int best = -1;
                float best_area = -1.0f;
                for (int i = 0; i < k; ++i) {
                    const Node& c = bvh.nodes[kids[i]];
                    if (c.is_leaf()) continue;
                    // its children are read when it is opened here or becomes a wide node's root:
                    // each opening waited on a cache miss (70 % of the collapse's samples); with the
                    // prefetch the 1M-triangle torus collapses in 12-14 ms instead of 21-23
                    if (c.index < n) __builtin_prefetch(bvh.nodes.data() + c.index);
                    const float a = fused_proof_half_area(c.box);
                    if (best < 0 || a > best_area) best = i, best_area = a;
                }
                if (best < 0) break;
                const Node& c = bvh.nodes[kids[best]];
                check(c.index + 1);
                kids[best] = c.index;  // keep the binary order: left replaces the parent, right goes after it
                for (int i = k; i > best + 1; --i) kids[i] = kids[i - 1];
                kids[best + 1] = c.index + 1;
                ++k;
            }
            NodeType out;
            for (int c = 0; c < W; ++c) out.clear(c);
            for (int i = 0; i < k; ++i) {
                const Node& c = bvh.nodes[kids[i]];
                out.set_box(i, c.box);
                if (c.is_leaf()) {
                    out.index[i] = c.index;
                    out.count[i] = c.count;
                } else {
                    out.index[i] = static_cast<std::uint32_t>(nodes.size());
                    out.count[i] = 0;
                    nodes.emplace_back();
                    todo.push_back({kids[i], out.index[i]});
                }
            }
            nodes[task.wide] = out;
        }
    }
};

using WideBvh = WideBvhT<4>;   ///< 4-wide tree (SSE)
using WideBvh8 = WideBvhT<8>;  ///< 8-wide tree (AVX; plain C++ without it)

}  // namespace raykit
