// raykit/kernels/trace.hpp — the one closest-hit / any-hit walk on the device.
//
// rk_walk() is the twin of raykit::closest_hit / any_hit over a Scene
// (scene/trace.hpp + Scene's instance leaves) walking SceneTrees::blocks, the
// CPU's fastest form: the same trees, the same order, the same pruning (a
// popped entry is skipped when its entry distance is beyond
// tmax·RK_SLAB_EXIT_SCALE), the same tie rule (smaller t, then smaller
// instance, then smaller triangle). Both levels are walked by one function:
// a top-level leaf enters its instances one after the other (the ray mapped
// into the object's space, an identity instance's ray used as it is); each
// object's walk is an inner loop (the hot one, as tight as a plain mesh walk)
// on its own stack and, when that is empty, hands back to the next instance
// or the top level. A plain mesh is the walk of one object with no top level
// (mesh mode).
//
// Objects: 8-wide nodes (rk_wnode, cl/device_tree.hpp) whose leaves are runs
// of 4-triangle blocks (rk_block), as raykit::traverse walks a WideBvh8 over
// BlockLeaves: node 0 holds the root box alone (the CPU's first test of
// WideBvhT::bounds, not counted as a step); at a node the 8 child boxes are
// tested at once (rk_wslab), the entered children sorted by entry distance
// (ties in slot order), the nearest entered and the others pushed far to
// near (any hit: pushed in slot order); a block is tested 4 lanes at once
// (rk_wt4_intersect), lanes taken in order. The binary walk over prim_ids →
// triangle → vertex indices → positions it replaces was slower everywhere
// measured (bench_cl, PoCL on this 2-core machine, process CPU ms per 262 144
// rays, binary → wide + blocks: torus100k primary closest 29.5 → 19.2,
// random closest 143 → 110, bunny primary closest 24.2 → 15.6, random
// closest 100 → 71); 8-wide nodes over per-triangle leaves without blocks
// were within noise of the blocks on these rows. A program that defines
// RK_QNODES walks the same tree with its child boxes quantized to bytes
// (rk_qnode, 104 bytes against 256; rk_qslab decodes them): the same answers,
// a few more boxes and triangles tested; on PoCL it was slower where the tree
// is cache-resident and faster on the 1M torus (README, "Quantized nodes").
// The top level stays binary (rk_node, bvh/traverse.hpp's order: nearer child
// first, the left one on equal entry distances): it is the CPU's top level,
// and the order instances are entered in decides the tmax each object's walk
// starts with, so a different top-level shape would change the traversal
// steps compared with the CPU (debug-cost images). It is rebuilt on the host
// each frame and holds one leaf entry per instance, a small part of a walk.
// Stacks: the top level's RK_MAX_DEPTH entries, an object's
// (RK_WIDTH − 1)·RK_MAX_DEPTH + 1 (traverse's bound); the CPU throws on a
// deeper tree, here the walk stops with the hits found so far (raykit's
// builders never emit such trees).
//
// Leaf filter: when the program defines RK_LEAF_FILTER (before this part) it
// also defines the type rk_filter and
//   bool rk_keep(const rk_filter* f, uint object, const rk_object* ob, uint prim, float u, float v)
// which rejects candidate hits (the renderer's alpha cut-outs; a walk given
// no filter, f == 0, keeps every hit); without it nothing of the filter is
// compiled, so scenes without cut-outs pay nothing. Traversal steps: with
// `steps` not 0 the inner nodes + leaves of the bottom-level trees visited
// are counted there (raykit::TraversalStats of a Scene query: the top level
// is not counted).
//
// Leaves: rk_leaf, the one leaf loop, also run by each lane of the packet walk
// (kernels/raykit/kernels/trace_packet.hpp, CPU devices).
//
// Kernels (one work-item per ray, n = number of rays; each pair only in programs that define
// RK_MESH_KERNELS or RK_SCENE_KERNELS, cl/trace.hpp trace_parts, so a program compiles only the
// walks it launches):
//   rk_mesh_closest / rk_mesh_any     one mesh: hits[i] (inst 0) / occluded[i] (1 or 0)
//   rk_scene_closest / rk_scene_any   two levels: top-level tree over instances
#pragma once

namespace raykit::kernels {

inline constexpr const char* kTrace = R"CLC(
/* The objects' node form a program walks (rk_onode, tested by rk_oslab): rk_qnode where the
   program defines RK_QNODES (cl/trace.hpp trace_parts, NodeForm::quantized), else rk_wnode. */
#ifdef RK_QNODES
typedef rk_qnode rk_onode;
#else
typedef rk_wnode rk_onode;
#endif
RK_INLINE uint rk_oslab(const rk_slab_ray* s, __global const rk_onode* n, float tmax, float* td) {
#ifdef RK_QNODES
    return rk_qslab(s, n, tmax, td);
#else
    return rk_wslab(s, n, tmax, td);
#endif
}

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

#ifndef RK_LEAF_FILTER
typedef struct {
    uint unused;
} rk_filter;
#endif

/* What a walk runs over: the scene's concatenated object arrays and its top
   level, or (mesh != 0) the one object `mesh_object` with no top level. */
typedef struct {
    __global const rk_node* top;
    __global const uint* top_ids;
    __global const rk_instance* instances;
    __global const rk_object* objects;
    __global const rk_onode* nodes;
    __global const rk_block* blocks;
    uint top_count;
    int mesh;
    rk_object mesh_object;
} rk_scene;

/* One binary node of the top level: slab-tests both children of the node whose first child is
   `index` (in `base`); enters the nearer one hit (*cur) and pushes the
   farther one with its entry distance. Returns 1 when a child is entered, 0
   when neither is (pop next), -1 when the stack is full (*sp == limit). */
RK_INLINE int rk_descend(const rk_slab_ray* s, __global const rk_node* base, const uint index, const float tmax,
                         uint* cur, uint* st_node, float* st_t, int* sp, const int limit) {
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
        if (*sp == limit) return -1;
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

/* Pops the next entry above `floor` still in front of tmax into *cur; false when none is left. */
RK_INLINE bool rk_pop(uint* cur, const uint* st_node, const float* st_t, int* sp, const int floor, const float tmax) {
    while (*sp > floor) {
        --*sp;
        if (st_t[*sp] <= tmax * RK_SLAB_EXIT_SCALE) {
            *cur = st_node[*sp];
            return true;
        }
    }
    return false;
}

/* Scene::object_ray: the world ray in the instance's object space (an identity instance's as it is). */
RK_INLINE rk_ray rk_object_ray(__global const rk_instance* in, const rk_ray* r, float tmax) {
    rk_ray o = *r;
    o.tmax = tmax;
    if (in->identity) return o;
    for (int k = 0; k < 3; ++k) {
        __global const float* m = in->world_to_object + 4 * k;
        o.org[k] = fma(m[0], r->org[0], fma(m[1], r->org[1], fma(m[2], r->org[2], m[3])));
        o.dir[k] = fma(m[0], r->dir[0], fma(m[1], r->dir[1], m[2] * r->dir[2]));
    }
    return o;
}

/* The object's stack: at most RK_WIDTH - 1 entries per wide level (raykit::traverse's bound). */
#define RK_WSTACK ((RK_WIDTH - 1) * RK_MAX_DEPTH + 1)

/* The lowest set bit's index (ctz is OpenCL C 2.0). */
RK_INLINE int rk_lowest_bit(const uint m) { return 31 - (int)clz(m & (0u - m)); }

/* The one leaf loop of the device walks (rk_walk, and each lane of the packet walk): the leaf's
   `count` blocks from `first` tested with rk_wt4_intersect in [tmin, *tmax], hits taken lane by
   lane in order as a scalar loop over the leaf's triangles would (t <= *tmax, Hit::closer_than
   against *best, the leaf filter). Any hit (any != 0): true at the first accepted hit. Closest
   hit: *best (inst set) and *tmax improved in place, true when they were. */
RK_INLINE bool rk_leaf(const rk_wt_ray* w, __global const rk_block* restrict blocks, const uint first, const uint count,
                       const float tmin, float* tmax, const int any, const uint inst, const uint object,
                       const rk_object* ob, rk_hit* best, const rk_filter* f) {
    bool found = false;
    for (uint k = first; k < first + count; ++k) {
        __global const rk_block* b = blocks + k;
        float4 t4, u4, v4;
        uint m = rk_wt4_intersect(w, b, tmin, *tmax, &t4, &u4, &v4);
#ifndef RK_LEAF_FILTER
        if (any && m) return true;  /* every lane of m lies in [tmin, tmax], and any hit keeps tmax */
#endif
        while (m) {  /* lanes in order, as a scalar loop over the leaf's triangles */
            const int i = rk_lowest_bit(m);
            m &= m - 1u;
            const float th = i == 0 ? t4.x : i == 1 ? t4.y : i == 2 ? t4.z : t4.w;
            if (!(th <= *tmax)) continue;
            const uint p = b->prim[i];
            /* Hit::closer_than against the best so far (th <= tmax = best->t when there is one) */
            if (!any && !(th < best->t || inst < best->inst || (inst == best->inst && p < best->prim))) continue;
            const float uh = i == 0 ? u4.x : i == 1 ? u4.y : i == 2 ? u4.z : u4.w;
            const float vh = i == 0 ? v4.x : i == 1 ? v4.y : i == 2 ? v4.z : v4.w;
#ifdef RK_LEAF_FILTER
            if (f && !rk_keep(f, object, ob, p, uh, vh)) continue;
#endif
            if (any) return true;
            best->t = th;
            best->u = uh;
            best->v = vh;
            best->prim = p;
            best->inst = inst;
            *tmax = th;
            found = true;
        }
    }
    return found;
}

/* Lane l's triangle-test set-up (w[l] from the ray o[l]), made when the lane first reaches a
   leaf (bit l of *ready): a ray that misses the root box or reaches no leaf never pays for it,
   nor does a packet's lane that reaches none (most camera rays of a packet; the CPU's
   prepare_lanes, scene/trace_level.inc, does the same). A single ray is lane 0 of its own. */
RK_INLINE void rk_lane_ready(rk_wt_ray* w, uint* ready, const rk_ray* o, const int l) {
    if ((*ready >> l) & 1u) return;
    w[l] = rk_wt_prepare(o[l].org, o[l].dir);
    *ready |= 1u << l;
}

/* rk_object_walk's result bits: a hit was found (closest: *best improved), the walk stopped
   on a tree deeper than its stack. */
#define RK_WALK_HIT 1
#define RK_WALK_ABORT 2

/* One object's walk (raykit::traverse_from over a WideBvhT) for ray s (lane l of o[], its
   triangle-test set-up w[l] made at its first leaf, rk_lane_ready) from entry (start,
   start_count) — node 0, which holds the root box alone, for a whole walk; a wide node whose
   box the ray enters, for a packet walk that has thinned out (trace_packet.hpp). Closest hits
   improve *best and *tmax in place; any hit returns at the first. Entered children nearest
   first (ties in slot order), the others pushed far to near; any hit pushes them in slot order. */
RK_INLINE int rk_object_walk(const rk_slab_ray* s, rk_wt_ray* w, uint* ready, const rk_ray* o, const int l,
                             __global const rk_onode* restrict nodes, __global const rk_block* restrict blocks,
                             const uint start, const uint start_count, const float tmin, float* tmax, const int any,
                             const uint inst, const uint object, const rk_object* ob, rk_hit* best,
                             const rk_filter* f, uint* steps) {
    uint ws_index[RK_WSTACK], ws_count[RK_WSTACK];  /* the object's entries */
    float ws_t[RK_WSTACK];
    int found = 0;
    uint cidx = start, ccnt = start_count;
    int wsp = 0;
    for (;;) {
        if (ccnt == 0u) {
            __global const rk_onode* n = nodes + cidx;
            if (steps && cidx != 0u) ++*steps;
            float td[RK_WIDTH];
            uint mask = rk_oslab(s, n, *tmax, td);
            if (mask) {
                if (wsp + RK_WIDTH - 1 > RK_WSTACK) return found | RK_WALK_ABORT;
                int i = rk_lowest_bit(mask);
                mask &= mask - 1u;
                if (any) {
                    cidx = n->index[i];
                    ccnt = n->count[i];
                    while (mask) {
                        i = rk_lowest_bit(mask);
                        mask &= mask - 1u;
                        ws_index[wsp] = n->index[i];
                        ws_count[wsp] = n->count[i];
                        ++wsp;  /* no entry distance: any hit keeps tmax, so every entry stays in front */
                    }
                    continue;
                }
                if (!mask) {  /* one child: no sorting */
                    cidx = n->index[i];
                    ccnt = n->count[i];
                    continue;
                }
                if (!(mask & (mask - 1u))) {  /* two: the nearer (ties: the first slot) */
                    const int i1 = rk_lowest_bit(mask);
                    const bool swap = td[i1] < td[i];
                    const int a = swap ? i1 : i, c = swap ? i : i1;
                    ws_index[wsp] = n->index[c];
                    ws_count[wsp] = n->count[c];
                    ws_t[wsp] = td[c];
                    ++wsp;
                    cidx = n->index[a];
                    ccnt = n->count[a];
                    continue;
                }
                int e[RK_WIDTH];
                int k = 1;
                e[0] = i;
                while (mask) {  /* three or more: insertion sort by entry distance, stable */
                    i = rk_lowest_bit(mask);
                    mask &= mask - 1u;
                    int j = k++;
                    while (j > 0 && td[e[j - 1]] > td[i]) {
                        e[j] = e[j - 1];
                        --j;
                    }
                    e[j] = i;
                }
                for (int j = k - 1; j >= 1; --j) {
                    ws_index[wsp] = n->index[e[j]];
                    ws_count[wsp] = n->count[e[j]];
                    ws_t[wsp] = td[e[j]];
                    ++wsp;
                }
                cidx = n->index[e[0]];
                ccnt = n->count[e[0]];
                continue;
            }
        } else {
            if (steps) ++*steps;
            rk_lane_ready(w, ready, o, l);
            if (rk_leaf(w + l, blocks, cidx, ccnt, tmin, tmax, any, inst, object, ob, best, f)) {
                if (any) return RK_WALK_HIT;
                found = RK_WALK_HIT;
            }
        }
        /* the next entry still in front of tmax */
        bool next = false;
        while (wsp > 0) {
            --wsp;
            if (any || ws_t[wsp] <= *tmax * RK_SLAB_EXIT_SCALE) {
                cidx = ws_index[wsp];
                ccnt = ws_count[wsp];
                next = true;
                break;
            }
        }
        if (!next) return found;
    }
}

/* Closest hit (any == 0: *best improved in place, inst set; true when it was)
   or any hit (any != 0: true when something blocks) of `r` in [r->tmin, r->tmax]. */
RK_INLINE bool rk_walk(const rk_scene* sc, const rk_ray* r, const int any, rk_hit* best, const rk_filter* f,
                       uint* steps) {
    if (steps) *steps = 0u;
    float tmax = r->tmax;
    uint st_node[RK_MAX_DEPTH];  /* the top level's entries */
    float st_t[RK_MAX_DEPTH];
    int sp = 0;
    uint tcur = 0;              /* top-level node */
    uint leaf_k = 0, leaf_end = sc->mesh ? 1u : 0u;  /* instances of the top-level leaf still to walk */
    bool top_pending = !sc->mesh, found = false;
    const rk_slab_ray top_s = rk_slab_prepare(r->org, r->dir, r->tmin);
    if (!sc->mesh) {
        float troot;
        if (sc->top_count == 0 || !rk_slab(&top_s, sc->top, tmax, &troot)) return false;
    }
    for (;;) {
        if (leaf_k < leaf_end) {  /* the next instance of the top-level leaf: its object's walk */
            rk_ray o = *r;
            rk_object ob;
            uint inst = 0u, object = 0u;
            bool mapped = false;  /* the ray differs from the world ray (else top_s serves) */
            if (sc->mesh) {
                ob = sc->mesh_object;
            } else {
                inst = sc->top_ids[leaf_k];
                __global const rk_instance* in = sc->instances + inst;
                object = in->object;
                ob = sc->objects[object];
                o = rk_object_ray(in, r, tmax);
                mapped = !in->identity;
            }
            ++leaf_k;
            if (ob.node_count == 0) continue;
            __global const rk_onode* restrict nodes = sc->nodes + ob.node_offset;
            __global const rk_block* restrict blocks = sc->blocks + ob.block_offset;
            const rk_slab_ray s = mapped ? rk_slab_prepare(o.org, o.dir, o.tmin) : top_s;
            rk_wt_ray w;
            uint ready = 0u;
            const int res = rk_object_walk(&s, &w, &ready, &o, 0, nodes, blocks, 0u, 0u, r->tmin, &tmax, any, inst,
                                           object, &ob, best, f, steps);
            if (res & RK_WALK_HIT) {
                if (any) return true;
                found = true;
            }
            if (res & RK_WALK_ABORT) return found;
            continue;
        }
        if (sc->mesh) return found;
        /* the top level: the next node in front of tmax, down to a leaf */
        if (!top_pending && !rk_pop(&tcur, st_node, st_t, &sp, 0, tmax)) return found;
        top_pending = false;
        __global const rk_node* n = sc->top + tcur;
        if (n->count != 0) {
            leaf_k = n->index;
            leaf_end = n->index + n->count;
            continue;
        }
        const int step = rk_descend(&top_s, sc->top, n->index, tmax, &tcur, st_node, st_t, &sp, RK_MAX_DEPTH);
        if (step < 0) return found;
        top_pending = step > 0;
    }
}

RK_INLINE rk_scene rk_mesh_scene(__global const rk_onode* nodes, __global const rk_block* blocks,
                                 const uint node_count) {
    rk_scene sc;
    sc.top = 0;
    sc.top_ids = 0;
    sc.instances = 0;
    sc.objects = 0;
    sc.nodes = nodes;
    sc.blocks = blocks;
    sc.top_count = 0u;
    sc.mesh = 1;
    rk_object ob = {0u, node_count, 0u, 0u, 0u, 0u, 0u, 0u};
    sc.mesh_object = ob;
    return sc;
}

/* The kernel parameters of a two-level scene, and the rk_scene made of them (tris: for the
   renderer's leaf filter; the walk reads the blocks). */
#define RK_SCENE_PARAMS __global const rk_node* top, const uint top_count, __global const uint* top_ids, \
    __global const rk_instance* instances, __global const rk_object* objects, __global const rk_onode* nodes, \
    __global const rk_block* blocks, __global const rk_triangle* tris
#define RK_SCENE_MAKE(sc) const rk_scene sc = {top, top_ids, instances, objects, nodes, blocks, \
    top_count, 0, {0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u}}

#ifdef RK_MESH_KERNELS
__kernel void rk_mesh_closest(__global const rk_onode* nodes, __global const rk_block* blocks, const uint node_count,
                              __global const rk_ray* rays, __global rk_hit* hits, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const rk_ray r = rays[i];
    const rk_scene sc = rk_mesh_scene(nodes, blocks, node_count);
    rk_hit h = rk_miss();
    rk_walk(&sc, &r, 0, &h, 0, 0);
    hits[i] = h;
}

__kernel void rk_mesh_any(__global const rk_onode* nodes, __global const rk_block* blocks, const uint node_count,
                          __global const rk_ray* rays, __global uint* occluded, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    const rk_ray r = rays[i];
    const rk_scene sc = rk_mesh_scene(nodes, blocks, node_count);
    rk_hit h = rk_miss();
    occluded[i] = rk_walk(&sc, &r, 1, &h, 0, 0) ? 1u : 0u;
}

#endif

#ifdef RK_SCENE_KERNELS
__kernel void rk_scene_closest(RK_SCENE_PARAMS, __global const rk_ray* rays, __global rk_hit* hits, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    RK_SCENE_MAKE(sc);
    const rk_ray r = rays[i];
    rk_hit best = rk_miss();
    rk_walk(&sc, &r, 0, &best, 0, 0);
    hits[i] = best;
}

__kernel void rk_scene_any(RK_SCENE_PARAMS, __global const rk_ray* rays, __global uint* occluded, const uint n) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    RK_SCENE_MAKE(sc);
    const rk_ray r = rays[i];
    rk_hit best = rk_miss();
    occluded[i] = rk_walk(&sc, &r, 1, &best, 0, 0) ? 1u : 0u;
}
#endif
)CLC";

}  // namespace raykit::kernels
