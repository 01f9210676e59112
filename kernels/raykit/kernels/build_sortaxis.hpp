// raykit/kernels/build_sortaxis.hpp — sort by axis on the device: the merge tree of
// SortAxisBuilder's default (Morton axis, area metric, mutual pairing within a window of W on
// each side, greedy on a level with too few mutual pairs); the rest of the build is
// kernels/raykit/kernels/build.hpp's (after which this part comes in the program).
//
// Elements of a level live in the element arrays (box, node id) with a 30-bit key each
// (ekey). Per level: the keys radix-sorted (4 passes: stable over element order, as the CPU's
// sort words), rk_sa_gather, rk_sa_nearest, rk_sa_count (one item per chunk), rk_sa_plan (one
// item), rk_sa_pair (one item per chunk, in order). Chunks of a level: max(1, m /
// RK_SA_CHUNK), chunk c from m·c/chunks (SortAxisBuilder's constants, set by build_parts).
#pragma once

namespace raykit::kernels {

inline constexpr const char* kBuildSortAxis = R"CLC(
RK_INLINE uint rk_spread10(uint x) {
    x = (x | x << 16) & 0x030000FFu;
    x = (x | x << 8) & 0x0300F00Fu;
    x = (x | x << 4) & 0x030C30C3u;
    x = (x | x << 2) & 0x09249249u;
    return x;
}
/* MortonQuantizer::code30 over the centroid bounds in fstate */
RK_INLINE uint rk_code30(const float3 p, __global const float* fstate) {
    const uint3 q = rk_morton_cells(p, fstate, 1.0f / 2048.0f, 1023.0f);
    return rk_spread10(q.x) << 2 | rk_spread10(q.y) << 1 | rk_spread10(q.z);
}
RK_INLINE uint rk_chunks(const uint m) { return max(1u, m / RK_SA_CHUNK); }
RK_INLINE uint rk_chunk_lo(const uint m, const uint chunks, const uint c) { return (uint)(((ulong)m * c) / chunks); }

/* Level 0: every primitive an element (working box, node = its index, key of its sanitized
   centroid); the sort keys of the level as (key, element). */
__kernel void rk_sa_init(__global const float* rbox, __global const float* cen, __global const float* fstate,
                         const uint n, __global float* cl, __global uint* cnode, __global uint* ekey) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    rk_box b = rk_load_box(rbox, i);
    const int usable = (b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z) && rk_finite3(b.lo) &&
                       rk_finite3(b.hi);
    const float3 c = rk_sanitized(cen, fstate, i);
    if (!usable) b.lo = b.hi = c;
    rk_cluster_set(cl, n, i, b);
    cnode[i] = i;
    ekey[i] = rk_code30(c, fstate);
}
__kernel void rk_sa_keys(__global const uint* ekey, const uint m, __global ulong* keys, __global uint* ids) {
    const uint i = (uint)get_global_id(0);
    if (i >= m) return;
    keys[i] = (ulong)ekey[i];
    ids[i] = i;
}
/* The level in sorted order: srt[s] = element ids[s]. */
__kernel void rk_sa_gather(__global const uint* ids, __global const float* cl, __global const uint* cnode,
                           const uint cap, const uint m, __global float* srt, __global uint* snode) {
    const uint s = (uint)get_global_id(0);
    if (s >= m) return;
    const uint e = ids[s];
    rk_cluster_set(srt, cap, s, rk_cluster_box(cl, cap, e));
    snode[s] = cnode[e];
}
/* SortAxisBuilder::area_dist */
RK_INLINE float rk_area_dist(__global const float* c, const uint cap, const uint a, const uint b) {
    float ex = (c[3 * cap + a] < c[3 * cap + b] ? c[3 * cap + b] : c[3 * cap + a]) - (c[b] < c[a] ? c[b] : c[a]);
    float ey = (c[4 * cap + a] < c[4 * cap + b] ? c[4 * cap + b] : c[4 * cap + a]) -
               (c[cap + b] < c[cap + a] ? c[cap + b] : c[cap + a]);
    float ez = (c[5 * cap + a] < c[5 * cap + b] ? c[5 * cap + b] : c[5 * cap + a]) -
               (c[2 * cap + b] < c[2 * cap + a] ? c[2 * cap + b] : c[2 * cap + a]);
    ex = ex < FLT_MAX ? ex : FLT_MAX;
    ey = ey < FLT_MAX ? ey : FLT_MAX;
    ez = ez < FLT_MAX ? ez : FLT_MAX;
    return rk_half_area3(ex, ey, ez);
}
/* SortAxisBuilder::nearest: the nearest of the sorted level's i − W … i + W within i's chunk,
   ties by the rank of the pair (offset, parity of its lower position, then position). */
__kernel void rk_sa_nearest(__global const float* srt, const uint cap, const uint m, const uint window,
                            __global uint* nn) {
    const uint i = (uint)get_global_id(0);
    if (i >= m) return;
    const uint chunks = rk_chunks(m);
    uint c = (uint)(((ulong)i * chunks) / m);
    if (c + 1u < chunks && rk_chunk_lo(m, chunks, c + 1u) <= i) ++c;
    const uint lo = rk_chunk_lo(m, chunks, c), hi = rk_chunk_lo(m, chunks, c + 1u), len = hi - lo;
    const uint W = min(window, len - 1u), r = i - lo;
    if (W == 0u) {
        nn[i] = i;
        return;
    }
    ulong best = 0xFFFFFFFFFFFFFFFFul;
    for (uint k = min(W, r); k >= 1u; --k) {
        const float d = rk_area_dist(srt, cap, i - k, i);
        const ulong key = (ulong)as_uint(d) << 32 | (ulong)(2u * k + ((i - k - lo) & 1u)) << 13 | (ulong)(W - k);
        best = min(best, key);
    }
    for (uint k = 1u; k <= W && r + k < len; ++k) {
        const float d = rk_area_dist(srt, cap, i, i + k);
        const ulong key = (ulong)as_uint(d) << 32 | (ulong)(2u * k + ((i - lo) & 1u)) << 13 | (ulong)(W - 1u + k);
        best = min(best, key);
    }
    const uint cc = (uint)(best & 0x1FFFul);
    nn[i] = cc < W ? i - W + cc : i - W + cc + 1u;
}
/* Per chunk: (elements out, new nodes) of mutual pairing. */
__kernel void rk_sa_count(__global const uint* nn, const uint m, __global uint2* chunk) {
    const uint c = (uint)get_global_id(0), chunks = rk_chunks(m);
    if (c >= chunks) return;
    const uint lo = rk_chunk_lo(m, chunks, c), hi = rk_chunk_lo(m, chunks, c + 1u);
    uint pairs = 0u;
    for (uint i = lo; i < hi; ++i) pairs += nn[i] > i && nn[nn[i]] == i;
    chunk[c] = (uint2)(hi - lo - pairs, pairs);
}
/* One item: mutual or greedy for the level (greedy when m > RK_SA_GREEDY_MIN and fewer than
   1 / RK_SA_MUTUAL_SHARE of the elements pair), the chunks' first output and node (exclusive
   sums), and state: [7] the merge-tree size before the level, [0] the next level's elements,
   [1] the merge-tree size after it, [2] levels, [6] greedy. */
__kernel void rk_sa_plan(__global uint2* chunk, const uint m, __global uint* state) {
    if (get_global_id(0) != 0) return;
    const uint chunks = rk_chunks(m);
    uint pairs = 0u;
    for (uint c = 0; c < chunks; ++c) pairs += chunk[c].y;
    const int greedy = m > RK_SA_GREEDY_MIN && (ulong)pairs * RK_SA_MUTUAL_SHARE < (ulong)m;
    uint2 acc = (uint2)(0u, 0u);
    for (uint c = 0; c < chunks; ++c) {
        const uint len = rk_chunk_lo(m, chunks, c + 1u) - rk_chunk_lo(m, chunks, c);
        const uint2 v = greedy ? (uint2)((len + 1u) / 2u, len / 2u) : chunk[c];
        chunk[c] = acc;
        acc += v;
    }
    state[7] = state[1];
    state[0] = acc.x;
    state[1] += acc.y;
    state[2] += 1u;
    state[6] = greedy ? 1u : 0u;
}
/* Makes the node over sorted elements a and b: new node `id` (merge-tree index), element o of
   the next level (its box, node and the key of its box's centre). */
RK_INLINE void rk_sa_make(__global const float* srt, __global const uint* snode, const uint cap, const uint a,
                          const uint b, const uint id, const uint n, const uint o, __global float* next,
                          __global uint* nnode, __global uint* nkey, __global uint2* kids,
                          __global const float* fstate) {
    rk_box box = rk_cluster_box(srt, cap, a);
    rk_box_grow(&box, rk_cluster_box(srt, cap, b));
    kids[id] = (uint2)(snode[a], snode[b]);
    rk_cluster_set(next, cap, o, box);
    nnode[o] = n + id;
    nkey[o] = rk_code30(box.lo * 0.5f + box.hi * 0.5f, fstate);
}
/* Per chunk, in order (SortAxisBuilder::pair_mutual / pair_greedy): the next level keeps the
   chunk's order, a new node where its first element was; carried elements keep their keys. */
__kernel void rk_sa_pair(__global const float* srt, __global const uint* snode, __global const ulong* skey,
                         const uint cap, const uint m, __global const uint* nn, __global const uint2* chunk,
                         __global const uint* state, const uint n, const uint window, __global float* next,
                         __global uint* nnode, __global uint* nkey, __global uint2* kids,
                         __global const float* fstate) {
    const uint c = (uint)get_global_id(0), chunks = rk_chunks(m);
    if (c >= chunks) return;
    const uint lo = rk_chunk_lo(m, chunks, c), hi = rk_chunk_lo(m, chunks, c + 1u);
    const uint base = state[7] + chunk[c].y, out = chunk[c].x;
    uint p = 0u, t = 0u;
    if (state[6] == 0u) {
        for (uint i = lo; i < hi; ++i) {
            const uint j = nn[i];
            if (j == i || nn[j] != i) {
                rk_cluster_set(next, cap, out + t, rk_cluster_box(srt, cap, i));
                nnode[out + t] = snode[i];
                nkey[out + t] = (uint)skey[i];
                ++t;
            } else if (i < j) {
                rk_sa_make(srt, snode, cap, i, j, base + p, n, out + t, next, nnode, nkey, kids, fstate);
                ++p;
                ++t;
            }
        }
        return;
    }
    uint win[RK_SA_MAX_WINDOW + 1];
    uint wn = 0u, q = lo;
    for (;;) {
        while (wn < window + 1u && q < hi) win[wn++] = q++;
        if (wn == 0u) break;
        const uint k = win[0];
        if (wn == 1u) {
            rk_cluster_set(next, cap, out + t, rk_cluster_box(srt, cap, k));
            nnode[out + t] = snode[k];
            nkey[out + t] = (uint)skey[k];
            break;
        }
        uint best = 1u;
        float bd = rk_area_dist(srt, cap, k, win[1]);
        for (uint j = 2u; j < wn; ++j) {
            const float d = rk_area_dist(srt, cap, k, win[j]);
            if (d < bd) {
                bd = d;
                best = j;
            }
        }
        rk_sa_make(srt, snode, cap, k, win[best], base + t, n, out + t, next, nnode, nkey, kids, fstate);
        ++t;
        uint w = 0u;
        for (uint j = 1u; j < wn; ++j)
            if (j != best) win[w++] = win[j];
        wn = w;
    }
}
)CLC";

}  // namespace raykit::kernels
