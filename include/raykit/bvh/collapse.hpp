// raykit/bvh/collapse.hpp — the shared back end of the bottom-up builders
// (PairwiseBuilder, SortAxisBuilder, PlocBuilder) and the helpers they share.
//
// A bottom-up builder records only the merge topology, as a detail::MergeTree:
// node ids 0..n-1 are the primitives, and every merge appends one inner node
// (id n + k) with two child ids. Merges come in batches (a level, an
// iteration); a batch's nodes have children only among the primitives and the
// earlier batches. detail::finish_bottom_up then turns that into a Bvh:
//
//   1. Depth limit. A node whose subtree would end deeper than
//      RAYKIT_BVH_MAX_DEPTH is rebuilt with median splits (see the proof at
//      detail::limit_depth). Skipped when the batch count already bounds the
//      height (pairwise and sort-by-axis halve the element count per level).
//   2. Leaf collapse, bottom-up over the real primitive boxes: a subtree of
//      n ≤ max_leaf_size primitives becomes one leaf when
//        Ci·SA·n ≤ Ct·SA + cost(left) + cost(right)
//      (its SAH cost with the children's best costs, SA = half surface area).
//   3. Output in depth-first pre-order with children side by side, exactly
//      the layout detail::compact_preorder produces (written directly, the
//      large subtrees on separate threads); a leaf's primitives are
//      contiguous in prim_ids, in left-to-right order of the merge tree.
//
// Everything here is deterministic: per-node work does not depend on how the
// nodes are split among threads.
//
// Also here (raykit::detail): centroid sanitizing, "working" boxes (finite,
// non-empty stand-ins for empty or non-finite primitive boxes, used for
// decisions only; the output boxes are always the real ones), Morton codes
// and a stable parallel LSD radix sort.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstdint>
#include <cstring>
#include <limits>
#include <span>
#include <vector>

#include "raykit/bvh/depth.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// Leaf-collapse settings shared by the bottom-up builders (each builder's
/// Config carries the same fields with the same defaults).
struct LeafCollapseConfig {
    unsigned max_leaf_size = 8;       ///< subtrees of more primitives are never collapsed (0 acts as 1)
    float traversal_cost = 1.0f;      ///< Ct, cost of visiting an inner node
    float intersection_cost = 1.0f;   ///< Ci, cost of one ray/triangle test
};

namespace detail {

inline constexpr float kFloatMax = std::numeric_limits<float>::max();

/// Element count from which per-element passes run on several threads.
inline constexpr std::size_t kBottomUpParallelPass = 16384;

/// Chunk count for a parallel pass over m elements: depends on m only.
inline std::size_t pass_chunks(std::size_t m) noexcept {
    return m < kBottomUpParallelPass ? 1 : std::min<std::size_t>(64, m / (kBottomUpParallelPass / 4));
}

/// Bounds of a set of points (finite ones only; NaN is ignored by grow, ±inf
/// are skipped explicitly). Exact for any chunking.
inline AABB finite_point_bounds(std::span<const vec3> pts, unsigned threads) {
    const std::size_t chunks = pass_chunks(pts.size());
    std::vector<AABB> part(chunks);
    parallel_chunks(pts.size(), chunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
        AABB b;
        for (std::size_t i = lo; i < hi; ++i)
            if (is_finite(pts[i])) b.grow(pts[i]);
        part[c] = b;
    });
    AABB all;
    for (const AABB& b : part) all.grow(b);
    return all;
}

/// Copies the centroids; non-finite ones (NaN triangles) go to the centre of
/// the finite ones, so that sorting, Morton codes and distances never see a
/// NaN (the same rule as BinnedSahBuilder).
inline std::vector<vec3> sanitize_centers(std::span<const vec3> centers, unsigned threads) {
    std::vector<vec3> c(centers.begin(), centers.end());
    const AABB all = finite_point_bounds(c, threads);
    const vec3 fill = all.is_empty() ? vec3(0.0f) : all.center();
    parallel_for(c.size(), threads, [&](std::size_t i) {
        if (!is_finite(c[i])) c[i] = fill;
    });
    return c;
}

inline bool box_is_finite(const AABB& b) noexcept { return is_finite(b.min) && is_finite(b.max); }

/// The box a builder reasons with: the primitive's own box when it is
/// finite and non-empty, else the point box at its (sanitized) centroid.
inline AABB working_box(const AABB& b, const vec3& sanitized_center) noexcept {
    return (!b.is_empty() && box_is_finite(b)) ? b : AABB::of_point(sanitized_center);
}

/// Centre of a finite box without overflow.
inline vec3 box_centre(const AABB& b) noexcept { return b.min * 0.5f + b.max * 0.5f; }

/// Clamp of a non-negative float difference that overflowed.
inline float clamp_extent(float e) noexcept { return e < kFloatMax ? e : kFloatMax; }

/// Float whose unsigned bit pattern orders like the float (no NaN).
inline std::uint32_t orderable_bits(float f) noexcept {
    const std::uint32_t u = std::bit_cast<std::uint32_t>(f == 0.0f ? 0.0f : f);  // -0 == +0
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

/// Spreads the low 21 bits of x to every third bit.
inline std::uint64_t spread_bits21(std::uint64_t x) noexcept {
    x &= 0x1FFFFFull;
    x = (x | x << 32) & 0x1F00000000FFFFull;
    x = (x | x << 16) & 0x1F0000FF0000FFull;
    x = (x | x << 8) & 0x100F00F00F00F00Full;
    x = (x | x << 4) & 0x10C30C30C30C30C3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
}

/// Maps points into a cube of 2^21 cells per side around `bounds` (same
/// scale on every axis, so distances keep their proportions) and returns
/// 63-bit Morton codes.
struct MortonQuantizer {
    vec3 lo{0.0f};
    float scale = 0.0f;
    explicit MortonQuantizer(const AABB& bounds) {
        if (bounds.is_empty()) return;
        lo = bounds.min;
        const vec3 e = bounds.extent();
        const float m = std::max(e.x, std::max(e.y, e.z));
        scale = m > 0.0f && m < kInf ? 2097151.0f / m : 0.0f;
    }
    std::uint64_t operator()(const vec3& p) const noexcept {
        auto q = [&](int a) -> std::uint64_t {
            float f = (p[a] - lo[a]) * scale;
            f = f > 0.0f ? f : 0.0f;  // also maps NaN to 0
            f = f < 2097151.0f ? f : 2097151.0f;
            return static_cast<std::uint64_t>(f);
        };
        return spread_bits21(q(0)) << 2 | spread_bits21(q(1)) << 1 | spread_bits21(q(2));
    }
};

/// Stable LSD radix sort of (keys, vals) by the low `bits` bits of the keys,
/// 11 bits per pass; passes where every key has the same digit are skipped.
/// The result is unique (stability), whatever the thread count.
template <class Key>
void radix_sort(std::vector<Key>& keys, std::vector<std::uint32_t>& vals, int bits, unsigned threads) {
    constexpr int kDigit = 11;
    constexpr std::size_t kBins = std::size_t(1) << kDigit;
    const std::size_t m = keys.size();
    if (m < 2) return;
    std::vector<Key> k2(m);
    std::vector<std::uint32_t> v2(m);
    const std::size_t chunks = threads > 1 ? pass_chunks(m) : 1;
    std::vector<std::uint32_t> hist(chunks * kBins);
    for (int shift = 0; shift < bits; shift += kDigit) {
        parallel_chunks(m, chunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            std::fill(h, h + kBins, 0u);
            for (std::size_t i = lo; i < hi; ++i) ++h[(keys[i] >> shift) & (kBins - 1)];
        });
        // skip a pass that would not move anything
        const std::size_t d0 = (keys[0] >> shift) & (kBins - 1);
        std::size_t same = 0;
        for (std::size_t c = 0; c < chunks; ++c) same += hist[c * kBins + d0];
        if (same == m) continue;
        std::uint32_t sum = 0;
        for (std::size_t b = 0; b < kBins; ++b)
            for (std::size_t c = 0; c < chunks; ++c) {
                const std::uint32_t h = hist[c * kBins + b];
                hist[c * kBins + b] = sum;
                sum += h;
            }
        parallel_chunks(m, chunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            for (std::size_t i = lo; i < hi; ++i) {
                const std::uint32_t pos = h[(keys[i] >> shift) & (kBins - 1)]++;
                k2[pos] = keys[i];
                v2[pos] = vals[i];
            }
        });
        keys.swap(k2);
        vals.swap(v2);
    }
}

/// Topology of a bottom-up build: ids < prims are primitives, id prims + k
/// is the inner node with children kids[k].
struct MergeTree {
    std::uint32_t prims = 0;
    std::vector<std::array<std::uint32_t, 2>> kids;
    /// Exclusive ends (indices into kids) of the batches; the nodes of one
    /// batch only have children among the primitives and earlier batches.
    std::vector<std::uint32_t> batch_end;
    /// Inner nodes from here on depend on each other (children before
    /// parents) and are finished one at a time.
    std::uint32_t sequential_from = std::numeric_limits<std::uint32_t>::max();
    std::uint32_t root = 0;

    /// Marks the end of the current batch (no-op for an empty batch).
    void close_batch() {
        const auto k = static_cast<std::uint32_t>(kids.size());
        if (batch_end.empty() ? k > 0 : batch_end.back() < k) batch_end.push_back(k);
    }
};

/// ⌈log2 c⌉ for c ≥ 1: the height of a median-split tree over c primitives.
inline int ceil_log2(std::uint64_t c) noexcept { return c <= 1 ? 0 : std::bit_width(c - 1); }

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
inline void limit_depth(MergeTree& t, std::span<const vec3> centers) {
    constexpr int D = RAYKIT_BVH_MAX_DEPTH;
    const std::uint32_t n = t.prims;
    const std::size_t k0 = t.kids.size();
    std::vector<std::uint32_t> height(k0), count(k0);
    auto h_of = [&](std::uint32_t id) -> std::uint32_t { return id < n ? 0u : height[id - n]; };
    auto c_of = [&](std::uint32_t id) -> std::uint32_t { return id < n ? 1u : count[id - n]; };
    for (std::size_t k = 0; k < k0; ++k) {
        const auto [a, b] = t.kids[k];
        height[k] = 1 + std::max(h_of(a), h_of(b));
        count[k] = c_of(a) + c_of(b);
    }
    if (int(h_of(t.root)) <= D) return;

    std::vector<std::uint32_t> ids, stack;
    // median-split rebuild of the primitives ids[b, e); returns the new id
    auto median_build = [&](auto&& self, std::uint32_t b, std::uint32_t e) -> std::uint32_t {
        if (e - b == 1) return ids[b];
        AABB cb;
        for (std::uint32_t i = b; i < e; ++i) cb.grow(centers[ids[i]]);
        const std::uint32_t mid = median_partition(ids, b, e, centers, max_axis(cb.extent()));
        const std::uint32_t l = self(self, b, mid), r = self(self, mid, e);
        t.kids.push_back({l, r});
        return n + static_cast<std::uint32_t>(t.kids.size() - 1);
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
                stack.push_back(t.kids[x - n][1]);
                stack.push_back(t.kids[x - n][0]);
            }
        }
        return median_build(median_build, 0, static_cast<std::uint32_t>(ids.size()));
    };
    t.sequential_from = std::min<std::uint32_t>(t.sequential_from, static_cast<std::uint32_t>(k0));

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
        const std::uint32_t a = t.kids[k][0], b = t.kids[k][1];
        const int cd = it.depth + 1;
        if ((fits(a, cd) || rebuildable(a, cd)) && (fits(b, cd) || rebuildable(b, cd))) {
            work.push_back({b, cd, k, 1});
            work.push_back({a, cd, k, 0});
        } else {
            const std::uint32_t nid = rebuild(it.id);
            if (it.parent == kNone) t.root = nid;
            else t.kids[it.parent][it.side] = nid;
        }
    }
}

/// Turns a merge tree into the final Bvh (steps 2 and 3 above; step 1 first
/// when the batch count does not already bound the height).
inline Bvh finish_bottom_up(MergeTree& t, std::span<const AABB> boxes, std::span<const vec3> centers,
                            const LeafCollapseConfig& cfg, unsigned threads) {
    Bvh bvh;
    const std::uint32_t n = t.prims;
    if (n == 0) return bvh;
    if (n == 1) {
        bvh.nodes.push_back(Node{boxes[0], 0, 1});
        bvh.prim_ids.push_back(0);
        return bvh;
    }
    if (t.batch_end.size() > std::size_t(RAYKIT_BVH_MAX_DEPTH)) limit_depth(t, centers);

    // bottom-up sweep: real boxes, primitive counts, best SAH cost, output size
    const std::size_t K = t.kids.size();
    std::vector<AABB> box(K);
    std::vector<std::uint32_t> count(K), out(K);
    std::vector<float> cost(K);
    const float ct = cfg.traversal_cost, ci = cfg.intersection_cost;
    const std::uint32_t max_leaf = std::max(1u, cfg.max_leaf_size);
    auto node = [&](std::size_t k) {
        const auto [a, b] = t.kids[k];
        AABB bx;
        std::uint32_t cnt = 0, o = 1;
        float cc = 0.0f;
        for (const std::uint32_t c : {a, b}) {
            if (c < n) {
                bx.grow(boxes[c]);
                cnt += 1;
                cc += ci * boxes[c].half_area();
                o += 1;
            } else {
                bx.grow(box[c - n]);
                cnt += count[c - n];
                cc += cost[c - n];
                o += out[c - n];
            }
        }
        const float sa = bx.half_area();
        const float split = ct * sa + cc;
        const float leaf = ci * sa * float(cnt);
        box[k] = bx;
        count[k] = cnt;
        if (cnt <= max_leaf && leaf <= split) {
            cost[k] = leaf;
            out[k] = 1;
        } else {
            cost[k] = split;
            out[k] = o;
        }
    };
    const std::size_t seq = std::min<std::size_t>(t.sequential_from, K);
    std::size_t begin = 0;
    for (const std::uint32_t end_u : t.batch_end) {
        const std::size_t end = std::min<std::size_t>(end_u, seq);
        if (end <= begin) continue;
        const std::size_t m = end - begin;
        if (threads > 1 && m >= kBottomUpParallelPass) {
            parallel_chunks(m, pass_chunks(m), threads, [&](std::size_t, std::size_t lo, std::size_t hi) {
                for (std::size_t k = begin + lo; k < begin + hi; ++k) node(k);
            });
        } else {
            for (std::size_t k = begin; k < end; ++k) node(k);
        }
        begin = end;
    }
    for (std::size_t k = begin; k < K; ++k) node(k);

    // top-down output, pre-order with children side by side
    const std::uint32_t root = t.root;
    const std::uint32_t total = root < n ? 1u : out[root - n];
    bvh.nodes.resize(total);
    bvh.prim_ids.resize(n);
    Node* nodes = bvh.nodes.data();
    std::uint32_t* prim_ids = bvh.prim_ids.data();
    int fork_depth = 0;
    if (threads > 1) {
        fork_depth = 1;
        while ((1u << (fork_depth - 1)) < threads) ++fork_depth;
        ++fork_depth;
    }
    auto emit = [&](auto&& self, std::uint32_t id, std::uint32_t slot, std::uint32_t desc, std::uint32_t first,
                    int depth) -> void {
        Node& o = nodes[slot];
        if (id < n) {
            o = Node{boxes[id], first, 1};
            prim_ids[first] = id;
            return;
        }
        const std::uint32_t k = id - n;
        if (out[k] == 1) {  // collapsed: gather the subtree's primitives left to right
            o = Node{box[k], first, count[k]};
            std::uint32_t at = first;
            std::uint32_t st[RAYKIT_BVH_MAX_DEPTH + 2];
            int sp = 0;
            st[sp++] = id;
            while (sp > 0) {
                const std::uint32_t x = st[--sp];
                if (x < n) {
                    prim_ids[at++] = x;
                } else {
                    st[sp++] = t.kids[x - n][1];
                    st[sp++] = t.kids[x - n][0];
                }
            }
            return;
        }
        o = Node{box[k], desc, 0};
        const std::uint32_t a = t.kids[k][0], b = t.kids[k][1];
        const std::uint32_t out_a = a < n ? 1u : out[a - n];
        const std::uint32_t cnt_a = a < n ? 1u : count[a - n];
        fork_join(
            depth < fork_depth && count[k] >= 8192,
            [&] { self(self, a, desc, desc + 2, first, depth + 1); },
            [&] { self(self, b, desc + 1, desc + 2 + (out_a - 1), first + cnt_a, depth + 1); });
    };
    emit(emit, root, 0, 1, 0, 0);
    return bvh;
}

}  // namespace detail
}  // namespace raykit
