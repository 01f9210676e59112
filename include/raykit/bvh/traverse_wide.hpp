// raykit/bvh/traverse_wide.hpp — ordered single-ray traversal of a WideBvh / WideBvh8.
//
// traverse<Mode>(wide, ray, tmax, leaf) has the contract of the binary
// traverse() in bvh/traverse.hpp (same leaf callable, same ClosestHit/AnyHit
// modes, same TraversalStats where `nodes` counts wide nodes): the root box is
// tested first, then at each node the child boxes are slab-tested in one SSE
// (4 children) or AVX (8 children) operation; for closest hits the entered
// children are sorted by entry distance, the nearest is visited and the
// others pushed far-to-near, and a popped entry beyond the current tmax is
// skipped; for any hit they are pushed unsorted.
//
// The 4-wide box test makes exactly the decisions of the binary slab test
// (intersect/slab.hpp): the same (plane − origin)·(1/d) distances, NaN lanes
// never deciding (SSE max/min return their second operand on NaN, the
// current interval end, as robust_max/robust_min do), and the exit distance
// widened by the same 1 + 2·gamma(3) — applied once after the minimum, which
// gives the same float because rounding is monotone. So a WideBvh collapsed
// from a Bvh visits the same leaves a ray can hit and returns the same answer.
//
// Stack: at most W − 1 entries per wide level, and a wide tree is no deeper
// than its binary tree (≤ RAYKIT_BVH_MAX_DEPTH for raykit's builders); a deeper
// tree from elsewhere makes traverse throw instead of overflowing.
//
// WideSlabRay and the walk are compiled once per instruction-set level: the part
// of this header below RAYKIT_ISA_PASS is their per-level part (scene/trace_level.inc
// includes it per level), and raykit::traverse, which calls the CPU's level, is in
// scene/trace.hpp.
#ifndef RAYKIT_BVH_TRAVERSE_WIDE_HPP
#define RAYKIT_BVH_TRAVERSE_WIDE_HPP

#include <bit>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/wide.hpp"
#include "raykit/simd/isa.hpp"

#endif  // RAYKIT_BVH_TRAVERSE_WIDE_HPP

#ifdef RAYKIT_ISA_PASS
namespace raykit::RAYKIT_ISA_NS {

/// Per-ray state of the wide slab test. test() uses SSE (4 lanes) / AVX (8
/// lanes) where the target has them; test_scalar() is the plain-C++ reference
/// it is tested against.
struct WideSlabRay {
    int near_row[3], far_row[3];  ///< WideNode::planes rows of the near/far planes per axis
    float org[3], inv[3];
#if RAYKIT_ISA_SSE2
    __m128 org4[3], inv4[3];
#endif
#if RAYKIT_ISA_AVX
    __m256 org8[3], inv8[3];
#endif

    RAYKIT_INLINE explicit WideSlabRay(const Ray& r) noexcept {
        const RayInv ri(r.dir);
        const float* o = &r.org.x;
        const float* v = &ri.inv.x;
        for (int a = 0; a < 3; ++a) {
            near_row[a] = 2 * a + ri.octant[a];
            far_row[a] = 2 * a + 1 - ri.octant[a];
            org[a] = o[a];
            inv[a] = v[a];
#if RAYKIT_ISA_SSE2
            org4[a] = _mm_set1_ps(o[a]);
            inv4[a] = _mm_set1_ps(v[a]);
#endif
#if RAYKIT_ISA_AVX
            org8[a] = _mm256_set1_ps(o[a]);
            inv8[a] = _mm256_set1_ps(v[a]);
#endif
        }
    }

    /// Tests the child boxes of `n` against [tmin, tmax]; returns a bit per
    /// child entered and writes the entry distances to t[0..W) (32-byte aligned).
    RAYKIT_INLINE unsigned test(const WideNode8& n, float tmin, float tmax, float* RAYKIT_RESTRICT t) const noexcept {
#if RAYKIT_ISA_AVX
        const __m256 tnx = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.planes[near_row[0]]), org8[0]), inv8[0]);
        const __m256 tny = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.planes[near_row[1]]), org8[1]), inv8[1]);
        const __m256 tnz = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.planes[near_row[2]]), org8[2]), inv8[2]);
        const __m256 tfx = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.planes[far_row[0]]), org8[0]), inv8[0]);
        const __m256 tfy = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.planes[far_row[1]]), org8[1]), inv8[1]);
        const __m256 tfz = _mm256_mul_ps(_mm256_sub_ps(_mm256_load_ps(n.planes[far_row[2]]), org8[2]), inv8[2]);
        const __m256 tn = _mm256_max_ps(tnx, _mm256_max_ps(tny, _mm256_max_ps(tnz, _mm256_set1_ps(tmin))));
        const __m256 tf =
            _mm256_mul_ps(_mm256_min_ps(tfx, _mm256_min_ps(tfy, _mm256_min_ps(tfz, _mm256_set1_ps(tmax)))),
                          _mm256_set1_ps(kSlabExitScale));
        _mm256_store_ps(t, tn);
        return static_cast<unsigned>(_mm256_movemask_ps(_mm256_cmp_ps(tn, tf, _CMP_LE_OQ)));
#else
        return test_scalar(n, tmin, tmax, t);
#endif
    }

    RAYKIT_INLINE unsigned test(const WideNode& n, float tmin, float tmax, float* RAYKIT_RESTRICT t) const noexcept {
#if RAYKIT_ISA_SSE2
        const __m128 tnx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.planes[near_row[0]]), org4[0]), inv4[0]);
        const __m128 tny = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.planes[near_row[1]]), org4[1]), inv4[1]);
        const __m128 tnz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.planes[near_row[2]]), org4[2]), inv4[2]);
        const __m128 tfx = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.planes[far_row[0]]), org4[0]), inv4[0]);
        const __m128 tfy = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.planes[far_row[1]]), org4[1]), inv4[1]);
        const __m128 tfz = _mm_mul_ps(_mm_sub_ps(_mm_load_ps(n.planes[far_row[2]]), org4[2]), inv4[2]);
        // NaN candidates (first operands) never decide: max/min return the second
        const __m128 tn = _mm_max_ps(tnx, _mm_max_ps(tny, _mm_max_ps(tnz, _mm_set1_ps(tmin))));
        const __m128 tf = _mm_mul_ps(_mm_min_ps(tfx, _mm_min_ps(tfy, _mm_min_ps(tfz, _mm_set1_ps(tmax)))),
                                     _mm_set1_ps(kSlabExitScale));
        _mm_store_ps(t, tn);
        return static_cast<unsigned>(_mm_movemask_ps(_mm_cmple_ps(tn, tf)));
#else
        return test_scalar(n, tmin, tmax, t);
#endif
    }

    /// One box, with slab_test()'s decision (intersect/slab.hpp), from this
    /// ray's reciprocals (no second division per ray). The near and far planes are picked by
    /// the octant's index, not a branch: a random ray's octant is random (see max_axis, math/types.hpp).
    RAYKIT_INLINE bool test_box(const AABB& b, float tmin, float tmax) const noexcept {
        const float* const corner[2] = {&b.min.x, &b.max.x};
        float t0 = tmin, t1 = tmax;
        for (int a = 0; a < 3; ++a) {
            const int neg = near_row[a] & 1;
            t0 = robust_max((corner[neg][a] - org[a]) * inv[a], t0);
            t1 = robust_min((corner[1 - neg][a] - org[a]) * inv[a], t1);
        }
        return t0 <= t1 * kSlabExitScale;
    }

    template <int W>
    unsigned test_scalar(const WideNodeT<W>& n, float tmin, float tmax, float* RAYKIT_RESTRICT t) const noexcept {
        unsigned mask = 0;
        for (int i = 0; i < W; ++i) {
            float t0 = tmin, t1 = tmax;
            for (int a = 0; a < 3; ++a) {
                t0 = robust_max((n.planes[near_row[a]][i] - org[a]) * inv[a], t0);
                t1 = robust_min((n.planes[far_row[a]][i] - org[a]) * inv[a], t1);
            }
            t1 *= kSlabExitScale;
            t[i] = t0;
            mask |= unsigned(t0 <= t1) << i;
        }
        return mask;
    }
};

/// The walk below the entry (index, count) of a non-empty tree — a wide node (count 0) or a
/// leaf's slots — whose box the ray `wr` enters. traverse() starts it at the root; a packet walk
/// starts it at the node where its packet has thinned out (bvh/traverse_packet.hpp).
/// An entry pushed on the stack is asked for from memory at once: a wide node's four cache lines,
/// or, through `prefetch_leaf(index, count)`, what the leaf store reads first; and a node's line
/// of child indices is asked for when the walk enters it, before the box test whose mask picks
/// the child (a load that waits for the test otherwise). A random ray's node step was about 57
/// cycles, half of them cache misses and mispredicted branches; fetching ahead made random rays
/// 2-6 % faster (pushed nodes), another 1-2 % (leaves) and for any hit another 1-4 % (the child
/// line) (BlockBvh8 against Embree in one process, one thread).
template <class Mode = ClosestHit, int W, class LeafFn, class Stats = std::nullptr_t,
          class LeafPrefetch = NoLeafPrefetch>
RAYKIT_INLINE bool traverse_from(const WideBvhT<W>& bvh, const WideSlabRay& wr, const Ray& ray, float& tmax,
                                 std::uint32_t index, std::uint32_t count, LeafFn&& leaf, Stats stats = nullptr,
                                 const LeafPrefetch& prefetch_leaf = {}) {
    const WideNodeT<W>* RAYKIT_RESTRICT nodes = bvh.nodes.data();
    struct Entry {
        std::uint32_t index, count;  // count 0: a wide node; else a leaf's prim_ids range
        float t;
    };
    constexpr int kStack = (W - 1) * RAYKIT_BVH_MAX_DEPTH + 1;
    Entry stack[std::size_t(kStack)];
    int sp = 0;
    Entry cur{index, count, 0.0f};
    const auto push = [&](const Entry& e) RAYKIT_LAMBDA_INLINE {
        stack[sp++] = e;
        if (e.count == 0) {
            const char* q = reinterpret_cast<const char*>(nodes + e.index);
            for (std::size_t line = 0; line < sizeof(WideNodeT<W>); line += 64) __builtin_prefetch(q + line);
        } else {
            prefetch_leaf(e.index, e.count);
        }
    };
    bool found = false;
    for (;;) {
        if (cur.count == 0) {
            if constexpr (!std::is_same_v<Stats, std::nullptr_t>) ++stats->nodes;
            const WideNodeT<W>& n = nodes[cur.index];
            __builtin_prefetch(n.index);  // its child line, read only once the box test's mask is known
            alignas(32) float td[std::size_t(W)];
            unsigned mask = wr.test(n, ray.tmin, tmax, td);
            // One multi-way branch on the number of entered children (random
            // rays make every such branch unpredictable, so take one, not three).
            if constexpr (Mode::any_hit) {
                // any hit: order does not change the answer, so no sorting
                if (mask) {
                    if (sp + W - 1 > kStack)
                        throw std::length_error("raykit::traverse: wide tree deeper than RAYKIT_BVH_MAX_DEPTH");
                    int i = std::countr_zero(mask);
                    mask &= mask - 1;
                    cur = {n.index[i], n.count[i], td[i]};
                    while (mask) {
                        i = std::countr_zero(mask);
                        mask &= mask - 1;
                        push({n.index[i], n.count[i], td[i]});
                    }
                    continue;
                }
            } else {
                switch (std::popcount(mask)) {
                    case 0:
                        break;
                    case 1: {
                        const int i = std::countr_zero(mask);
                        cur = {n.index[i], n.count[i], td[i]};
                        continue;
                    }
                    case 2: {
                        if (sp + 1 > kStack)
                            throw std::length_error("raykit::traverse: wide tree deeper than RAYKIT_BVH_MAX_DEPTH");
                        const int i0 = std::countr_zero(mask);
                        const int i1 = std::countr_zero(mask & (mask - 1));
                        const bool swap = td[i1] < td[i0];  // ties keep slot order
                        const int a = swap ? i1 : i0, b = swap ? i0 : i1;
                        push({n.index[b], n.count[b], td[b]});
                        cur = {n.index[a], n.count[a], td[a]};
                        continue;
                    }
                    default: {
                        if (sp + W - 1 > kStack)
                            throw std::length_error("raykit::traverse: wide tree deeper than RAYKIT_BVH_MAX_DEPTH");
                        // three or more: insertion sort by entry distance (stable), push far
                        // to near
                        Entry e[std::size_t(W)];
                        int k = 0;
                        do {
                            const int i = std::countr_zero(mask);
                            mask &= mask - 1;
                            const Entry x{n.index[i], n.count[i], td[i]};
                            int j = k++;
                            while (j > 0 && e[j - 1].t > x.t) {
                                e[j] = e[j - 1];
                                --j;
                            }
                            e[j] = x;
                        } while (mask);
                        for (int j = k - 1; j >= 1; --j) push(e[j]);
                        cur = e[0];
                        continue;
                    }
                }
            }
        } else {
            if constexpr (!std::is_same_v<Stats, std::nullptr_t>) ++stats->leaves;
            if (leaf(cur.index, cur.count, tmax)) {
                found = true;
                if constexpr (Mode::any_hit) return true;
            }
        }
        for (;;) {
            if (sp == 0) return found;
            const Entry e = stack[--sp];
            if (e.t <= tmax * kSlabExitScale) {
                cur = e;
                break;
            }
        }
    }
}

template <class Mode = ClosestHit, int W, class LeafFn, class Stats = std::nullptr_t,
          class LeafPrefetch = NoLeafPrefetch>
RAYKIT_INLINE bool traverse(const WideBvhT<W>& bvh, const Ray& ray, float& tmax, LeafFn&& leaf, Stats stats = nullptr,
                            const LeafPrefetch& prefetch_leaf = {}) {
    if (bvh.nodes.empty()) return false;
    const WideSlabRay wr(ray);
    if (!wr.test_box(bvh.bounds, ray.tmin, tmax)) return false;  // the binary traversal's first test
    return RAYKIT_ISA_NS::traverse_from<Mode>(bvh, wr, ray, tmax, 0, 0, leaf, stats, prefetch_leaf);
}

}  // namespace raykit::RAYKIT_ISA_NS
#endif  // RAYKIT_ISA_PASS
