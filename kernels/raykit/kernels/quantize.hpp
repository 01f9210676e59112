// raykit/kernels/quantize.hpp — wide nodes quantized on the device (rk_wnode -> rk_qnode).
//
// The twin of raykit::cl::quantize_node (cl/device_tree.hpp), for the dynamic objects of a
// DeviceScene whose walk reads quantized nodes: their full nodes are refitted (or rebuilt) in
// place each frame and quantized again here, without a read-back. The host's result is
// canonical (the smallest fitting exponent from frexp(extent) - 8 up, the outermost bytes
// whose planes still hold each child), and every operation is a float add, subtract or
// multiply by a power of two, a comparison or frexp: exact or rounded once, so the device
// writes the host's bytes (test_cl compares them after refits; a device that flushes subnormal
// floats, CL_FP_DENORM unset, could differ on planes within 2^-126 of an origin at zero). Leaves of more than 255 blocks
// are refused on the host before any of this runs (DeviceScene keeps full nodes then).
//
// Kernel: rk_quantize_nodes(nodes, qnodes, objects, which, dyn, n): qnodes[g] from nodes[g]
// for g < n; with dyn > 0 only nodes of the current trees of objects which[0 .. dyn) (in
// node order: DeviceScene puts its dynamic objects first), the rest of their capacity left.
//
// Expects from the program preamble (raykit::cl::config_source()): RK_QUANTIZE_LIMIT
// (kQuantizeLimit, exact hex float) and RK_QUANTIZE_MAX_EXP (kQuantizeMaxExponent).
#pragma once

namespace raykit::kernels {

inline constexpr const char* kQuantize = R"CLC(
/* detail::quantize_input */
RK_INLINE float rk_qinput(const float x, const int high) {
    const float m = RK_QUANTIZE_LIMIT;
    if (isnan(x)) return high ? m : -m;
    return x < -m ? -m : x > m ? m : x;
}

/* quantize_node, for a node with no leaf over 255 blocks */
RK_INLINE void rk_quantize_node(__global const rk_wnode* n, __global rk_qnode* out) {
    rk_qnode r;
    r.used = 0;
    for (int c = 0; c < RK_WIDTH; ++c) {
        const bool used = n->count[c] != 0u || n->index[c] != 0u;
        if (used) r.used |= (uchar)(1u << c);
        r.index[c] = used ? n->index[c] : 0u;
        r.count[c] = used ? (uchar)n->count[c] : (uchar)0;
        for (int k = 0; k < 6; ++k) r.q[k][c] = 0;
    }
    for (int a = 0; a < 3; ++a) {
        r.origin[a] = 0.0f;
        r.exponent[a] = 0;
    }
    if (r.used != 0) {
        for (int a = 0; a < 3; ++a) {
            float clo[RK_WIDTH], chi[RK_WIDTH];
            float lo = INFINITY, hi = -INFINITY;
            for (int c = 0; c < RK_WIDTH; ++c) {
                clo[c] = rk_qinput(n->planes[2 * a][c], 0);
                chi[c] = rk_qinput(n->planes[2 * a + 1][c], 1);
                if ((r.used >> c) & 1u) {
                    lo = clo[c] < lo ? clo[c] : lo;
                    hi = chi[c] > hi ? chi[c] : hi;
                }
            }
            const float extent = hi - lo;
            int e = -126;
            if (extent > 0.0f) {
                int x = 0;
                frexp(extent, &x);
                e = max(-126, min(RK_QUANTIZE_MAX_EXP, x - 8));
            }
            for (;; ++e) {
                const float step = rk_qstep((char)e);
                const float inv = rk_qstep((char)(-e));
                bool fits = true;
                for (int c = 0; c < RK_WIDTH && fits; ++c) {
                    if (!((r.used >> c) & 1u)) continue;
                    const float gl = floor((clo[c] - lo) * inv);
                    int ql = 255.0f < gl || isnan(gl) ? 255 : (int)gl;
                    while (ql > 0 && rk_qdecode(lo, ql, step) > clo[c]) --ql;
                    while (ql < 255 && rk_qdecode(lo, ql + 1, step) <= clo[c]) ++ql;
                    const float gh = ceil((chi[c] - lo) * inv);
                    int qh = !(gh > 0.0f) ? 0 : 255.0f < gh ? 255 : (int)gh;
                    while (qh > 0 && rk_qdecode(lo, qh - 1, step) >= chi[c]) --qh;
                    while (qh < 255 && rk_qdecode(lo, qh, step) < chi[c]) ++qh;
                    if (rk_qdecode(lo, qh, step) < chi[c]) {
                        fits = false;
                        break;
                    }
                    r.q[2 * a][c] = (uchar)ql;
                    r.q[2 * a + 1][c] = (uchar)qh;
                }
                if (fits || e == RK_QUANTIZE_MAX_EXP) break;
            }
            r.origin[a] = lo;
            r.exponent[a] = (char)e;
        }
    }
    *out = r;
}

__kernel void rk_quantize_nodes(__global const rk_wnode* nodes, __global rk_qnode* qnodes,
                                __global const rk_object* objects, __global const uint* which, const uint dyn,
                                const uint n) {
    const uint g = (uint)get_global_id(0);
    if (g >= n) return;
    if (dyn > 0u) {  /* the dynamic object whose range holds g: the last that starts at or before it */
        uint lo = 0u, hi = dyn;
        while (hi - lo > 1u) {
            const uint mid = (lo + hi) / 2u;
            if (objects[which[mid]].node_offset <= g) lo = mid;
            else hi = mid;
        }
        const rk_object ob = objects[which[lo]];
        if (g < ob.node_offset || g - ob.node_offset >= ob.node_count) return;
    }
    rk_quantize_node(nodes + g, qnodes + g);
}
)CLC";

}  // namespace raykit::kernels
