// raykit/bvh/node.hpp — the BVH node layout and the tree container.
//
// One flat array of 32-byte nodes plus one array of primitive indices. A node
// is a leaf when `count > 0`: its primitives are prim_ids[index .. index+count).
// Otherwise it is an inner node whose two children sit side by side at
// nodes[index] and nodes[index + 1]. Builders lay trees out in depth-first
// pre-order, so every child index is larger than its parent's: refit is one
// reverse sweep, and node 0 is the root. The layout crosses to OpenCL unchanged.
#pragma once

#include <cstddef>
#include <cstdint>
#include <new>
#include <type_traits>
#include <vector>

#include "raykit/math/aabb.hpp"
#include "raykit/util/block_cache.hpp"

namespace raykit {

struct alignas(32) Node {
    AABB box;
    std::uint32_t index = 0;  ///< first child (inner) or first prim_ids slot (leaf)
    std::uint32_t count = 0;  ///< 0 for inner nodes, number of primitives for leaves

    bool is_leaf() const noexcept { return count != 0; }
    std::uint32_t left() const noexcept { return index; }
    std::uint32_t right() const noexcept { return index + 1; }
};
static_assert(sizeof(Node) == 32 && alignof(Node) == 32);
static_assert(std::is_standard_layout_v<Node>);
static_assert(offsetof(Node, box) == 0 && offsetof(Node, index) == 24 && offsetof(Node, count) == 28);

/// Allocator that places element 1 of an array of 32-byte nodes on a 64-byte
/// boundary. Children come in pairs starting at odd indices (root 0, its
/// children 1 and 2, ...), so every pair then fills exactly one cache line.
/// Large arrays come from detail::BlockCache (util/block_cache.hpp).
template <class T>
struct PairAlignedAllocator {
    static_assert(sizeof(T) == 32, "PairAlignedAllocator is for 32-byte nodes");
    using value_type = T;
    PairAlignedAllocator() = default;
    template <class U>
    PairAlignedAllocator(const PairAlignedAllocator<U>&) noexcept {}  // NOLINT implicit
    T* allocate(std::size_t n) {
        void* p = detail::BlockCache::get().allocate((n + 1) * sizeof(T));
        return reinterpret_cast<T*>(static_cast<char*>(p) + 32);
    }
    void deallocate(T* p, std::size_t n) noexcept {
        detail::BlockCache::get().deallocate(reinterpret_cast<char*>(p) - 32, (n + 1) * sizeof(T));
    }
    template <class U>
    bool operator==(const PairAlignedAllocator<U>&) const noexcept {
        return true;
    }
};

using NodeArray = std::vector<Node, PairAlignedAllocator<Node>>;

/// A bounding volume hierarchy over primitives 0..n-1 (the caller's order).
struct Bvh {
    NodeArray nodes;
    std::vector<std::uint32_t> prim_ids;

    bool empty() const noexcept { return nodes.empty(); }
    std::size_t memory_bytes() const noexcept {
        return nodes.size() * sizeof(Node) + prim_ids.size() * sizeof(std::uint32_t);
    }
    std::size_t leaf_count() const noexcept {
        std::size_t n = 0;
        for (const Node& nd : nodes) n += nd.is_leaf();
        return n;
    }
    /// Depth of the deepest leaf (root = 0). Iterative; O(nodes).
    int depth() const {
        if (nodes.empty()) return 0;
        std::vector<int> d(nodes.size(), 0);
        int best = 0;
        for (std::size_t i = 0; i < nodes.size(); ++i) {
            const Node& n = nodes[i];
            if (n.is_leaf()) {
                best = d[i] > best ? d[i] : best;
            } else if (n.index + 1 < nodes.size()) {
                d[n.index] = d[n.index + 1] = d[i] + 1;
            }
        }
        return best;
    }
};

}  // namespace raykit
