// raykit/kernels/refit.hpp — bottom-up refit of the objects' wide trees on the device
// (rk_wnode, cl/device_tree.hpp), two ways, both bit-identical to the CPU's refit of a
// BlockBvh8 (scene/block_bvh.hpp refit, bvh/refit.hpp refit_wide_nodes): a leaf slot's box
// is the AABB::grow of its blocks' lanes' MeshView::bounds in order, an inner slot's box the
// grow of its child node's used slots in slot order; min/max select the same floats as the
// CPU. Node 0 of an object (the root box alone) is refitted like any node.
//
// Each leaf's step also rewrites its blocks (rk_block: the triangles' vertices in leaf
// order, what the walk reads) from the current vertices: the gather after the vertex stage
// costs no launch of its own and the frame stays on the device.
//
// Trees live in one concatenated node buffer; each work item carries its node's global index
// and its object (rk_object: node/prim/triangle/vertex offsets). Inner child `index` of a node
// of that object is node node_offset + index.
//
//   rk_refit_level     one launch per tree level (deepest first); `entries` holds every
//                      level's (node, object) pairs back to back, the launch gets
//                      [first, first + count)
//   rk_refit_one_pass  one launch over the nodes without inner children: each computes its
//                      node, then walks up through `parents`; at each parent an atomic
//                      counter lets every inner child but the last to arrive stop, and the
//                      last compute the parent (and reset the counter to 0 for the next refit)
//   rk_gather_roots    root boxes of some objects, for the top-level build
#pragma once

namespace raykit::kernels {

inline constexpr const char* kRefit = R"CLC(
/* A box as two float3 (private only; never crosses). */
typedef struct {
    float3 lo, hi;
} rk_box;

/* AABB::grow(AABB): o is the candidate, robust_min(o, b) = o < b ? o : b. */
RK_INLINE void rk_box_grow(rk_box* b, const rk_box o) {
    b->lo = select(b->lo, o.lo, isless(o.lo, b->lo));
    b->hi = select(b->hi, o.hi, isgreater(o.hi, b->hi));
}

/* MeshView::bounds: empty when a vertex is not finite, else the corners
   grown in order from the empty box (the first corner becomes both ends). */
RK_INLINE rk_box rk_triangle_box(const float3 p0, const float3 p1, const float3 p2) {
    const int finite = all(isfinite(p0)) & all(isfinite(p1)) & all(isfinite(p2));
    float3 lo = p0, hi = p0;
    lo = select(lo, p1, isless(p1, lo));
    hi = select(hi, p1, isgreater(p1, hi));
    lo = select(lo, p2, isless(p2, lo));
    hi = select(hi, p2, isgreater(p2, hi));
    rk_box b;
    b.lo = finite ? lo : (float3)(INFINITY);
    b.hi = finite ? hi : (float3)(-INFINITY);
    return b;
}

/* A leaf's box: its blocks' lanes' triangle boxes grown in order from the empty box (the CPU's
   BlockBvh refit, scene/block_bvh.hpp). Also rewrites the blocks from the triangles' current
   vertices (the gather after the vertex stage, fused with the refit). */
RK_INLINE rk_box rk_leaf_box(const uint first, const uint count, __global rk_block* blocks,
                             __global const uint* tris, __global const float* pos, const rk_object* ob) {
    rk_box b;
    b.lo = (float3)(INFINITY);
    b.hi = (float3)(-INFINITY);
    for (uint k = ob->block_offset + first; k < ob->block_offset + first + count; ++k) {
        __global rk_block* blk = blocks + k;
        for (int i = 0; i < 4; ++i) {
            const uint3 t = vload3(ob->triangle_offset + blk->prim[i], tris);
            const float3 p0 = vload3(ob->vertex_offset + t.x, pos), p1 = vload3(ob->vertex_offset + t.y, pos),
                         p2 = vload3(ob->vertex_offset + t.z, pos);
            blk->p[0][i] = p0.x; blk->p[1][i] = p0.y; blk->p[2][i] = p0.z;
            blk->p[3][i] = p1.x; blk->p[4][i] = p1.y; blk->p[5][i] = p1.z;
            blk->p[6][i] = p2.x; blk->p[7][i] = p2.y; blk->p[8][i] = p2.z;
            rk_box_grow(&b, rk_triangle_box(p0, p1, p2));
        }
    }
    return b;
}

/* Slot c's box of a wide node. */
RK_INLINE rk_box rk_slot_box(volatile __global const rk_wnode* n, const int c) {
    rk_box b;
    b.lo = (float3)(n->planes[0][c], n->planes[2][c], n->planes[4][c]);
    b.hi = (float3)(n->planes[1][c], n->planes[3][c], n->planes[5][c]);
    return b;
}

/* Recomputes every used slot of node g (refit_wide_nodes): a leaf from its triangles, an inner
   child as the union of its child node's used slots (read volatile: in the one-pass refit
   another work item wrote them). */
RK_INLINE void rk_refit_node(__global rk_wnode* nodes, const uint g, __global rk_block* blocks,
                             __global const uint* tris, __global const float* pos, const rk_object* ob) {
    __global rk_wnode* n = nodes + g;
    for (int c = 0; c < RK_WIDTH; ++c) {
        const uint index = n->index[c], count = n->count[c];
        if (count == 0u && index == 0u) continue;  /* unused */
        rk_box b;
        if (count != 0u) {
            b = rk_leaf_box(index, count, blocks, tris, pos, ob);
        } else {
            volatile __global const rk_wnode* child = nodes + ob->node_offset + index;
            b.lo = (float3)(INFINITY);
            b.hi = (float3)(-INFINITY);
            for (int k = 0; k < RK_WIDTH; ++k)
                if (child->count[k] != 0u || child->index[k] != 0u) rk_box_grow(&b, rk_slot_box(child, k));
        }
        n->planes[0][c] = b.lo.x;
        n->planes[1][c] = b.hi.x;
        n->planes[2][c] = b.lo.y;
        n->planes[3][c] = b.hi.y;
        n->planes[4][c] = b.lo.z;
        n->planes[5][c] = b.hi.z;
    }
}

__kernel void rk_refit_level(__global rk_wnode* nodes, __global rk_block* blocks, __global const uint* tris,
                             __global const float* pos, __global const rk_object* objects,
                             __global const uint2* entries, const uint first, const uint count) {
    const uint i = (uint)get_global_id(0);
    if (i >= count) return;
    const uint2 e = entries[first + i];
    const rk_object ob = objects[e.y];
    rk_refit_node(nodes, e.x, blocks, tris, pos, &ob);
}

/* One work item per node without inner children; up the tree the last of a node's inner
   children to arrive (needs[p] of them) computes it. */
__kernel void rk_refit_one_pass(__global rk_wnode* nodes, __global rk_block* blocks, __global const uint* tris,
                                __global const float* pos, __global const rk_object* objects, __global const uint2* starts,
                                __global const uint* parents, __global const uint* needs,
                                __global uint* counters, const uint count) {
    const uint i = (uint)get_global_id(0);
    if (i >= count) return;
    const uint2 e = starts[i];
    if (e.x == RK_INVALID) return;  /* node-indexed plans: a node with inner children, or unused */
    const rk_object ob = objects[e.y];
    uint g = e.x;
    rk_refit_node(nodes, g, blocks, tris, pos, &ob);
    for (;;) {
        const uint p = parents[g];
        if (p == RK_INVALID) return;
        RK_GLOBAL_FENCE();                                       /* our boxes before the counter */
        if (atomic_inc(&counters[p]) + 1u < needs[p]) return;  /* a sibling finishes p */
        RK_GLOBAL_FENCE();                                       /* the siblings' boxes after it */
        counters[p] = 0u;                                        /* ready for the next refit */
        rk_refit_node(nodes, p, blocks, tris, pos, &ob);
        g = p;
    }
}

/* Root boxes (slot 0 of node 0) of some objects, for the top-level build. */
__kernel void rk_gather_roots(__global const rk_wnode* nodes, __global const rk_object* objects,
                              __global const uint* which, __global float* boxes, const uint count) {
    const uint i = (uint)get_global_id(0);
    if (i >= count) return;
    const rk_object ob = objects[which[i]];
    for (int a = 0; a < 3; ++a) {
        boxes[6 * i + a] = ob.node_count ? nodes[ob.node_offset].planes[2 * a][0] : INFINITY;
        boxes[6 * i + 3 + a] = ob.node_count ? nodes[ob.node_offset].planes[2 * a + 1][0] : -INFINITY;
    }
}
)CLC";

}  // namespace raykit::kernels
