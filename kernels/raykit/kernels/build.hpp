// raykit/kernels/build.hpp — building an object's tree on the device (cl/device_build.hpp):
// what the device's twins of the bottom-up builders share. The builders themselves make the
// merge tree (kernels/raykit/kernels/build_ploc.hpp, build_sortaxis.hpp; a program holds the
// one it uses); this part holds the stages before and after them, the twins of
// primitive_refs, sanitize_centers, the radix sort, and the back end that turns the merge
// tree into BlockBvh8::build's 8-wide tree and blocks in device_tree()'s form, bit for bit.
//
// Stages (one work item per primitive, element or node unless said):
//   rk_build_refs      triangle boxes (MeshView::bounds) and centres (AABB::center; NaN when empty)
//   rk_build_bounds    one work-group: bounds of the finite centres (sanitize_centers)
//   rk_radix_count / rk_radix_scatter   LSD radix sort of (key, index), 8 bits a pass, stable:
//                      the CPU's order (its radix sort of keys over indices 0..n-1)
//   rk_scan_*          exclusive sums of uint2 (block scans, or one work-group for short runs)
//   -- the builder's rounds or levels (build_ploc.hpp / build_sortaxis.hpp) --
//   rk_tree_parents, rk_tree_up   real boxes, counts and the leaf merge (node_cost) bottom-up;
//                      the last of two children to arrive computes the parent (atomic counter)
//   rk_tree_top, rk_tree_down   top-down, one launch per round or level (last to first):
//                      first prim_ids slot (left-to-right order) of every node, and its leaf
//   rk_tree_slots      per primitive: its slot, its leaf's first slot and size, block starts
//                      flagged (then scanned)
//   rk_tree_blocks     the leaves' TriangleBlock4s (lanes past a leaf's end repeat its last)
//   rk_tree_roots      which inner nodes start a wide node: the collapse of wide.hpp (open the
//                      child of largest area until 8), one launch per wide level from the root;
//                      wide nodes are numbered in descending merge id (a scan of the flags), so
//                      a child comes after its parent
//   rk_tree_wide       the wide nodes (device_tree's form: node 0 the root box alone) and the
//                      refit tables of the new topology (parents, needs, one-pass starts)
//   rk_tree_cost       the SAH cost of objects' wide trees, for the rebuild policy
// Decisions use the same floats as the CPU: areas through fused_proof_half_area (products
// exact in double), FP_CONTRACT off, min/max by the same selects.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kBuild = R"CLC(
#pragma OPENCL FP_CONTRACT OFF
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* raykit::fused_proof_half_area */
RK_INLINE float rk_half_area3(const float ex, const float ey, const float ez) {
    const double x = ex, y = ey, z = ez;
    return (float)((x * y + y * z) + z * x);
}
RK_INLINE float rk_box_half_area(const rk_box b) {
    const int empty = !(b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z);
    if (empty) return 0.0f;
    const float3 e = b.hi - b.lo;
    return rk_half_area3(e.x, e.y, e.z);
}
RK_INLINE rk_box rk_load_box(__global const float* b, const uint i) {
    rk_box r;
    r.lo = vload3(2 * i, b);
    r.hi = vload3(2 * i + 1, b);
    return r;
}
RK_INLINE void rk_store_box(__global float* b, const uint i, const rk_box r) {
    vstore3(r.lo, 2 * i, b);
    vstore3(r.hi, 2 * i + 1, b);
}
RK_INLINE int rk_finite3(const float3 p) { return all(isfinite(p)); }

/* state: [0] elements (clusters), [1] merge-tree nodes, [2] rounds or levels, [3] wide nodes,
   [4] blocks, [5] height of the root, [6] (sort by axis) the level pairs greedily, [7]
   merge-tree nodes before the round; fstate: [0..5] centroid bounds */

__kernel void rk_build_refs(__global const uint* tris, __global const float* pos, const uint tri_off,
                            const uint vert_off, const uint n, __global float* rbox, __global float* cen) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const uint3 t = vload3(tri_off + i, tris);
    const rk_box b = rk_triangle_box(vload3(vert_off + t.x, pos), vload3(vert_off + t.y, pos),
                                     vload3(vert_off + t.z, pos));
    rk_store_box(rbox, i, b);
    const int empty = !(b.lo.x <= b.hi.x && b.lo.y <= b.hi.y && b.lo.z <= b.hi.z);
    vstore3(empty ? (float3)(NAN) : (b.lo + b.hi) * 0.5f, i, cen);
}

/* One work-group of RK_BUILD_GROUP items. Bounds of the finite centres; a non-finite centre
   is later read as the centre of those (empty: the origin, and the bounds that point). */
__kernel void rk_build_bounds(__global const float* cen, const uint n, __global float* fstate,
                              __global uint* state) {
    __local float lo[3][RK_BUILD_GROUP], hi[3][RK_BUILD_GROUP];
    const uint l = (uint)get_local_id(0);
    float3 a = (float3)(INFINITY), b = (float3)(-INFINITY);
    for (uint i = l; i < n; i += RK_BUILD_GROUP) {
        const float3 c = vload3(i, cen);
        if (!rk_finite3(c)) continue;
        a = select(a, c, isless(c, a));
        b = select(b, c, isgreater(c, b));
    }
    lo[0][l] = a.x; lo[1][l] = a.y; lo[2][l] = a.z;
    hi[0][l] = b.x; hi[1][l] = b.y; hi[2][l] = b.z;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l != 0) return;
    for (uint k = 1; k < RK_BUILD_GROUP; ++k)
        for (int x = 0; x < 3; ++x) {
            lo[x][0] = lo[x][k] < lo[x][0] ? lo[x][k] : lo[x][0];
            hi[x][0] = hi[x][k] > hi[x][0] ? hi[x][k] : hi[x][0];
        }
    const int empty = !(lo[0][0] <= hi[0][0] && lo[1][0] <= hi[1][0] && lo[2][0] <= hi[2][0]);
    for (int x = 0; x < 3; ++x) {
        fstate[x] = empty ? 0.0f : lo[x][0];
        fstate[3 + x] = empty ? 0.0f : hi[x][0];
    }
    for (int k = 0; k < 8; ++k) state[k] = 0u;
    state[0] = n;
}

RK_INLINE float3 rk_sanitized(__global const float* cen, __global const float* fstate, const uint i) {
    const float3 c = vload3(i, cen);
    return rk_finite3(c) ? c : (vload3(0, fstate) + vload3(1, fstate)) * 0.5f;
}

/* MortonQuantizer over the centroid bounds in fstate: p's cell per axis, (p − lo)·scale·per_unit
   with scale = 2097151 / the largest extent (one scale on every axis), clamped to [0, top]
   (NaN to 0). PLOC's 63-bit codes: per_unit 1, top 2097151; code30: per_unit 1/2048, top 1023. */
RK_INLINE uint3 rk_morton_cells(const float3 p, __global const float* fstate, const float per_unit, const float top) {
    const float3 lo = vload3(0, fstate), e = vload3(1, fstate) - lo;
    const float m = e.x < e.y ? (e.y < e.z ? e.z : e.y) : (e.x < e.z ? e.z : e.x);
    const float scale = (m > 0.0f && m < INFINITY ? 2097151.0f / m : 0.0f) * per_unit;
    float3 f = (p - lo) * scale;
    f = select((float3)(0.0f), f, isgreater(f, (float3)(0.0f)));
    f = select((float3)(top), f, isless(f, (float3)(top)));
    return convert_uint3(f);
}

/* LSD radix sort of (key, index), 8 bits a pass: stable, so from indices in order it gives the
   order of the CPU's radix sort (util/radix_sort.hpp). One work item per block of
   RK_RADIX_BLOCK entries counts its digits, then scatters its entries in order; counts are
   stored digit-major (counts[digit * blocks + block]), so their exclusive sums are the first
   slot of each (digit, block). Private counters: fine on CPU devices; a GPU would want a
   work-group per block and local-memory ranks. */
__kernel void rk_radix_count(__global const ulong* keys, const uint n, const uint shift, __global uint2* counts,
                             const uint blocks) {
    const uint b = (uint)get_global_id(0);
    if (b >= blocks) return;
    uint c[256];
    for (int d = 0; d < 256; ++d) c[d] = 0u;
    const uint first = b * RK_RADIX_BLOCK, last = min(n, first + RK_RADIX_BLOCK);
    for (uint i = first; i < last; ++i) ++c[(uint)(keys[i] >> shift) & 255u];
    for (int d = 0; d < 256; ++d) counts[(uint)d * blocks + b] = (uint2)(c[d], 0u);
}
__kernel void rk_radix_scatter(__global const ulong* keys, __global const uint* ids, __global ulong* keys_out,
                               __global uint* ids_out, const uint n, const uint shift,
                               __global const uint2* offsets, const uint blocks) {
    const uint b = (uint)get_global_id(0);
    if (b >= blocks) return;
    uint o[256];
    for (int d = 0; d < 256; ++d) o[d] = offsets[(uint)d * blocks + b].x;
    const uint first = b * RK_RADIX_BLOCK, last = min(n, first + RK_RADIX_BLOCK);
    for (uint i = first; i < last; ++i) {
        const ulong k = keys[i];
        const uint j = o[(uint)(k >> shift) & 255u]++;
        keys_out[j] = k;
        ids_out[j] = ids[i];
    }
}

/* Elements (PLOC's clusters, sort by axis's level): six float arrays of `cap` (lx, ly, lz, hx,
   hy, hz) and node ids. */
RK_INLINE rk_box rk_cluster_box(__global const float* c, const uint cap, const uint i) {
    rk_box b;
    b.lo = (float3)(c[i], c[cap + i], c[2 * cap + i]);
    b.hi = (float3)(c[3 * cap + i], c[4 * cap + i], c[5 * cap + i]);
    return b;
}
RK_INLINE void rk_cluster_set(__global float* c, const uint cap, const uint i, const rk_box b) {
    c[i] = b.lo.x; c[cap + i] = b.lo.y; c[2 * cap + i] = b.lo.z;
    c[3 * cap + i] = b.hi.x; c[4 * cap + i] = b.hi.y; c[5 * cap + i] = b.hi.z;
}

/* Block scans: a work-group of RK_SCAN_GROUP items takes a block of RK_SCAN_BLOCK entries,
   RK_SCAN_PER = RK_SCAN_BLOCK / RK_SCAN_GROUP consecutive ones per item. rk_group_scan: each
   item brings the total of its entries and gets the total of the items before it; item 0
   writes the block's total to sums[group]. rk_serial_scan: sums[0..blocks) made exclusive in
   place by one work item; returns the total. */
#define RK_SCAN_PER (RK_SCAN_BLOCK / RK_SCAN_GROUP)
RK_INLINE uint2 rk_group_scan(__local uint2* part, const uint2 s, __global uint2* sums) {
    const uint l = (uint)get_local_id(0);
    part[l] = s;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (l == 0u) {
        uint2 acc = (uint2)(0u, 0u);
        for (uint k = 0; k < RK_SCAN_GROUP; ++k) {
            const uint2 v = part[k];
            part[k] = acc;
            acc += v;
        }
        sums[get_group_id(0)] = acc;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    return part[l];
}
RK_INLINE uint2 rk_serial_scan(__global uint2* sums, const uint blocks) {
    uint2 acc = (uint2)(0u, 0u);
    for (uint k = 0; k < blocks; ++k) {
        const uint2 v = sums[k];
        sums[k] = acc;
        acc += v;
    }
    return acc;
}

/* This item's entries in[first, last) summed into out, exclusive, after the entries of the
   work-group's items before it (rk_group_scan: the group's total to group_sums[group]). */
RK_INLINE void rk_scan_items(__global const uint2* in, __global uint2* out, const uint first, const uint last,
                             __local uint2* part, __global uint2* group_sums) {
    uint2 s = (uint2)(0u, 0u);
    for (uint k = first; k < last; ++k) s += in[k];
    uint2 acc = rk_group_scan(part, s, group_sums);
    for (uint k = first; k < last; ++k) {
        const uint2 v = in[k];
        out[k] = acc;
        acc += v;
    }
}

/* Exclusive sums of uint2 over `count` entries: the blocks, then the block sums (total[0]: all
   of them), then the blocks' offsets added. */
__kernel void rk_scan_blocks(__global const uint2* in, __global uint2* out, __global uint2* sums, const uint count) {
    __local uint2 part[RK_SCAN_GROUP];
    const uint first = (uint)get_group_id(0) * RK_SCAN_BLOCK + (uint)get_local_id(0) * RK_SCAN_PER;
    rk_scan_items(in, out, first, min(count, first + RK_SCAN_PER), part, sums);
}
__kernel void rk_scan_sums(__global uint2* sums, const uint blocks, __global uint2* total) {
    if (get_global_id(0) == 0) total[0] = rk_serial_scan(sums, blocks);
}
/* The whole scan in one work-group of RK_SCAN_GROUP items (short arrays: one launch instead of
   three); each item takes ceil(count / RK_SCAN_GROUP) consecutive entries. */
__kernel void rk_scan_one_group(__global const uint2* in, __global uint2* out, const uint count,
                                __global uint2* total) {
    __local uint2 part[RK_SCAN_GROUP];
    const uint per = (count + RK_SCAN_GROUP - 1u) / RK_SCAN_GROUP;
    const uint first = min(count, (uint)get_local_id(0) * per);
    rk_scan_items(in, out, first, min(count, first + per), part, total);
}
__kernel void rk_scan_add(__global uint2* out, __global const uint2* sums, const uint count) {
    const uint k = (uint)get_global_id(0);
    if (k < count) out[k] += sums[k / RK_SCAN_BLOCK];
}

/* ---------------------------------------------------------------- back end */

/* Per merge-tree node (ids < n primitives, n + k inner): parent. */
__kernel void rk_tree_parents(__global const uint2* kids, const uint n, __global uint* parent) {
    const uint k = (uint)get_global_id(0);
    if (k >= n - 1u) return;
    parent[kids[k].x] = n + k;
    parent[kids[k].y] = n + k;
    if (k == n - 2u) parent[n + k] = RK_INVALID;
}

typedef struct {
    uint count, out, height;
    float cost;
} rk_subtree;

RK_INLINE rk_subtree rk_read_sub(__global const float* rbox, volatile __global const float* ibox,
                                 volatile __global const uint* icnt, const uint n, const uint x, const float ci,
                                 rk_box* box) {
    rk_subtree s;
    if (x < n) {
        *box = rk_load_box(rbox, x);
        s.count = 1u;
        s.out = 1u;
        s.height = 0u;
        s.cost = ci * rk_box_half_area(*box);
    } else {
        const uint k = x - n;
        box->lo = (float3)(ibox[6 * k], ibox[6 * k + 1], ibox[6 * k + 2]);
        box->hi = (float3)(ibox[6 * k + 3], ibox[6 * k + 4], ibox[6 * k + 5]);
        s.count = icnt[4 * k];
        s.out = icnt[4 * k + 1];
        s.height = icnt[4 * k + 2];
        s.cost = as_float(icnt[4 * k + 3]);
    }
    return s;
}

/* One item per primitive; at each parent the second child to arrive computes it: real box
   (kid 0's grown by kid 1's), count, output size, height and the leaf merge's best cost
   (node_cost: a leaf when count <= max_leaf and Ci·SA·blocks <= Ct·SA + children). */
__kernel void rk_tree_up(__global const uint2* kids, __global const uint* parent, __global uint* counters,
                         __global const float* rbox, __global float* ibox, __global uint* icnt, const uint n,
                         const float ct, const float ci, const uint max_leaf, const uint block_shift,
                         __global uint* state) {
    const uint p = (uint)get_global_id(0);
    if (p >= n) return;
    uint g = parent[p];
    while (g != RK_INVALID) {
        const uint k = g - n;
        RK_GLOBAL_FENCE();
        if (atomic_inc(&counters[k]) == 0u) return;  /* the sibling computes g */
        RK_GLOBAL_FENCE();
        counters[k] = 0u;
        rk_box ba, bb;
        const rk_subtree a = rk_read_sub(rbox, ibox, icnt, n, kids[k].x, ci, &ba);
        const rk_subtree b = rk_read_sub(rbox, ibox, icnt, n, kids[k].y, ci, &bb);
        rk_box_grow(&ba, bb);
        const float sa = rk_box_half_area(ba);
        const uint cnt = a.count + b.count;
        const float split = (float)((double)ct * sa + (double)(a.cost + b.cost));
        const float leaf = ci * sa * (float)((cnt + (1u << block_shift) - 1u) >> block_shift);
        const int is_leaf = cnt <= max_leaf && leaf <= split;
        ibox[6 * k] = ba.lo.x; ibox[6 * k + 1] = ba.lo.y; ibox[6 * k + 2] = ba.lo.z;
        ibox[6 * k + 3] = ba.hi.x; ibox[6 * k + 4] = ba.hi.y; ibox[6 * k + 5] = ba.hi.z;
        icnt[4 * k] = cnt;
        icnt[4 * k + 1] = is_leaf ? 1u : 1u + a.out + b.out;
        icnt[4 * k + 2] = 1u + max(a.height, b.height);
        icnt[4 * k + 3] = as_uint(is_leaf ? leaf : split);
        if (parent[g] == RK_INVALID) state[5] = 1u + max(a.height, b.height);
        g = parent[g];
    }
}

RK_INLINE uint rk_count_of(__global const uint* icnt, const uint n, const uint x) { return x < n ? 1u : icnt[4 * (x - n)]; }
RK_INLINE uint rk_out_of(__global const uint* icnt, const uint n, const uint x) { return x < n ? 1u : icnt[4 * (x - n) + 1]; }

/* Top-down, one launch per PLOC round from the last to the first (a node's parent is of a
   later round): each node of the round (merge-tree indices [lo, hi)) gives its children their
   first prim_ids slot (left-to-right order) and the leaf they lie in, as (first slot, size),
   or RK_INVALID above the leaves: a leaf is the first node of output size 1 on the way down
   (the back end's top-down emission). rk_tree_top seeds the root. */
__kernel void rk_tree_top(__global const uint* icnt, const uint n, __global uint* first, __global uint2* leaf) {
    if (get_global_id(0) != 0) return;
    const uint root = n == 1u ? 0u : 2u * n - 2u;
    first[root] = 0u;
    leaf[root] = rk_out_of(icnt, n, root) == 1u ? (uint2)(0u, rk_count_of(icnt, n, root)) : (uint2)(RK_INVALID, 0u);
}
__kernel void rk_tree_down(__global const uint2* kids, __global const uint* icnt, const uint n, const uint lo,
                           const uint hi, __global uint* first, __global uint2* leaf) {
    const uint k = lo + (uint)get_global_id(0);
    if (k >= hi) return;
    const uint f = first[n + k];
    const uint2 lf = leaf[n + k];
    const uint a = kids[k].x, b = kids[k].y;
    const uint fb = f + rk_count_of(icnt, n, a);
    first[a] = f;
    first[b] = fb;
    if (lf.x != RK_INVALID) {
        leaf[a] = lf;
        leaf[b] = lf;
    } else {
        leaf[a] = rk_out_of(icnt, n, a) == 1u ? (uint2)(f, rk_count_of(icnt, n, a)) : (uint2)(RK_INVALID, 0u);
        leaf[b] = rk_out_of(icnt, n, b) == 1u ? (uint2)(fb, rk_count_of(icnt, n, b)) : (uint2)(RK_INVALID, 0u);
    }
}
/* Per primitive: prim_ids[slot] = p, its leaf (first slot, size) by slot, and whether the slot
   starts a block of 4. */
__kernel void rk_tree_slots(__global const uint* first, __global const uint2* leaf, const uint n, __global uint* prims,
                            __global uint2* leaf_of, __global uint2* bflag) {
    const uint p = (uint)get_global_id(0);
    if (p >= n) return;
    const uint s = first[p];
    const uint2 lf = leaf[p];
    prims[s] = p;
    leaf_of[s] = lf;
    bflag[s] = (uint2)(((s - lf.x) & 3u) == 0u ? 1u : 0u, 0u);
}

__kernel void rk_tree_blocks(__global const uint* prims, __global const uint2* leaf_of, __global const uint2* bflag,
                             __global const uint2* bpos, const uint n, __global const uint* tris,
                             __global const float* pos, const uint tri_off, const uint vert_off,
                             __global rk_block* blocks, const uint block_off, __global uint* state) {
    const uint s = (uint)get_global_id(0);
    if (s >= n) return;
    if (s == n - 1u) state[4] = bpos[s].x + bflag[s].x;
    if (bflag[s].x == 0u) return;
    __global rk_block* blk = blocks + block_off + bpos[s].x;
    const uint2 lf = leaf_of[s];
    for (int i = 0; i < 4; ++i) {
        const uint t = min(s + (uint)i, lf.x + lf.y - 1u);
        const uint pr = prims[t];
        const uint3 tv = vload3(tri_off + pr, tris);
        const float3 p0 = vload3(vert_off + tv.x, pos), p1 = vload3(vert_off + tv.y, pos), p2 = vload3(vert_off + tv.z, pos);
        blk->p[0][i] = p0.x; blk->p[1][i] = p0.y; blk->p[2][i] = p0.z;
        blk->p[3][i] = p1.x; blk->p[4][i] = p1.y; blk->p[5][i] = p1.z;
        blk->p[6][i] = p2.x; blk->p[7][i] = p2.y; blk->p[8][i] = p2.z;
        blk->prim[i] = pr;
    }
}

/* The real box of merge-tree node x (a primitive's, or an inner node's from rk_tree_up). */
RK_INLINE rk_box rk_node_box(__global const float* rbox, __global const float* ibox, const uint n, const uint x) {
    if (x < n) return rk_load_box(rbox, x);
    rk_box b;
    const uint q = x - n;
    b.lo = (float3)(ibox[6 * q], ibox[6 * q + 1], ibox[6 * q + 2]);
    b.hi = (float3)(ibox[6 * q + 3], ibox[6 * q + 4], ibox[6 * q + 5]);
    return b;
}

/* The slots of the wide node that starts at inner node v (WideBvhT::build_nodes): open the
   inner child of largest area (first one on ties) until RK_WIDTH; left replaces the parent,
   right goes after it. Returns the slot count. */
RK_INLINE int rk_expand(const uint v, __global const uint2* kids, __global const float* rbox,
                        __global const float* ibox, __global const uint* icnt, const uint n, uint* slot) {
    int k = 2;
    slot[0] = kids[v - n].x;
    slot[1] = kids[v - n].y;
    while (k < RK_WIDTH) {
        int best = -1;
        float best_area = -1.0f;
        for (int i = 0; i < k; ++i) {
            if (rk_out_of(icnt, n, slot[i]) == 1u) continue;
            const float a = rk_box_half_area(rk_node_box(rbox, ibox, n, slot[i]));
            if (best < 0 || a > best_area) {
                best = i;
                best_area = a;
            }
        }
        if (best < 0) break;
        const uint c = slot[best];
        for (int i = k; i > best + 1; --i) slot[i] = slot[i - 1];
        slot[best] = kids[c - n].x;
        slot[best + 1] = kids[c - n].y;
        ++k;
    }
    return k;
}

/* Which inner nodes start a wide node, level by level from the root (wflag[root - id]): the
   root does; each wide node of a level marks its inner slots (rk_expand) and lists them for
   the next level. counts[L]: nodes on level L (the list order varies, the flags do not). */
__kernel void rk_tree_roots_init(__global const uint* icnt, const uint n, __global uint2* wflag, __global uint* list,
                                 __global uint* counts) {
    const uint q = (uint)get_global_id(0);
    if (q >= n - 1u) return;
    const int inner = rk_out_of(icnt, n, 2u * n - 2u) != 1u;
    wflag[q] = (uint2)(q == 0u && inner ? 1u : 0u, 0u);
    if (q == 0u) {
        list[0] = 2u * n - 2u;
        counts[0] = inner ? 1u : 0u;
        for (int l = 1; l < RK_MAX_DEPTH + 2; ++l) counts[l] = 0u;
    }
}
__kernel void rk_tree_roots(__global const uint2* kids, __global const float* rbox, __global const float* ibox,
                            __global const uint* icnt, const uint n, __global const uint* list, __global uint* out,
                            __global uint* counts, const uint level, __global uint2* wflag) {
    const uint i = (uint)get_global_id(0);
    if (i >= counts[level]) return;
    uint slot[RK_WIDTH];
    const int cnt = rk_expand(list[i], kids, rbox, ibox, icnt, n, slot);
    for (int c = 0; c < cnt; ++c) {
        if (rk_out_of(icnt, n, slot[c]) == 1u) continue;
        wflag[2u * n - 2u - slot[c]] = (uint2)(1u, 0u);
        out[atomic_inc(&counts[level + 1u])] = slot[c];
    }
}

RK_INLINE void rk_slot_clear(__global rk_wnode* w, const int c) {
    w->planes[0][c] = INFINITY; w->planes[1][c] = -INFINITY;
    w->planes[2][c] = INFINITY; w->planes[3][c] = -INFINITY;
    w->planes[4][c] = INFINITY; w->planes[5][c] = -INFINITY;
    w->index[c] = 0u;
    w->count[c] = 0u;
}
RK_INLINE void rk_slot_set(__global rk_wnode* w, const int c, const rk_box b, const uint index, const uint count) {
    w->planes[0][c] = b.lo.x; w->planes[1][c] = b.hi.x;
    w->planes[2][c] = b.lo.y; w->planes[3][c] = b.hi.y;
    w->planes[4][c] = b.lo.z; w->planes[5][c] = b.hi.z;
    w->index[c] = index;
    w->count[c] = count;
}
/* Wide nodes: node 0 (the root box alone, inner child 1), then wide node w at 1 + w. One
   item per flag index; item 0 also writes node 0 and, for a one-leaf tree, node 1. Refit
   tables of the object's node range [node_offset, node_offset + cap): parents (global), needs
   (inner children), starts ((global node, object) for nodes without inner children, else
   RK_INVALID); entries of unused nodes get RK_INVALID / 0. */
__kernel void rk_tree_wide(__global const uint2* kids, __global const float* rbox, __global const float* ibox,
                           __global const uint* icnt, __global const uint* first, __global const uint2* wflag,
                           __global const uint2* wpos, __global const uint2* bpos, const uint n, const uint cap,
                           const uint node_offset, const uint object, __global rk_wnode* nodes,
                           __global uint* parents, __global uint* needs, __global uint2* starts,
                           __global uint* state) {
    const uint q = (uint)get_global_id(0);
    if (q >= cap) return;
    const uint root = n == 1u ? 0u : 2u * n - 2u;
    const int one_leaf = n == 1u || rk_out_of(icnt, n, root) == 1u;
    const uint wide = one_leaf ? 1u : wpos[n - 2u].x + wflag[n - 2u].x;
    if (q == 0u) {
        state[3] = 1u + wide;
        __global rk_wnode* w0 = nodes + node_offset;
        for (int c = 0; c < RK_WIDTH; ++c) rk_slot_clear(w0, c);
        rk_slot_set(w0, 0, rk_node_box(rbox, ibox, n, root), 1u, 0u);
        parents[node_offset] = RK_INVALID;
        needs[node_offset] = 1u;
        starts[node_offset] = (uint2)(RK_INVALID, 0u);
        if (one_leaf) {
            __global rk_wnode* w1 = nodes + node_offset + 1u;
            for (int c = 0; c < RK_WIDTH; ++c) rk_slot_clear(w1, c);
            rk_slot_set(w1, 0, rk_node_box(rbox, ibox, n, root), bpos[0].x, (rk_count_of(icnt, n, root) + 3u) >> 2);
            parents[node_offset + 1u] = node_offset;
            needs[node_offset + 1u] = 0u;
            starts[node_offset + 1u] = (uint2)(node_offset + 1u, object);
        }
    }
    /* nodes past the tree: no parent, nothing to wait for, not a start */
    if (q + 1u >= 1u + wide && !(one_leaf && q == 0u)) {
        parents[node_offset + q + 1u] = RK_INVALID;
        needs[node_offset + q + 1u] = 0u;
        starts[node_offset + q + 1u] = (uint2)(RK_INVALID, 0u);
    }
    if (one_leaf || q >= n - 1u || wflag[q].x == 0u) return;
    const uint v = root - q;
    const uint me = node_offset + 1u + wpos[q].x;
    uint slot[RK_WIDTH];
    const int cnt = rk_expand(v, kids, rbox, ibox, icnt, n, slot);
    __global rk_wnode* w = nodes + me;
    uint inner = 0u;
    for (int c = 0; c < RK_WIDTH; ++c) {
        if (c >= cnt) {
            rk_slot_clear(w, c);
            continue;
        }
        const uint x = slot[c];
        const rk_box b = rk_node_box(rbox, ibox, n, x);
        if (rk_out_of(icnt, n, x) == 1u) {
            rk_slot_set(w, c, b, bpos[first[x]].x, (rk_count_of(icnt, n, x) + 3u) >> 2);
        } else {
            const uint child = 1u + wpos[root - x].x;
            rk_slot_set(w, c, b, child, 0u);
            parents[node_offset + child] = me;
            ++inner;
        }
    }
    if (q == 0u) parents[me] = node_offset;
    needs[me] = inner;
    starts[me] = inner == 0u ? (uint2)(me, object) : (uint2)(RK_INVALID, 0u);
}

/* SAH cost of an object's wide tree (nodes 1 .. count - 1 of its range; Ct = Ci = 1, a leaf
   slot weighted by its blocks) over its root's area, for the rebuild policy. One work item
   per object (`which`: the objects), in a fixed order: the same value on every run. */
__kernel void rk_tree_cost(__global const rk_wnode* nodes, __global const rk_object* objects,
                           __global const uint* which, __global const uint* counts, __global float* cost,
                           const uint m) {
    const uint d = (uint)get_global_id(0);
    if (d >= m) return;
    const rk_object ob = objects[which[d]];
    const uint count = counts[d];
    if (count < 2u) {
        cost[d] = 0.0f;
        return;
    }
    rk_box r;
    r.lo = (float3)(nodes[ob.node_offset].planes[0][0], nodes[ob.node_offset].planes[2][0], nodes[ob.node_offset].planes[4][0]);
    r.hi = (float3)(nodes[ob.node_offset].planes[1][0], nodes[ob.node_offset].planes[3][0], nodes[ob.node_offset].planes[5][0]);
    double sum = 0.0;
    for (uint i = 1; i < count; ++i) {
        __global const rk_wnode* w = nodes + ob.node_offset + i;
        for (int c = 0; c < RK_WIDTH; ++c) {
            if (w->count[c] == 0u && w->index[c] == 0u) continue;
            rk_box b;
            b.lo = (float3)(w->planes[0][c], w->planes[2][c], w->planes[4][c]);
            b.hi = (float3)(w->planes[1][c], w->planes[3][c], w->planes[5][c]);
            sum += (double)rk_box_half_area(b) * (double)(w->count[c] == 0u ? 1u : w->count[c]);
        }
    }
    const float root = rk_box_half_area(r);
    cost[d] = root > 0.0f ? (float)(sum / (double)root) : 0.0f;
}
)CLC";

}  // namespace raykit::kernels
