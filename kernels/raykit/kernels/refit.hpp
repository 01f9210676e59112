// raykit/kernels/refit.hpp — bottom-up refit of BVHs on the device, two ways,
// both bit-identical to raykit::refit (bvh/refit.hpp): a leaf's box is the
// AABB::grow of its triangles' MeshView::bounds in prim_ids order, an inner
// box is merge(left, right); min/max select the same floats as the CPU.
//
// Trees live in one concatenated node buffer; each work item carries its
// node's global index and its object (rk_object: node/prim/triangle/vertex
// offsets). Children of node g are at node_offset + index (+1).
//
//   rk_refit_level     one launch per tree level (deepest first); `entries`
//                      holds every level's (node, object) pairs back to back,
//                      the launch gets [first, first + count)
//   rk_refit_one_pass  one launch over all leaves: each leaf computes its box,
//                      then walks up through `parents`; at each parent an
//                      atomic counter lets the first child to arrive stop and
//                      the second compute the parent (and reset the counter
//                      to 0 for the next refit)
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
RK_INLINE rk_box rk_triangle_box(__global const float* pos, const uint vbase, const uint3 t) {
    const float3 p0 = vload3(vbase + t.x, pos), p1 = vload3(vbase + t.y, pos), p2 = vload3(vbase + t.z, pos);
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

/* refit's leaf: grow the triangles' boxes in prim_ids order. */
RK_INLINE rk_box rk_leaf_box(const uint index, const uint count, __global const uint* prim_ids, __global const uint* tris,
                   __global const float* pos, const rk_object* ob) {
    rk_box b;
    b.lo = (float3)(INFINITY);
    b.hi = (float3)(-INFINITY);
    for (uint k = index; k < index + count; ++k) {
        const uint p = prim_ids[ob->prim_offset + k];
        rk_box_grow(&b, rk_triangle_box(pos, ob->vertex_offset, vload3(ob->triangle_offset + p, tris)));
    }
    return b;
}

RK_INLINE rk_box rk_node_box(__global const rk_node* n) {
    rk_box b;
    b.lo = (float3)(n->min[0], n->min[1], n->min[2]);
    b.hi = (float3)(n->max[0], n->max[1], n->max[2]);
    return b;
}
/* The same through volatile loads: in the one-pass refit the sibling was
   written by another work item. */
RK_INLINE rk_box rk_node_box_volatile(volatile __global const rk_node* n) {
    rk_box b;
    b.lo = (float3)(n->min[0], n->min[1], n->min[2]);
    b.hi = (float3)(n->max[0], n->max[1], n->max[2]);
    return b;
}

RK_INLINE void rk_store_box(__global rk_node* n, const rk_box b) {
    n->min[0] = b.lo.x;
    n->min[1] = b.lo.y;
    n->min[2] = b.lo.z;
    n->max[0] = b.hi.x;
    n->max[1] = b.hi.y;
    n->max[2] = b.hi.z;
}

__kernel void rk_refit_level(__global rk_node* nodes, __global const uint* prim_ids, __global const uint* tris,
                             __global const float* pos, __global const rk_object* objects,
                             __global const uint2* entries, const uint first, const uint count) {
    const uint i = (uint)get_global_id(0);
    if (i >= count) return;
    const uint2 e = entries[first + i];
    const rk_object ob = objects[e.y];
    __global rk_node* n = nodes + e.x;
    const uint index = n->index, cnt = n->count;
    rk_box b;
    if (cnt != 0) {
        b = rk_leaf_box(index, cnt, prim_ids, tris, pos, &ob);
    } else {
        __global const rk_node* l = nodes + ob.node_offset + index;
        b = rk_node_box(l);  /* merge(left, right): right is the candidate */
        rk_box_grow(&b, rk_node_box(l + 1));
    }
    rk_store_box(n, b);
}

__kernel void rk_refit_one_pass(__global rk_node* nodes, __global const uint* prim_ids, __global const uint* tris,
                                __global const float* pos, __global const rk_object* objects,
                                __global const uint2* leaves, __global const uint* parents,
                                __global uint* counters, const uint count) {
    const uint i = (uint)get_global_id(0);
    if (i >= count) return;
    const uint2 e = leaves[i];
    const rk_object ob = objects[e.y];
    uint g = e.x;
    __global rk_node* n = nodes + g;
    rk_store_box(n, rk_leaf_box(n->index, n->count, prim_ids, tris, pos, &ob));
    for (;;) {
        const uint p = parents[g];
        if (p == RK_INVALID) return;
        mem_fence(CLK_GLOBAL_MEM_FENCE);             /* our box before the counter */
        if (atomic_inc(&counters[p]) == 0u) return;  /* first child: the sibling finishes p */
        mem_fence(CLK_GLOBAL_MEM_FENCE);             /* the sibling's box after the counter */
        counters[p] = 0u;                            /* ready for the next refit */
        __global rk_node* q = nodes + p;
        volatile __global const rk_node* l = nodes + ob.node_offset + q->index;
        rk_box b = rk_node_box_volatile(l);
        rk_box_grow(&b, rk_node_box_volatile(l + 1));
        rk_store_box(q, b);
        g = p;
    }
}

__kernel void rk_gather_roots(__global const rk_node* nodes, __global const rk_object* objects,
                              __global const uint* which, __global float* boxes, const uint count) {
    const uint i = (uint)get_global_id(0);
    if (i >= count) return;
    const rk_object ob = objects[which[i]];
    for (int a = 0; a < 3; ++a) {
        boxes[6 * i + a] = ob.node_count ? nodes[ob.node_offset].min[a] : INFINITY;
        boxes[6 * i + 3 + a] = ob.node_count ? nodes[ob.node_offset].max[a] : -INFINITY;
    }
}
)CLC";

}  // namespace raykit::kernels
