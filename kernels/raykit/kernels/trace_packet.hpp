// raykit/kernels/trace_packet.hpp — packets of rays walking the device's wide trees together.
//
// The device twin of bvh/traverse_packet.hpp, for OpenCL devices that are CPUs (PoCL): one
// work-item walks RK_PACKET rays (16) at once, each child box slab-tested against all of them
// in one vector operation (float16: PoCL compiles it to AVX-512 or to two or four narrower
// registers), the node fetched once for all of them. A child is entered by the lanes whose own
// test enters it; a lane mask travels with every stack entry; a popped entry is re-tested
// against its lanes' current tmax (its box read again from the parent node). Leaves run rk_leaf,
// the single-ray walk's leaf loop (kernels/raykit/kernels/trace.hpp), for each entering lane,
// so every lane's answer is its single-ray answer bit for bit: a closest hit is the smallest
// (t, instance, triangle) over the triangles a ray tests in boxes it enters, whatever the
// visiting order, and a box that holds a closer hit is entered by the same per-lane arithmetic
// (z, y, x axis order, NaN candidates never deciding, the exit widened once). As on the CPU,
// where every lane's origin and reciprocal are finite a node tests its 8 slots against the
// packet's frustum first (rk_packet_frustum, one float8 test) and only the slots it keeps lane
// by lane, the nearest at once and the rest when popped (bench_cl camera rows, PoCL, three
// interleaved runs, ms: bunny closest 7.18-7.56 -> 6.71-7.18, 100k torus 9.01-9.37 ->
// 8.70-8.99, any-hit unchanged); otherwise children are entered nearest first by the first
// active lane's entry distance. Below a node reached by
// RK_PACKET_SWITCH (3) active lanes or fewer, each lane walks alone (rk_object_walk, the
// single-ray walk from that node), which changes no answer by the same argument.
//
// Why a second walk on CPU devices only: PoCL runs a work-group's work-items one after another
// on a core, so a single-ray walk per work-item is scalar code plus one 8-wide box test; a
// packet shares each node's fetch and box test among 16 coherent rays, as the CPU renderer's
// batches do. On a GPU, work-items of a sub-group already run in lock step and a 16-ray packet
// per work-item would spill its registers, so by default only CL_DEVICE_TYPE_CPU devices get
// this part (cl/trace.hpp packet_walk_default). Measured (PoCL, 2 cores): bench_render thesis
// frame trace 15.1 -> 8.5 ms, shadow 8.3 -> 5.9 ms; bench_cl camera rays 1.1-1.2x the single
// walk's speed, random rays unchanged (they go ray by ray); the README's device tables.
//
// As on the CPU, packets are walked only where they pay: rays of one octant (the signs of
// their directions pick the near planes for all lanes) under a top level that is one leaf
// (the instances walked one after the other, as Scene's batch does); other rays, and the rays
// of a deeper top level, take rk_walk one by one. Traversal steps are not counted here:
// programs that count them (RK_DR_STEPS) do not define RK_PACKET.
//
// Kernels: rk_mesh_closest_packet, rk_mesh_any_packet, rk_scene_closest_packet,
// rk_scene_any_packet (trace.hpp's, one work-item per RK_PACKET rays); the renderer's
// rk_dr_closest_packet / rk_dr_shadow_packet are in shade.hpp.
//
// Expects RK_PACKET == 16 and the parts before it: kernels/raykit/kernels/common.hpp
// (rk_wt_prepare, rk_slab_prepare, RK_SLAB_EXIT_SCALE) and trace.hpp (rk_scene, rk_walk,
// rk_object_walk, rk_leaf, rk_lane_ready, rk_object_ray, rk_hit, rk_lowest_bit, RK_WSTACK).
#pragma once

namespace raykit::kernels {

inline constexpr const char* kTracePacket = R"CLC(
#if RK_PACKET != 16
#error "RK_PACKET must be 16"
#endif

/* A packet reaching a wide node with this many active lanes or fewer walks on ray by ray below
   it (rk_object_walk from that node), as the CPU's traverse_packet does (kPacketSwitchLanes). */
#define RK_PACKET_SWITCH 3

/* One bit per lane of a vector comparison (lanes -1 or 0). */
RK_INLINE uint rk_lane_bits(const int16 m) {
    const int16 b = m & (int16)(1, 2, 4, 8, 16, 32, 64, 128, 256, 512, 1024, 2048, 4096, 8192, 16384, 32768);
    const int8 b8 = b.lo | b.hi;
    const int4 b4 = b8.lo | b8.hi;
    const int2 b2 = b4.lo | b4.hi;
    return (uint)(b2.x | b2.y);
}

/* A packet's per-lane origins, reciprocal directions and tmin (lanes past the rays given copy
   lane 0), and, for the octant all its lanes share, the offsets in floats of the near and far
   plane rows of rk_wnode (rk_slab_prepare's wnear / wfar). */
typedef struct {
    float16 org[3], inv[3], tmin;
    int wnear[3], wfar[3];
    /* the frustum of the lanes being walked (rk_packet_frustum), per axis: the origin that makes
       every lane's near-plane distance smallest and the one that makes its far-plane distance
       largest, the smallest and largest reciprocal; the smallest tmin; frustum: whether they hold
       (every lane's origin finite, its reciprocal finite and non-zero; full nodes only) */
    float fo_near[3], fo_far[3], fi_lo[3], fi_hi[3], ftmin;
    int frustum;
} rk_packet;

/* Lanes of `mask` entering the box whose near planes are n[] and far planes f[] within
   [tmin, tm[lane]]: rk_wslab's arithmetic lane by lane (tn_out: the entry distances). */
RK_INLINE uint rk_packet_enter(const rk_packet* p, const float* tm, const float n0, const float n1, const float n2,
                               const float f0, const float f1, const float f2, const uint mask, float* tn_out) {
    const float16 tnx = (n0 - p->org[0]) * p->inv[0], tfx = (f0 - p->org[0]) * p->inv[0];
    const float16 tny = (n1 - p->org[1]) * p->inv[1], tfy = (f1 - p->org[1]) * p->inv[1];
    const float16 tnz = (n2 - p->org[2]) * p->inv[2], tfz = (f2 - p->org[2]) * p->inv[2];
    float16 t0 = p->tmin, t1 = vload16(0, tm);
    t0 = select(t0, tnz, isgreater(tnz, t0));
    t1 = select(t1, tfz, isless(tfz, t1));
    t0 = select(t0, tny, isgreater(tny, t0));
    t1 = select(t1, tfy, isless(tfy, t1));
    t0 = select(t0, tnx, isgreater(tnx, t0));
    t1 = select(t1, tfx, isless(tfx, t1));
    t1 = t1 * RK_SLAB_EXIT_SCALE;
    if (tn_out) vstore16(t0, 0, tn_out);
    return rk_lane_bits(islessequal(t0, t1)) & mask;
}

/* rk_packet_enter for child `i` of node `n` (a quantized node's planes decoded as rk_qslab does). */
RK_INLINE uint rk_packet_child(const rk_packet* p, const float* tm, __global const rk_onode* n, const int i,
                               const uint mask, float* tn_out) {
#ifdef RK_QNODES
    return rk_packet_enter(p, tm, rk_qplane(n, p->wnear[0] + i, 0), rk_qplane(n, p->wnear[1] + i, 1),
                           rk_qplane(n, p->wnear[2] + i, 2), rk_qplane(n, p->wfar[0] + i, 0),
                           rk_qplane(n, p->wfar[1] + i, 1), rk_qplane(n, p->wfar[2] + i, 2), mask, tn_out);
#else
    __global const float* f = (__global const float*)n;
    return rk_packet_enter(p, tm, f[p->wnear[0] + i], f[p->wnear[1] + i], f[p->wnear[2] + i], f[p->wfar[0] + i],
                           f[p->wfar[1] + i], f[p->wfar[2] + i], mask, tn_out);
#endif
}

#ifndef RK_QNODES
/* The slots of node `n` that some lane of `p` may enter: a superset of rk_packet_child's lanes
   over all slots, all 8 in one float8 test (the CPU's frustum_enter, where the argument is).
   An unused slot holds an empty box (layout.hpp), whose near distance is +inf and far −inf, so
   it is never kept, as rk_wslab never enters it. Writes lower bounds of the entry distances to
   tn_out. */
RK_INLINE uint rk_packet_frustum(const rk_packet* p, __global const rk_onode* n, float* tn_out) {
    __global const float* f = (__global const float*)n;
    float8 t0 = (float8)(p->ftmin), t1 = (float8)(INFINITY);
    for (int a = 2; a >= 0; --a) {  /* z, y, x, as rk_packet_enter's chains */
        const float8 dn = vload8(0, f + p->wnear[a]) - p->fo_near[a];
        const float8 df = vload8(0, f + p->wfar[a]) - p->fo_far[a];
        const float8 n0 = dn * p->fi_lo[a], n1 = dn * p->fi_hi[a];
        const float8 f0 = df * p->fi_lo[a], f1 = df * p->fi_hi[a];
        const float8 lo = select(n1, n0, isless(n0, n1)), hi = select(f1, f0, isgreater(f0, f1));
        t0 = select(t0, lo, isgreater(lo, t0));
        t1 = select(t1, hi, isless(hi, t1));
    }
    t1 = t1 * RK_SLAB_EXIT_SCALE;
    vstore8(t0, 0, tn_out);
    const int8 b = islessequal(t0, t1) & (int8)(1, 2, 4, 8, 16, 32, 64, 128);
    const int4 b4 = b.lo | b.hi;
    const int2 b2 = b4.lo | b4.hi;
    return (uint)(b2.x | b2.y);
}
#endif

/* Sets p's frustum over the lanes `group` (one octant). */
RK_INLINE void rk_packet_set_frustum(rk_packet* p, const float lorg[3][RK_PACKET], const float linv[3][RK_PACKET],
                                     const float* ltmin, const uint group) {
#ifdef RK_QNODES
    p->frustum = 0;
#else
    int ok = 1;
    float tmin = INFINITY;
    for (uint lm = group; lm; lm &= lm - 1u) {
        const float t = ltmin[rk_lowest_bit(lm)];
        tmin = t < tmin ? t : tmin;  /* a NaN tmin: that lane enters nothing */
    }
    p->ftmin = tmin;
    for (int a = 0; a < 3; ++a) {
        float olo = INFINITY, ohi = -INFINITY, ilo = INFINITY, ihi = -INFINITY;
        for (uint lm = group; lm; lm &= lm - 1u) {
            const int l = rk_lowest_bit(lm);
            const float o = lorg[a][l], v = linv[a][l];
            if (!isfinite(o) || !isfinite(v) || v == 0.0f) ok = 0;
            olo = o < olo ? o : olo;
            ohi = o > ohi ? o : ohi;
            ilo = v < ilo ? v : ilo;
            ihi = v > ihi ? v : ihi;
        }
        const int neg = p->wnear[a] > p->wfar[a];  /* the octant's sign on this axis */
        p->fo_near[a] = neg ? olo : ohi;
        p->fo_far[a] = neg ? ohi : olo;
        p->fi_lo[a] = ilo;
        p->fi_hi[a] = ihi;
    }
    p->frustum = ok;
#endif
}

/* The octant of a direction: bit a set when component a's sign bit is. */
RK_INLINE int rk_octant(const float* dir) {
    return (signbit(dir[0]) ? 1 : 0) | (signbit(dir[1]) ? 2 : 0) | (signbit(dir[2]) ? 4 : 0);
}

/* True when rays[0, n) point into one octant. */
RK_INLINE bool rk_one_octant(const rk_ray* rays, const uint n) {
    const int s0 = rk_octant(rays[0].dir);
    for (uint k = 1; k < n; ++k)
        if (rk_octant(rays[k].dir) != s0) return false;
    return true;
}

/* Slot i with key t and lanes m into the k entries so far, nearest first (ties in slot order). */
RK_INLINE void rk_enter_insert(float* key, uint* msk, int* ent, int* k, const int i, const float t, const uint m) {
    int j = (*k)++;
    while (j > 0 && key[j - 1] > t) {
        key[j] = key[j - 1];
        msk[j] = msk[j - 1];
        ent[j] = ent[j - 1];
        --j;
    }
    key[j] = t;
    msk[j] = m;
    ent[j] = i;
}

/* One object's walk for the lanes `lanes` of rays o[] (object space, all in one octant):
   closest hits improve best[] and tm[] in place (as rk_walk's leaf does, instance `inst`); any
   hits return the lanes that found one. */
RK_INLINE uint rk_packet_walk(const rk_packet* pk, rk_wt_ray* w, uint* ready, __global const rk_onode* restrict nodes,
                              __global const rk_block* restrict blocks, const rk_object* ob, const uint object,
                              const uint inst, const rk_ray* o, uint lanes, const int any, rk_hit* best, float* tm,
                              const rk_filter* f) {
    uint st_index[RK_WSTACK], st_count[RK_WSTACK], st_parent[RK_WSTACK], st_slot_mask[RK_WSTACK];
    int sp = 0;
    uint finished = 0u;
    uint cidx = 0u, ccnt = 0u, cmask = lanes;  /* node 0: the root box alone, as rk_walk starts */
    for (;;) {
        if (ccnt == 0u && popcount(cmask) <= RK_PACKET_SWITCH) {
            for (uint lm = cmask; lm; lm &= lm - 1u) {  /* each lane alone below this node */
                const int l = rk_lowest_bit(lm);
                const rk_slab_ray s = rk_slab_prepare(o[l].org, o[l].dir, o[l].tmin);
                if ((rk_object_walk(&s, w, ready, o, l, nodes, blocks, cidx, 0u, o[l].tmin, tm + l, any, inst, object,
                                    ob, best + l, f, 0) & RK_WALK_HIT) && any)
                    finished |= 1u << l;
            }
            if (any) {
                lanes &= ~finished;
                if (!lanes) return finished;
            }
        } else if (ccnt == 0u) {
            __global const rk_onode* n = nodes + cidx;
            float key[RK_WIDTH];
            uint msk[RK_WIDTH];
            int ent[RK_WIDTH];
            int k = 0;
#ifndef RK_QNODES
            if (pk->frustum) {
                /* the slots some lane may enter, by the frustum's entry bound, with the node's lanes:
                   each is tested lane by lane when taken (the first, below) or popped */
                float tn[RK_WIDTH];
                for (uint cand = rk_packet_frustum(pk, n, tn); cand; cand &= cand - 1u) {
                    const int i = rk_lowest_bit(cand);
                    rk_enter_insert(key, msk, ent, &k, i, tn[i], cmask);
                }
            } else
#endif
            {
                const int lead = rk_lowest_bit(cmask);  /* the lane whose distances order the slots */
                for (int i = 0; i < RK_WIDTH; ++i) {
                    if (n->count[i] == 0u && n->index[i] == 0u) continue;  /* an unused slot: an empty box */
                    float tn[RK_PACKET];
                    const uint m = rk_packet_child(pk, tm, n, i, cmask, tn);
                    if (m) rk_enter_insert(key, msk, ent, &k, i, tn[lead], m);
                }
            }
            if (k > 0) {
                if (sp + k - 1 > RK_WSTACK) return finished;  /* deeper than raykit's builders make */
                for (int j = k - 1; j >= 1; --j) {
                    st_index[sp] = n->index[ent[j]];
                    st_count[sp] = n->count[ent[j]];
                    st_parent[sp] = cidx;
                    st_slot_mask[sp] = (uint)ent[j] << 24 | msk[j];
                    ++sp;
                }
                const uint m = pk->frustum ? rk_packet_child(pk, tm, n, ent[0], msk[0], 0) : msk[0];
                if (m) {
                    cidx = n->index[ent[0]];
                    ccnt = n->count[ent[0]];
                    cmask = m;
                    continue;
                }
            }
        } else {
            for (uint lm = cmask; lm; lm &= lm - 1u) {  /* each entering lane: the single-ray leaf */
                const int l = rk_lowest_bit(lm);
                rk_lane_ready(w, ready, o, l);
                if (rk_leaf(w + l, blocks, cidx, ccnt, o[l].tmin, tm + l, any, inst, object, ob, best + l, f) && any)
                    finished |= 1u << l;
            }
            if (any) {
                lanes &= ~finished;
                if (!lanes) return finished;
            }
        }
        /* the next entry some of whose lanes still enter its box */
        bool next = false;
        while (sp > 0) {
            --sp;
            uint m = st_slot_mask[sp] & 0xFFFFFFu & lanes;
            if (!m) continue;
            m = rk_packet_child(pk, tm, nodes + st_parent[sp], (int)(st_slot_mask[sp] >> 24), m, 0);
            if (m) {
                cidx = st_index[sp];
                ccnt = st_count[sp];
                cmask = m;
                next = true;
                break;
            }
        }
        if (!next) return finished;
    }
}

/* One object's walk for the lanes `lanes` of rays o[] (object space): the lanes are walked one
   octant at a time (an instance's rotation can split a coherent packet's octant). */
RK_INLINE uint rk_packet_object(const rk_scene* sc, const rk_object* ob, const uint object, const uint inst,
                                const rk_ray* o, uint lanes, const int any, rk_hit* best, float* tm,
                                const rk_filter* f) {
    __global const rk_onode* restrict nodes = sc->nodes + ob->node_offset;
    __global const rk_block* restrict blocks = sc->blocks + ob->block_offset;
    rk_packet p;
    rk_wt_ray w[RK_PACKET];
    float lorg[3][RK_PACKET], linv[3][RK_PACKET], ltmin[RK_PACKET];
    int oct[RK_PACKET];
    const int first = rk_lowest_bit(lanes);
    for (int k = 0; k < RK_PACKET; ++k) {
        const rk_ray* r = o + (((lanes >> k) & 1u) ? k : first);
        for (int a = 0; a < 3; ++a) {
            lorg[a][k] = r->org[a];
            linv[a][k] = 1.0f / r->dir[a];
        }
        ltmin[k] = r->tmin;
        oct[k] = rk_octant(r->dir);
    }
    for (int a = 0; a < 3; ++a) {
        p.org[a] = vload16(0, lorg[a]);
        p.inv[a] = vload16(0, linv[a]);
    }
    p.tmin = vload16(0, ltmin);
    uint finished = 0u, ready = 0u;
    while (lanes) {
        const int o0 = oct[rk_lowest_bit(lanes)];
        uint group = 0u;
        for (uint lm = lanes; lm; lm &= lm - 1u)
            if (oct[rk_lowest_bit(lm)] == o0) group |= 1u << rk_lowest_bit(lm);
        for (int a = 0; a < 3; ++a) {
            const int neg = (o0 >> a) & 1;
            p.wnear[a] = (2 * a + neg) * RK_WIDTH;
            p.wfar[a] = (2 * a + 1 - neg) * RK_WIDTH;
        }
        rk_packet_set_frustum(&p, lorg, linv, ltmin, group);
        finished |= rk_packet_walk(&p, w, &ready, nodes, blocks, ob, object, inst, o, group, any, best, tm, f);
        lanes &= ~group;
    }
    return finished;
}

/* rk_walk for rays[0, n) (n <= RK_PACKET): closest hits into best[] (any == 0; each starts as a
   miss), or the lanes with a hit (any != 0). Packets where this header's comment says, else
   rk_walk ray by ray. */
RK_INLINE uint rk_walk_batch(const rk_scene* sc, const rk_ray* rays, const uint n, const int any, rk_hit* best,
                             const rk_filter* f) {
    uint blocked = 0u;
    for (uint k = 0; k < n; ++k) best[k] = rk_miss();
    const bool one_leaf = sc->mesh || (sc->top_count == 1u && sc->top[0].count != 0u);
    if (!one_leaf || !rk_one_octant(rays, n)) {
        for (uint k = 0; k < n; ++k)
            if (rk_walk(sc, rays + k, any, best + k, f, 0)) blocked |= 1u << k;
        return blocked;
    }
    const uint all = n >= 32u ? 0xFFFFFFFFu : (1u << n) - 1u;
    float tm[RK_PACKET];
    for (int k = 0; k < RK_PACKET; ++k) tm[k] = rays[(uint)k < n ? k : 0].tmax;
    const uint first = sc->mesh ? 0u : sc->top[0].index;
    const uint count = sc->mesh ? 1u : sc->top[0].count;
    rk_ray mapped[RK_PACKET];
    for (uint s = first; s < first + count; ++s) {
        const uint lanes = all & ~blocked;
        if (!lanes) break;
        rk_object ob;
        uint inst = 0u, object = 0u;
        const rk_ray* o = rays;
        if (sc->mesh) {
            ob = sc->mesh_object;
        } else {
            inst = sc->top_ids[s];
            __global const rk_instance* in = sc->instances + inst;
            object = in->object;
            ob = sc->objects[object];
            if (!in->identity) {
                for (uint k = 0; k < n; ++k) mapped[k] = rk_object_ray(in, rays + k, tm[k]);
                o = mapped;
            }
        }
        if (ob.node_count == 0u) continue;
        blocked |= rk_packet_object(sc, &ob, object, inst, o, lanes, any, best, tm, f);
    }
    return blocked;
}

/* trace.hpp's four kernels with RK_PACKET rays per work-item: the same answers bit for bit.
   The work-item's rays from rays[]: closest hits into hits[] (any == 0) or occlusion flags into
   occluded[] (any != 0). */
RK_INLINE void rk_packet_kernel(const rk_scene* sc, __global const rk_ray* rays, __global rk_hit* hits,
                                __global uint* occluded, const uint n, const int any) {
    const uint first = (uint)get_global_id(0) * RK_PACKET;
    if (first >= n) return;
    const uint m = min((uint)RK_PACKET, n - first);
    rk_ray r[RK_PACKET];
    rk_hit h[RK_PACKET];
    for (uint k = 0; k < m; ++k) r[k] = rays[first + k];
    const uint blocked = rk_walk_batch(sc, r, m, any, h, 0);
    for (uint k = 0; k < m; ++k) {
        if (any) occluded[first + k] = (blocked >> k) & 1u;
        else hits[first + k] = h[k];
    }
}

#ifdef RK_MESH_KERNELS
__kernel void rk_mesh_closest_packet(__global const rk_onode* nodes, __global const rk_block* blocks,
                                     const uint node_count, __global const rk_ray* rays, __global rk_hit* hits,
                                     const uint n) {
    const rk_scene sc = rk_mesh_scene(nodes, blocks, node_count);
    rk_packet_kernel(&sc, rays, hits, 0, n, 0);
}

__kernel void rk_mesh_any_packet(__global const rk_onode* nodes, __global const rk_block* blocks,
                                 const uint node_count, __global const rk_ray* rays, __global uint* occluded,
                                 const uint n) {
    const rk_scene sc = rk_mesh_scene(nodes, blocks, node_count);
    rk_packet_kernel(&sc, rays, 0, occluded, n, 1);
}
#endif

#ifdef RK_SCENE_KERNELS
__kernel void rk_scene_closest_packet(RK_SCENE_PARAMS, __global const rk_ray* rays, __global rk_hit* hits,
                                      const uint n) {
    RK_SCENE_MAKE(sc);
    rk_packet_kernel(&sc, rays, hits, 0, n, 0);
}

__kernel void rk_scene_any_packet(RK_SCENE_PARAMS, __global const rk_ray* rays, __global uint* occluded,
                                  const uint n) {
    RK_SCENE_MAKE(sc);
    rk_packet_kernel(&sc, rays, 0, occluded, n, 1);
}
#endif
)CLC";

}  // namespace raykit::kernels
