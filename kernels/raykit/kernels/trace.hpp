// raykit/kernels/trace.hpp — closest-hit and any-hit traversal on the device.
//
// rk_trace_tree() is the twin of raykit::traverse() + the leaf loops of
// scene/trace.hpp: the same front-to-back order (nearer child first, the
// left one on equal entry distances), the same pruning (a popped node is
// skipped when its entry is beyond tmax·RK_SLAB_EXIT_SCALE), the same tie rule
// (smaller t, then smaller triangle index), a stack of RK_MAX_DEPTH entries.
// The CPU throws on a tree deeper than that; here the walk stops with the
// hits found so far (raykit's builders never emit such trees).
//
// Kernels (one work-item per ray, n = number of rays):
//   rk_mesh_closest / rk_mesh_any     one mesh: hits[i] (inst 0) / occluded[i] (1 or 0)
//   rk_scene_closest / rk_scene_any   two levels: top-level tree over instances,
//                                     rays mapped into object space per instance
#pragma once

namespace raykit::kernels {

inline constexpr const char* kTrace = R"CLC(
RK_INLINE rk_hit rk_miss(void) {
    rk_hit h;
    h.t = INFINITY;
    h.u = 0.0f;
    h.v = 0.0f;
    h.prim = RK_INVALID;
    h.inst = RK_INVALID;
    return h;
}

/* Hit::closer_than */
RK_INLINE bool rk_closer(const rk_hit* a, const rk_hit* b) {
    if (a->t != b->t) return a->t < b->t;
    if (a->inst != b->inst) return a->inst < b->inst;
    return a->prim < b->prim;
}

/* One inner node of an ordered walk over `base`: slab-tests both children of
   the node whose first child is `index`; enters the nearer one hit (*cur) and
   pushes the farther one with its entry distance. Returns 1 when a child is
   entered, 0 when neither is (pop next), -1 when the stack is full (a tree
   deeper than RK_MAX_DEPTH, which raykit's builders never make). */
RK_INLINE int rk_descend(const rk_slab_ray* s, __global const rk_node* base, const uint index, const float tmax,
                         uint* cur, uint* st_node, float* st_t, int* sp) {
    float tl, tr;
    const bool hl = rk_slab(s, base + index, tmax, &tl);
    const bool hr = rk_slab(s, base + index + 1, tmax, &tr);
    if (hl && hr) {
        uint nearc = index, farc = index + 1;
        float tf = tr;
        if (tr < tl) {
            nearc = index + 1;
            farc = index;
            tf = tl;
        }
        if (*sp == RK_MAX_DEPTH) return -1;
        st_node[*sp] = farc;
        st_t[*sp] = tf;
        ++*sp;
        *cur = nearc;
        return 1;
    }
    if (hl || hr) {
        *cur = hl ? index : index + 1;
        return 1;
    }
    return 0;
}

/* Pops the next entry still in front of tmax into *cur; false when none is left. */
RK_INLINE bool rk_pop(uint* cur, const uint* st_node, const float* st_t, int* sp, const float tmax) {
    while (*sp > 0) {
        --*sp;
        if (st_t[*sp] <= tmax * RK_SLAB_EXIT_SCALE) {
            *cur = st_node[*sp];
            return true;
        }
    }
    return false;
}

/* Closest hit (any == 0: fills *hit, prim relative to the object, inst
   untouched) or any hit (any != 0) of `ray` limited to [ray->tmin, tmax]
   with one bottom-level tree. Returns true when something was hit. */
RK_INLINE bool rk_trace_tree(__global const rk_node* restrict nodes, __global const uint* restrict prim_ids,
                   __global const rk_triangle* restrict tris, __global const float* restrict pos,
                   const rk_object* ob, const rk_ray* ray, float tmax, const int any, rk_hit* hit) {
    if (ob->node_count == 0) return false;
    nodes += ob->node_offset;
    prim_ids += ob->prim_offset;
    tris += ob->triangle_offset;
    pos += (size_t)3 * ob->vertex_offset;
    const rk_slab_ray s = rk_slab_prepare(ray->org, ray->dir, ray->tmin);
    const rk_wt_ray w = rk_wt_prepare(ray->org, ray->dir);
    const float tmin = ray->tmin, tlimit = tmax;
    float troot;
    if (!rk_slab(&s, nodes, tmax, &troot)) return false;
    uint st_node[RK_MAX_DEPTH];
    float st_t[RK_MAX_DEPTH];
    int sp = 0;
    uint cur = 0;
    bool found = false;
    for (;;) {
        __global const rk_node* n = nodes + cur;
        const uint index = n->index, count = n->count;
        if (count != 0) {
            for (uint k = index; k < index + count; ++k) {
                const uint p = prim_ids[k];
                const rk_triangle t = tris[p];
                const float3 p0 = vload3(t.v[0], pos), p1 = vload3(t.v[1], pos), p2 = vload3(t.v[2], pos);
                float th, uh, vh;
                if (any) {
                    if (rk_wt_intersect(&w, p0, p1, p2, tmin, tlimit, &th, &uh, &vh)) return true;
                } else if (rk_wt_intersect(&w, p0, p1, p2, tmin, tmax, &th, &uh, &vh) &&
                           (th < hit->t || p < hit->prim)) {
                    hit->t = th;
                    hit->u = uh;
                    hit->v = vh;
                    hit->prim = p;
                    tmax = th;
                    found = true;
                }
            }
        } else {
            const int step = rk_descend(&s, nodes, index, tmax, &cur, st_node, st_t, &sp);
            if (step < 0) return found;
            if (step > 0) continue;
        }
        if (!rk_pop(&cur, st_node, st_t, &sp, tmax)) return found;
    }
}

__kernel void rk_mesh_closest(__global const rk_node* nodes, __global const uint* prim_ids,
                              __global const rk_triangle* tris, __global const float* pos, const uint node_count,
                              __global const rk_ray* rays, __global rk_hit* hits, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const rk_ray r = rays[i];
    rk_object ob = {0u, node_count, 0u, 0u, 0u, 0u, 0u, 0u};
    rk_hit h = rk_miss();
    if (rk_trace_tree(nodes, prim_ids, tris, pos, &ob, &r, r.tmax, 0, &h) && h.prim != RK_INVALID) h.inst = 0u;
    hits[i] = h;
}

__kernel void rk_mesh_any(__global const rk_node* nodes, __global const uint* prim_ids,
                          __global const rk_triangle* tris, __global const float* pos, const uint node_count,
                          __global const rk_ray* rays, __global uint* occluded, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const rk_ray r = rays[i];
    rk_object ob = {0u, node_count, 0u, 0u, 0u, 0u, 0u, 0u};
    rk_hit h = rk_miss();
    occluded[i] = rk_trace_tree(nodes, prim_ids, tris, pos, &ob, &r, r.tmax, 1, &h) ? 1u : 0u;
}

/* Scene::object_ray: world ray into the instance's object space. */
RK_INLINE rk_ray rk_object_ray(__global const rk_instance* in, const rk_ray* r, float tmax) {
    rk_ray o;
    for (int k = 0; k < 3; ++k) {
        __global const float* m = in->world_to_object + 4 * k;
        o.org[k] = fma(m[0], r->org[0], fma(m[1], r->org[1], fma(m[2], r->org[2], m[3])));
        o.dir[k] = fma(m[0], r->dir[0], fma(m[1], r->dir[1], m[2] * r->dir[2]));
    }
    o.tmin = r->tmin;
    o.tmax = tmax;
    return o;
}

/* Two-level trace (Scene::intersect_closest / intersect_any). */
RK_INLINE bool rk_trace_scene(__global const rk_node* top, const uint top_count, __global const uint* top_ids,
                    __global const rk_instance* instances, __global const rk_object* objects,
                    __global const rk_node* nodes, __global const uint* prim_ids,
                    __global const rk_triangle* tris, __global const float* pos,
                    const rk_ray* r, const int any, rk_hit* best) {
    if (top_count == 0) return false;
    const rk_slab_ray s = rk_slab_prepare(r->org, r->dir, r->tmin);
    float tmax = r->tmax;
    float troot;
    if (!rk_slab(&s, top, tmax, &troot)) return false;
    uint st_node[RK_MAX_DEPTH];
    float st_t[RK_MAX_DEPTH];
    int sp = 0;
    uint cur = 0;
    bool found = false;
    for (;;) {
        __global const rk_node* n = top + cur;
        const uint index = n->index, count = n->count;
        if (count != 0) {
            for (uint k = index; k < index + count; ++k) {
                const uint inst = top_ids[k];
                __global const rk_instance* in = instances + inst;
                const rk_object ob = objects[in->object];
                const rk_ray o = rk_object_ray(in, r, any ? r->tmax : tmax);
                rk_hit h = rk_miss();
                if (any) {
                    if (rk_trace_tree(nodes, prim_ids, tris, pos, &ob, &o, o.tmax, 1, &h)) return true;
                } else if (rk_trace_tree(nodes, prim_ids, tris, pos, &ob, &o, o.tmax, 0, &h) && h.prim != RK_INVALID) {
                    h.inst = inst;
                    if (rk_closer(&h, best)) {
                        *best = h;
                        tmax = h.t;
                        found = true;
                    }
                }
            }
        } else {
            const int step = rk_descend(&s, top, index, tmax, &cur, st_node, st_t, &sp);
            if (step < 0) return found;
            if (step > 0) continue;
        }
        if (!rk_pop(&cur, st_node, st_t, &sp, tmax)) return found;
    }
}

__kernel void rk_scene_closest(__global const rk_node* top, const uint top_count, __global const uint* top_ids,
                               __global const rk_instance* instances, __global const rk_object* objects,
                               __global const rk_node* nodes, __global const uint* prim_ids,
                               __global const rk_triangle* tris, __global const float* pos,
                               __global const rk_ray* rays, __global rk_hit* hits, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const rk_ray r = rays[i];
    rk_hit best = rk_miss();
    rk_trace_scene(top, top_count, top_ids, instances, objects, nodes, prim_ids, tris, pos, &r, 0, &best);
    hits[i] = best;
}

__kernel void rk_scene_any(__global const rk_node* top, const uint top_count, __global const uint* top_ids,
                           __global const rk_instance* instances, __global const rk_object* objects,
                           __global const rk_node* nodes, __global const uint* prim_ids,
                           __global const rk_triangle* tris, __global const float* pos,
                           __global const rk_ray* rays, __global uint* occluded, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const rk_ray r = rays[i];
    rk_hit best = rk_miss();
    occluded[i] = rk_trace_scene(top, top_count, top_ids, instances, objects, nodes, prim_ids, tris, pos, &r, 1, &best)
                      ? 1u : 0u;
}
)CLC";

}  // namespace raykit::kernels
