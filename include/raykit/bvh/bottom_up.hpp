// raykit/bvh/bottom_up.hpp — the shared back end of the bottom-up builders
// (PairwiseBuilder, SortAxisBuilder, PlocBuilder): merge tree → Bvh.
//
// A bottom-up builder records only the merge topology, as a detail::MergeTree:
// node ids 0..n-1 are the primitives, and every merge appends one inner node
// (id n + k) with two child ids; every node but the last root is merged
// exactly once. Merges come in batches (a level, an iteration): a batch's
// nodes have children only among the primitives and earlier batches.
// detail::finish_bottom_up then turns that into a Bvh:
//
//   1. Depth limit (detail::limit_depth). Subtrees that would end deeper than
//      RAYKIT_BVH_MAX_DEPTH are rebuilt with median splits (proof at the
//      function). A node of batch b has height ≤ b + 1, so this only runs
//      when there are more batches than RAYKIT_BVH_MAX_DEPTH and the tree is
//      actually too deep (PLOC on chain-like inputs; pairwise and
//      sort-by-axis halve the element count per level and never need it).
//   2. Leaf merge, bottom-up over the real primitive boxes: a subtree of
//      n ≤ max_leaf_size primitives (LeafCost, bvh/sah.hpp) becomes one leaf when
//        Ci·SA·n ≤ Ct·SA + cost(left) + cost(right)
//      (its SAH cost, with the children's best costs; SA = half area).
//      Merging subtrees into leaves only removes levels, so the depth bound
//      still holds.
//   3. Output in depth-first pre-order with children side by side: exactly
//      the layout detail::compact_preorder produces, written directly, batch
//      by batch from the root down (after a depth cut: recursively). A
//      leaf's primitives are contiguous in prim_ids, in the merge tree's
//      left-to-right order.
// Steps 2 and 3 split large batches among threads; every node's result
// depends only on the tree, so the output is the same for any thread count.
//
// What the builders share before this step lives beside it: Morton codes
// (bvh/morton.hpp), sanitized centroids and working boxes (bvh/sanitize.hpp),
// radix sorts and raw scratch arrays (util/radix_sort.hpp, util/raw_array.hpp)
// and the thread team (util/parallel.hpp). The optional post-pass that may run
// between the builder and this back end is in bvh/optimize.hpp.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "raykit/bvh/depth.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/util/parallel.hpp"
#include "raykit/util/raw_array.hpp"

namespace raykit {

namespace detail {

/// What a parent needs from a finished subtree for the leaf merge.
struct SubtreeCost {
    std::uint32_t count;  ///< primitives below
    std::uint32_t out;    ///< output nodes below (1: the subtree becomes one leaf)
    float cost;           ///< best SAH cost (a leaf's, or a split's with the children's best)
};

/// Per inner node: box, children and leaf-merge data (bottom-up), then its
/// place in the output (top-down).
struct MergeInfo {
    AABB box;
    std::uint32_t kid[2];
    SubtreeCost sub;
    std::uint32_t slot, desc, first;  // output slot (kInside: within a leaf), its children's slot, first prim_ids slot
};

/// The leaf-merge rule for a primitive (a one-primitive leaf)...
inline SubtreeCost primitive_cost(const AABB& real_box, const LeafCost& cfg) noexcept {
    return {1, 1, cfg.intersection_cost * fused_proof_half_area(real_box)};
}
/// ... and for an inner node with box `box` over subtrees a and b: a leaf
/// when it holds at most leaf_limit() primitives and Ci·SA·n ≤ Ct·SA +
/// cost(a) + cost(b).
inline SubtreeCost node_cost(const AABB& box, const SubtreeCost& a, const SubtreeCost& b,
                             const LeafCost& cfg) noexcept {
    const float sa = fused_proof_half_area(box);
    const std::uint32_t cnt = a.count + b.count;
    const float split = cfg.split_cost(sa, a.cost + b.cost);
    const float leaf = cfg.leaf_cost(sa, cnt);
    if (cnt <= cfg.leaf_limit() && leaf <= split) return {cnt, 1, leaf};
    return {cnt, 1 + a.out + b.out, split};
}

/// Topology of a bottom-up build: ids < prims are primitives, id prims + k
/// is the inner node with children info[k].kid.
struct MergeTree {
    std::uint32_t prims = 0;
    /// One record per inner node. Builders set kid; they may also fill box
    /// (the real bounds) and sub and then set info_ready, else
    /// finish_bottom_up computes those.
    RawArray<MergeInfo> info;
    bool info_ready = false;
    /// Exclusive ends (indices into info) of the batches; the nodes of one
    /// batch only have children among the primitives and earlier batches.
    std::vector<std::uint32_t> batch_end;
    std::uint32_t root = 0;

    std::size_t size() const noexcept { return info.size(); }
    void set(std::size_t k, std::uint32_t a, std::uint32_t b) noexcept {
        info[k].kid[0] = a;
        info[k].kid[1] = b;
    }
    /// Appends an inner node over a and b; returns its id.
    std::uint32_t add(std::uint32_t a, std::uint32_t b) {
        MergeInfo in{};
        in.kid[0] = a;
        in.kid[1] = b;
        info.push_back(in);
        return prims + static_cast<std::uint32_t>(info.size() - 1);
    }
    /// Marks the end of the current batch (no-op for an empty batch).
    void close_batch() {
        const auto k = static_cast<std::uint32_t>(info.size());
        if (batch_end.empty() ? k > 0 : batch_end.back() < k) batch_end.push_back(k);
    }
};

/// ⌈log2 c⌉ for c ≥ 1: the height of a median-split tree over c primitives.
inline int ceil_log2(std::uint64_t c) noexcept { return c <= 1 ? 0 : static_cast<int>(std::bit_width(c - 1)); }

/// Depth-limit pass. Rebuilds, with median splits, subtrees that would end
/// deeper than RAYKIT_BVH_MAX_DEPTH (= D).
///
/// Proof that afterwards no leaf is deeper than D. Let h(v) be the height of
/// v's subtree, c(v) its primitive count, d(v) its depth, and call v
/// "rebuildable" when d(v) + ⌈log2 c(v)⌉ ≤ D: a median split halves the
/// count (⌈c/2⌉ ≤ the larger half), so a median-split tree over c primitives
/// has height exactly ⌈log2 c⌉, and rebuilding a rebuildable v keeps all its
/// leaves at depth ≤ D. The walk only ever visits rebuildable nodes: the root
/// is one, because c ≤ 2^31 (the builders reject more) and D ≥ 40 > 31. At a
/// visited v:
///   - if d(v) + h(v) ≤ D the subtree is kept as is: all its leaves are at
///     depth ≤ D;
///   - else, if each child is either such a kept subtree or rebuildable at
///     depth d(v) + 1, the walk goes on into both children (v stays an inner
///     node at depth ≤ D);
///   - else v itself is rebuilt, which is safe because v is rebuildable.
/// Every leaf of the result lies in a kept or a rebuilt subtree, so its depth
/// is ≤ D. The walk uses an explicit stack (the input may be O(n) deep).
/// Returns whether anything was rebuilt.
inline bool limit_depth(MergeTree& t, std::span<const vec3> centers) {
    constexpr int D = RAYKIT_BVH_MAX_DEPTH;
    const std::uint32_t n = t.prims;
    const std::size_t k0 = t.size();
    std::vector<std::uint32_t> height(k0), count(k0);
    auto h_of = [&](std::uint32_t id) -> std::uint32_t { return id < n ? 0u : height[id - n]; };
    auto c_of = [&](std::uint32_t id) -> std::uint32_t { return id < n ? 1u : count[id - n]; };
    for (std::size_t k = 0; k < k0; ++k) {
        const std::uint32_t a = t.info[k].kid[0], b = t.info[k].kid[1];
        height[k] = 1 + std::max(h_of(a), h_of(b));
        count[k] = c_of(a) + c_of(b);
    }
    if (int(h_of(t.root)) <= D) return false;

    std::vector<std::uint32_t> ids, stack;
    // median-split rebuild of the primitives ids[b, e); returns the new id
    auto median_build = [&](auto&& self, std::uint32_t b, std::uint32_t e) -> std::uint32_t {
        if (e - b == 1) return ids[b];
        AABB cb;
        for (std::uint32_t i = b; i < e; ++i) cb.grow(centers[ids[i]]);
        const std::uint32_t mid = median_partition(ids, b, e, centers, max_axis(cb.extent()));
        const std::uint32_t l = self(self, b, mid), r = self(self, mid, e);
        return t.add(l, r);
    };
    auto rebuild = [&](std::uint32_t v) -> std::uint32_t {
        ids.clear();
        stack.assign(1, v);
        while (!stack.empty()) {
            const std::uint32_t x = stack.back();
            stack.pop_back();
            if (x < n) {
                ids.push_back(x);
            } else {
                stack.push_back(t.info[x - n].kid[1]);
                stack.push_back(t.info[x - n].kid[0]);
            }
        }
        return median_build(median_build, 0, static_cast<std::uint32_t>(ids.size()));
    };

    struct Item {
        std::uint32_t id;
        int depth;
        std::uint32_t parent;  // inner index k of the parent (kNone: the root)
        int side;              // which child of the parent
    };
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    auto fits = [&](std::uint32_t id, int d) { return d + int(h_of(id)) <= D; };
    auto rebuildable = [&](std::uint32_t id, int d) { return d + ceil_log2(c_of(id)) <= D; };
    std::vector<Item> work{{t.root, 0, kNone, 0}};
    while (!work.empty()) {
        const Item it = work.back();
        work.pop_back();
        if (fits(it.id, it.depth)) continue;
        const std::uint32_t k = it.id - n;  // an inner node: primitives always fit
        const std::uint32_t a = t.info[k].kid[0], b = t.info[k].kid[1];
        const int cd = it.depth + 1;
        if ((fits(a, cd) || rebuildable(a, cd)) && (fits(b, cd) || rebuildable(b, cd))) {
            work.push_back({b, cd, k, 1});
            work.push_back({a, cd, k, 0});
        } else {
            const std::uint32_t nid = rebuild(it.id);
            if (it.parent == kNone) t.root = nid;
            else t.info[it.parent].kid[it.side] = nid;
        }
    }
    return true;
}

/// Calls node(k) for every inner node, batch after batch (children before
/// parents); large batches are split among threads.
template <class Fn>
void sweep_batches(const MergeTree& t, unsigned threads, Fn& node, WorkTeam* team = nullptr) {
    const std::size_t K = t.size();
    std::size_t begin = 0;
    for (const std::uint32_t end_u : t.batch_end) {
        const std::size_t end = std::min<std::size_t>(end_u, K);
        if (end <= begin) continue;
        for_range(begin, end, threads, team, node);
        begin = end;
    }
    for (std::size_t k = begin; k < K; ++k) node(k);
}

/// Turns a merge tree into the final Bvh (steps 2 and 3 above; step 1 first
/// when the batch count does not already bound the height).
inline Bvh finish_bottom_up(MergeTree& t, std::span<const AABB> boxes, std::span<const vec3> centers,
                            const LeafCost& cfg, unsigned threads, WorkTeam* team = nullptr) {
    Bvh bvh;
    const std::uint32_t n = t.prims;
    if (n == 0) return bvh;
    if (n == 1) {
        bvh.nodes.push_back(Node{boxes[0], 0, 1});
        bvh.prim_ids.push_back(0);
        return bvh;
    }
    t.close_batch();
    const bool cut = t.batch_end.size() > std::size_t(RAYKIT_BVH_MAX_DEPTH) && limit_depth(t, centers);

    // bottom-up sweep: real boxes, primitive counts, best SAH cost, output
    // size, packed per node so that the top-down pass touches one record
    using Info = MergeInfo;
    RawArray<Info>& info = t.info;
    auto node = [&](std::size_t k) {
        const std::uint32_t a = info[k].kid[0], b = info[k].kid[1];
        Info in;
        in.kid[0] = a;
        in.kid[1] = b;
        SubtreeCost sa, sb;
        if (a < n) {
            in.box = boxes[a];
            sa = primitive_cost(boxes[a], cfg);
        } else {
            in.box = info[a - n].box;
            sa = info[a - n].sub;
        }
        if (b < n) {
            in.box.grow(boxes[b]);
            sb = primitive_cost(boxes[b], cfg);
        } else {
            in.box.grow(info[b - n].box);
            sb = info[b - n].sub;
        }
        in.sub = node_cost(in.box, sa, sb, cfg);
        info[k] = in;
    };
    int fork_depth = 0;
    if (threads > 1) {
        fork_depth = 1;
        while ((1u << (fork_depth - 1)) < threads) ++fork_depth;
        ++fork_depth;
    }
    if (cut) {
        // Nodes above the rebuilt subtrees now have children appended after
        // them, so the batch order no longer has children first: sweep the
        // reachable tree in post-order instead (its depth is now ≤ D).
        auto sweep = [&](auto&& self, std::uint32_t id, int depth) -> void {
            if (id < n) return;
            const std::uint32_t k = id - n;
            fork_join(
                depth < fork_depth, [&] { self(self, info[k].kid[0], depth + 1); },
                [&] { self(self, info[k].kid[1], depth + 1); });
            node(k);
        };
        sweep(sweep, t.root, 0);
    } else if (!t.info_ready) {
        sweep_batches(t, threads, node, team);
    }

    // top-down output, pre-order with children side by side
    const std::uint32_t root = t.root;
    const std::uint32_t total = root < n ? 1u : info[root - n].sub.out;
    bvh.nodes.resize(total);
    bvh.prim_ids.resize(n);
    Node* nodes = bvh.nodes.data();
    std::uint32_t* prim_ids = bvh.prim_ids.data();
    if (!cut) {
        // Batch by batch from the root down (parents are created after their
        // children, and the nodes of one batch are unrelated): each node
        // reads the place its parent gave it and places its children.
        // Records are read in order; the output is written scattered.
        constexpr std::uint32_t kInside = 0xFFFFFFFFu;
        Info& top = info[root - n];
        top.slot = 0;
        top.desc = 1;
        top.first = 0;
        const std::size_t K = t.size();
        auto down = [&](std::size_t k) {
            // The children's records (earlier batches), the primitive boxes and
            // the output are scattered: fetch those of the node kAhead on, whose
            // own place its parent (a later batch) has already set. The sort-by-
            // axis build of the 1M torus waited on these loads for a quarter of
            // its samples; its whole build 1.13x as fast on two threads (paired).
            constexpr std::size_t kAhead = 16;
            if (k + kAhead < K) {
                const Info& f = info[k + kAhead];
                for (const std::uint32_t c : f.kid) {
                    if (c < n) __builtin_prefetch(&boxes[c]);
                    else __builtin_prefetch(&info[c - n].sub, 1);
                }
                if (f.slot < total) __builtin_prefetch(&nodes[f.slot], 1);  // kInside: within a leaf
                if (f.first < n) __builtin_prefetch(&prim_ids[f.first], 1);
            }
            const Info& in = info[k];
            const std::uint32_t a = in.kid[0];
            const std::uint32_t out_a = a < n ? 1u : info[a - n].sub.out;
            const std::uint32_t cnt_a = a < n ? 1u : info[a - n].sub.count;
            std::uint32_t cslot[2] = {kInside, kInside}, cdesc[2] = {0, 0};
            if (in.slot != kInside) {
                if (in.sub.out == 1) {
                    nodes[in.slot] = Node{in.box, in.first, in.sub.count};
                } else {
                    nodes[in.slot] = Node{in.box, in.desc, 0};
                    cslot[0] = in.desc;
                    cslot[1] = in.desc + 1;
                    cdesc[0] = in.desc + 2;
                    cdesc[1] = in.desc + 2 + (out_a - 1);
                }
            }
            const std::uint32_t cfirst[2] = {in.first, in.first + cnt_a};
            for (int side = 0; side < 2; ++side) {
                const std::uint32_t c = in.kid[side];
                if (c < n) {
                    prim_ids[cfirst[side]] = c;
                    if (cslot[side] != kInside) nodes[cslot[side]] = Node{boxes[c], cfirst[side], 1};
                } else {
                    Info& ch = info[c - n];
                    ch.slot = cslot[side];
                    ch.desc = cdesc[side];
                    ch.first = cfirst[side];
                }
            }
        };
        for (std::size_t bi = t.batch_end.size(); bi-- > 0;) {
            for_range(bi == 0 ? 0 : t.batch_end[bi - 1], t.batch_end[bi], threads, team, down);
        }
        return bvh;
    }
    // after a depth cut: recursive, the depth is now bounded
    auto emit = [&](auto&& self, std::uint32_t id, std::uint32_t slot, std::uint32_t desc, std::uint32_t first,
                    int depth) -> void {
        Node& o = nodes[slot];
        if (id < n) {
            o = Node{boxes[id], first, 1};
            prim_ids[first] = id;
            return;
        }
        const Info& in = info[id - n];
        if (in.sub.out == 1) {  // merged into one leaf: gather the subtree's primitives left to right
            o = Node{in.box, first, in.sub.count};
            std::uint32_t at = first;
            std::uint32_t st[RAYKIT_BVH_MAX_DEPTH + 2];
            int sp = 0;
            st[sp++] = id;
            while (sp > 0) {
                const std::uint32_t x = st[--sp];
                if (x < n) {
                    prim_ids[at++] = x;
                } else {
                    st[sp++] = info[x - n].kid[1];
                    st[sp++] = info[x - n].kid[0];
                }
            }
            return;
        }
        o = Node{in.box, desc, 0};
        const std::uint32_t a = in.kid[0], b = in.kid[1];
        const std::uint32_t out_a = a < n ? 1u : info[a - n].sub.out;
        const std::uint32_t cnt_a = a < n ? 1u : info[a - n].sub.count;
        fork_join(
            depth < fork_depth && in.sub.count >= 8192,
            [&] { self(self, a, desc, desc + 2, first, depth + 1); },
            [&] { self(self, b, desc + 1, desc + 2 + (out_a - 1), first + cnt_a, depth + 1); });
    };
    emit(emit, root, 0, 1, 0, 0);
    return bvh;
}

}  // namespace detail
}  // namespace raykit

