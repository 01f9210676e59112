// raykit/bvh/traverse_wide.hpp — ordered single-ray traversal of a WideBvh.
//
// traverse<Mode>(wide, ray, tmax, leaf) has the contract of the binary
// traverse() in bvh/traverse.hpp (same leaf callable, same ClosestHit/AnyHit
// modes, same TraversalStats where `nodes` counts wide nodes): at each node
// the four child boxes are slab-tested in one SSE operation, the hit children
// are sorted by entry distance, the nearest is visited and the others pushed
// far-to-near; a popped entry beyond the current tmax is skipped.
//
// The 4-wide box test makes exactly the decisions of the binary slab test
// (intersect/slab.hpp): the same (plane − origin)·(1/d) distances, NaN lanes
// never deciding (SSE max/min return their second operand on NaN, the
// current interval end, as robust_max/robust_min do), and the exit distance
// widened by the same 1 + 2·gamma(3) — applied once after the minimum, which
// gives the same float because rounding is monotone. So a WideBvh collapsed
// from a Bvh visits the same leaves a ray can hit and returns the same answer.
//
// Stack: at most 3 entries per wide level, and a wide tree is no deeper than
// its binary tree (≤ RAYKIT_BVH_MAX_DEPTH for raykit's builders); a deeper
// tree from elsewhere makes traverse throw instead of overflowing.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <type_traits>
#include <utility>

#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/wide.hpp"

#if (defined(__SSE2__) || defined(_M_X64)) && !defined(RAYKIT_NO_SIMD)
#include <emmintrin.h>
#define RAYKIT_WIDE_SSE 1
#endif

namespace raykit {

/// Per-ray state of the 4-wide slab test. test() uses SSE where the target
/// has it; test_scalar() is the plain-C++ reference it is tested against.
struct WideSlabRay {
    int near_row[3], far_row[3];  ///< WideNode::planes rows of the near/far planes per axis
    float org[3], inv[3];
#if RAYKIT_WIDE_SSE
    __m128 org4[3], inv4[3];
#endif

    explicit WideSlabRay(const Ray& r) noexcept {
        const RayInv ri(r.dir);
        const float* o = &r.org.x;
        const float* v = &ri.inv.x;
        for (int a = 0; a < 3; ++a) {
            near_row[a] = 2 * a + ri.octant[a];
            far_row[a] = 2 * a + 1 - ri.octant[a];
            org[a] = o[a];
            inv[a] = v[a];
#if RAYKIT_WIDE_SSE
            org4[a] = _mm_set1_ps(o[a]);
            inv4[a] = _mm_set1_ps(v[a]);
#endif
        }
    }

    /// Tests the four child boxes of `n` against [tmin, tmax]; returns a bit
    /// per child entered and writes the entry distances to t[0..3] (16-byte aligned).
    RAYKIT_INLINE unsigned test(const WideNode& n, float tmin, float tmax, float* RAYKIT_RESTRICT t) const noexcept {
#if RAYKIT_WIDE_SSE
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

    unsigned test_scalar(const WideNode& n, float tmin, float tmax, float* RAYKIT_RESTRICT t) const noexcept {
        unsigned mask = 0;
        for (int i = 0; i < WideNode::kWidth; ++i) {
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

template <class Mode = ClosestHit, class LeafFn, class Stats = std::nullptr_t>
bool traverse(const WideBvh& bvh, const Ray& ray, float& tmax, LeafFn&& leaf, Stats stats = nullptr) {
    if (bvh.nodes.empty()) return false;
    const WideNode* RAYKIT_RESTRICT nodes = bvh.nodes.data();
    const WideSlabRay wr(ray);

    struct Entry {
        std::uint32_t index, count;  // count 0: a wide node; else a leaf's prim_ids range
        float t;
    };
    constexpr int kStack = 3 * RAYKIT_BVH_MAX_DEPTH + 1;
    Entry stack[kStack];
    int sp = 0;
    Entry cur{0, 0, 0.0f};
    bool found = false;
    for (;;) {
        if (cur.count == 0) {
            if constexpr (!std::is_same_v<Stats, std::nullptr_t>) ++stats->nodes;
            const WideNode& n = nodes[cur.index];
            alignas(16) float td[4];
            unsigned mask = wr.test(n, ray.tmin, tmax, td);
            if (mask) {
                const int i0 = std::countr_zero(mask);
                mask &= mask - 1;
                if (!mask) {
                    cur = {n.index[i0], n.count[i0], td[i0]};
                    continue;
                }
                if (sp + 3 > kStack) throw std::length_error("raykit::traverse: wide tree deeper than RAYKIT_BVH_MAX_DEPTH");
                const int i1 = std::countr_zero(mask);
                mask &= mask - 1;
                Entry a{n.index[i0], n.count[i0], td[i0]}, b{n.index[i1], n.count[i1], td[i1]};
                if (b.t < a.t) std::swap(a, b);
                if (!mask) {  // two children: push the far one
                    stack[sp++] = b;
                    cur = a;
                    continue;
                }
                // three or four: sort by entry distance (stable), push far to near
                Entry e[4] = {a, b};
                int k = 2;
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
                for (int j = k - 1; j >= 1; --j) stack[sp++] = e[j];
                cur = e[0];
                continue;
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

}  // namespace raykit
