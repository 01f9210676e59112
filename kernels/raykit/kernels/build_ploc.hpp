// raykit/kernels/build_ploc.hpp — PLOC on the device: the merge tree of PlocBuilder
// (bvh/ploc.hpp, post-pass off) from the sorted Morton keys; the rest of the build is
// kernels/raykit/kernels/build.hpp's (after which this part comes in the program).
//
//   rk_build_morton    63-bit Morton keys (MortonQuantizer) and indices, then radix-sorted
//   rk_ploc_init       clusters in key order, working boxes (working_box)
//   per round: rk_ploc_nn (nearest of R on each side, fused_proof_half_area, first smallest),
//              rk_ploc_count, rk_ploc_sums (mutual pairs; exclusive sums of keeps and merges;
//              cluster and node counts in `state`), rk_ploc_merge (a new node takes the lower
//              place, numbered in array order)
#pragma once

namespace raykit::kernels {

inline constexpr const char* kBuildPloc = R"CLC(
RK_INLINE ulong rk_spread21(ulong x) {
    x &= 0x1FFFFFul;
    x = (x | x << 32) & 0x1F00000000FFFFul;
    x = (x | x << 16) & 0x1F0000FF0000FFul;
    x = (x | x << 8) & 0x100F00F00F00F00Ful;
    x = (x | x << 4) & 0x10C30C30C30C30C3ul;
    x = (x | x << 2) & 0x1249249249249249ul;
    return x;
}

__kernel void rk_build_morton(__global const float* cen, __global const float* fstate, const uint n,
                              __global ulong* keys, __global uint* ids) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const uint3 q = rk_morton_cells(rk_sanitized(cen, fstate, i), fstate, 1.0f, 2097151.0f);
    keys[i] = rk_spread21(q.x) << 2 | rk_spread21(q.y) << 1 | rk_spread21(q.z);
    ids[i] = i;
}

__kernel void rk_ploc_init(__global const uint* ids, __global const float* rbox, __global const float* cen,
                           __global const float* fstate, const uint n, __global float* cl, __global uint* cnode) {
    const uint s = (uint)get_global_id(0);
    if (s >= n) return;
    const uint p = ids[s];
    rk_box b = rk_load_box(rbox, p);
    const int usable = (b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z) && rk_finite3(b.lo) &&
                       rk_finite3(b.hi);
    if (!usable) b.lo = b.hi = rk_sanitized(cen, fstate, p);
    rk_cluster_set(cl, n, s, b);
    cnode[s] = p;
}

__kernel void rk_ploc_nn(__global const float* cl, const uint cap, const uint m, const uint R, __global uint* nn) {
    const uint i = (uint)get_global_id(0);
    if (i >= m || m < 2u) return;
    const rk_box a = rk_cluster_box(cl, cap, i);
    const uint b = i >= R ? i - R : 0u, e = min(m, i + R + 1u);
    uint best = RK_INVALID;
    float bestd = 0.0f;
    for (uint j = b; j < e; ++j) {
        if (j == i) continue;
        float ex = (cl[3 * cap + j] > a.hi.x ? cl[3 * cap + j] : a.hi.x) - (cl[j] < a.lo.x ? cl[j] : a.lo.x);
        float ey = (cl[4 * cap + j] > a.hi.y ? cl[4 * cap + j] : a.hi.y) -
                   (cl[cap + j] < a.lo.y ? cl[cap + j] : a.lo.y);
        float ez = (cl[5 * cap + j] > a.hi.z ? cl[5 * cap + j] : a.hi.z) -
                   (cl[2 * cap + j] < a.lo.z ? cl[2 * cap + j] : a.lo.z);
        ex = ex < FLT_MAX ? ex : FLT_MAX;
        ey = ey < FLT_MAX ? ey : FLT_MAX;
        ez = ez < FLT_MAX ? ez : FLT_MAX;
        const float d = rk_half_area3(ex, ey, ez);
        if (best == RK_INVALID || d < bestd) {
            best = j;
            bestd = d;
        }
    }
    nn[i] = best;
}

/* (keep, merge) of PLOC cluster i: a mutual pair i < j merges into i's place, j's is dropped. */
RK_INLINE uint2 rk_ploc_flag(__global const uint* nn, const uint i) {
    const uint j = nn[i];
    const int mutual = nn[j] == i;
    return (uint2)((mutual && j < i) ? 0u : 1u, (mutual && i < j) ? 1u : 0u);
}

/* The round's exclusive sums of (keep, merge) within each block (the flags made from nn on the
   fly); rk_ploc_sums then sums the blocks and sets the new counts. */
__kernel void rk_ploc_count(__global const uint* nn, const uint m, __global uint2* pos, __global uint2* sums) {
    __local uint2 part[RK_SCAN_GROUP];
    const uint first = (uint)get_group_id(0) * RK_SCAN_BLOCK + (uint)get_local_id(0) * RK_SCAN_PER;
    const uint last = min(m, first + RK_SCAN_PER);
    uint2 s = (uint2)(0u, 0u);
    for (uint i = first; i < last; ++i) s += rk_ploc_flag(nn, i);
    uint2 acc = rk_group_scan(part, s, sums);
    for (uint i = first; i < last; ++i) {
        pos[i] = acc;
        acc += rk_ploc_flag(nn, i);
    }
}
/* One work item: block sums made exclusive; state: [7] the merge-tree size before the round
   (the new nodes' base), [0] the new cluster count, [1] the new size, [2] rounds. */
__kernel void rk_ploc_sums(__global uint2* sums, const uint blocks, __global uint* state) {
    if (get_global_id(0) != 0) return;
    const uint2 total = rk_serial_scan(sums, blocks);
    state[7] = state[1];
    state[0] = total.x;
    state[1] += total.y;
    state[2] += 1u;
}

__kernel void rk_ploc_merge(__global const float* cl, __global const uint* cnode, __global float* next,
                            __global uint* nnode, const uint cap, __global const uint* nn,
                            __global const uint2* pos, __global const uint2* sums, __global const uint* state,
                            const uint n, const uint m, __global uint2* kids) {
    const uint i = (uint)get_global_id(0);
    if (i >= m || m < 2u) return;
    const uint j = nn[i];
    const int mutual = nn[j] == i;
    if (mutual && j < i) return;
    const uint2 p = pos[i] + sums[i / RK_SCAN_BLOCK];
    rk_box b = rk_cluster_box(cl, cap, i);
    uint id = cnode[i];
    if (mutual) {
        const uint k = state[7] + p.y;
        kids[k] = (uint2)(cnode[i], cnode[j]);
        rk_box_grow(&b, rk_cluster_box(cl, cap, j));
        id = n + k;
    }
    rk_cluster_set(next, cap, p.x, b);
    nnode[p.x] = id;
}
)CLC";

}  // namespace raykit::kernels
