// raykit/bvh/traverse.hpp — ordered single-ray traversal.
//
// traverse<AnyHit>(bvh, ray, leaf) walks the tree front to back: at an inner
// node both children are slab-tested, the nearer is visited first and the
// farther pushed with its entry distance; a popped node whose entry distance
// is beyond the current ray.tmax is skipped. The stack holds at most one entry
// per level, and every raykit builder bounds the depth by RAYKIT_BVH_MAX_DEPTH
// (bvh/depth.hpp), so the fixed stack below cannot overflow for their trees.
// A tree from elsewhere that is deeper makes traverse throw instead of
// writing past the stack (validate() reports it beforehand).
//
// The leaf callable is `bool leaf(std::uint32_t first_slot, std::uint32_t count,
// float& tmax)`: it intersects prim_ids[first_slot .. +count), shrinks tmax on
// closest hits, and returns true when it found a hit; with AnyHit = true the
// walk stops at the first leaf that returns true.
//
// The walk is compiled once per instruction-set level: the part of this header below
// RAYKIT_ISA_PASS is its per-level part (scene/trace_level.inc includes it per level), and
// raykit::traverse, which calls the CPU's level, is in scene/trace.hpp.
#ifndef RAYKIT_BVH_TRAVERSE_HPP
#define RAYKIT_BVH_TRAVERSE_HPP

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <type_traits>

#include "raykit/bvh/node.hpp"
#include "raykit/intersect/slab.hpp"

namespace raykit {

struct ClosestHit {
    static constexpr bool any_hit = false;
};
struct AnyHit {
    static constexpr bool any_hit = true;
};

/// Traversal statistics (optional, see traverse_counted).
struct TraversalStats {
    std::uint32_t nodes = 0;   ///< inner nodes visited
    std::uint32_t leaves = 0;  ///< leaves visited
};

}  // namespace raykit

#endif  // RAYKIT_BVH_TRAVERSE_HPP

#ifdef RAYKIT_ISA_PASS
namespace raykit::RAYKIT_ISA_NS {

/// The walks' default for the leaves they reach ahead: nothing to fetch (a leaf store may
/// offer a prefetch, scene/trace_level.inc's leaf_prefetch).
struct NoLeafPrefetch {
    RAYKIT_INLINE void operator()(std::uint32_t, std::uint32_t) const noexcept {}
};

/// `prefetch_leaf(index, count)` is asked for a child leaf's data when the walk starts fetching
/// its grandchildren (as traverse_from does for the leaves it pushes, bvh/traverse_wide.hpp).
template <class Mode = ClosestHit, class LeafFn, class Stats = std::nullptr_t, class LeafPrefetch = NoLeafPrefetch>
bool traverse(const Bvh& bvh, const Ray& ray, float& tmax, LeafFn&& leaf, Stats stats = nullptr,
              const LeafPrefetch& prefetch_leaf = {}) {
    if (bvh.nodes.empty()) return false;
    const Node* RAYKIT_RESTRICT nodes = bvh.nodes.data();
    const SlabRay sr(ray);
    float t_root;
    if (!sr.test(nodes[0].box, ray.tmin, tmax, t_root)) return false;

    struct Entry {
        std::uint32_t node;
        float t;
    };
    Entry stack[RAYKIT_BVH_MAX_DEPTH];
    int sp = 0;
    std::uint32_t cur = 0;
    bool found = false;
    for (;;) {
        const Node& n = nodes[cur];
        if (n.is_leaf()) {
            if constexpr (!std::is_same_v<Stats, std::nullptr_t>) ++stats->leaves;
            if (leaf(n.index, n.count, tmax)) {
                found = true;
                if constexpr (Mode::any_hit) return true;
            }
        } else {
            if constexpr (!std::is_same_v<Stats, std::nullptr_t>) ++stats->nodes;
            const Node& l = nodes[n.index];
            const Node& r = nodes[n.index + 1];
#if defined(__GNUC__) || defined(__clang__)
            // start fetching the grandchildren while the children are tested
            if (!l.is_leaf()) __builtin_prefetch(&nodes[l.index]);
            else prefetch_leaf(l.index, l.count);
            if (!r.is_leaf()) __builtin_prefetch(&nodes[r.index]);
            else prefetch_leaf(r.index, r.count);
#endif
            float tl, tr;
            const unsigned mask = sr.test_pair(l.box, r.box, ray.tmin, tmax, tl, tr);
            const bool hl = mask & 1u, hr = mask & 2u;
            if (hl && hr) {
                std::uint32_t nearc = n.index, farc = n.index + 1;
                float tf = tr;
                if (tr < tl) {
                    nearc = n.index + 1;
                    farc = n.index;
                    tf = tl;
                }
                if (sp == RAYKIT_BVH_MAX_DEPTH) throw std::length_error("raykit::traverse: tree deeper than RAYKIT_BVH_MAX_DEPTH");
                stack[sp++] = {farc, tf};
                cur = nearc;
                continue;
            }
            if (hl) {
                cur = n.index;
                continue;
            }
            if (hr) {
                cur = n.index + 1;
                continue;
            }
        }
        // pop the next node still in front of the closest hit
        for (;;) {
            if (sp == 0) return found;
            const Entry e = stack[--sp];
            if (e.t <= tmax * kSlabExitScale) {
                cur = e.node;
                break;
            }
        }
    }
}

}  // namespace raykit::RAYKIT_ISA_NS
#endif  // RAYKIT_ISA_PASS
