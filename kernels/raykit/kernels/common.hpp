// raykit/kernels/common.hpp — OpenCL C twins of raykit's CPU math: robust
// min/max, the slab test, the watertight ray/triangle test.
//
// Expects from the program preamble (raykit::cl::config_source()):
//   RK_MAX_DEPTH         RAYKIT_BVH_MAX_DEPTH (traversal stack entries)
//   RK_SLAB_EXIT_SCALE   raykit::kSlabExitScale as an exact hex float
//   RK_FUSE_MSUB, RK_FUSE_T  how the host build rounds two Watertight expressions (below)
//
// Watertight test: the 2-D edge functions are evaluated in double when the
// device has cl_khr_fp64 (a product of two floats is exact in double, so
// each edge function is rounded once, the same way in both triangles sharing
// an edge, whether or not the compiler fuses multiply-adds) — exactly the
// CPU's method, so answers agree with intersect/triangle.hpp. Without fp64
// they are evaluated in float with FP_CONTRACT OFF: each product rounded on
// its own, then subtracted, which is antisymmetric in the two triangles
// sharing an edge (watertight, but not bit-identical to the CPU).
//
// The remaining float operations that a compiler may fuse into fma
// (A[kx] − sx·A[kz] and the t numerator) are written out explicitly, fused
// or not as the host's own build of intersect/triangle.hpp does it
// (RK_FUSE_MSUB, RK_FUSE_T from raykit::cl::host_float_config()), so the
// device returns the CPU's t, u, v bit for bit whatever the host flags
// (-O2 -march=native fuses; -O0/-O1, -ffp-contract=off or no FMA do not).
#pragma once

namespace raykit::kernels {

inline constexpr const char* kCommon = R"CLC(
#ifndef RK_EDGE_DOUBLE /* may be forced to 0 (-DRK_EDGE_DOUBLE=0) to use the float path */
#ifdef cl_khr_fp64
#define RK_EDGE_DOUBLE 1
#else
#define RK_EDGE_DOUBLE 0
#endif
#endif
#if RK_EDGE_DOUBLE
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif

/* Hot helpers are forced inline: PoCL's compiler otherwise keeps them as
   calls (outputs through memory), which costs ~15 % of trace throughput. */
#define RK_INLINE __attribute__((always_inline))

/* The fence of the bottom-up passes (the build's leaf merge, the one-pass refit): the first
   child to reach a parent writes its data, fences and counts; the second counts, fences and
   reads that data, possibly in another work-group. OpenCL 1.2's mem_fence orders one
   work-item's accesses, which suffices on CPU devices; NVIDIA's compiler (CUDA 13) emits it as
   PTX membar.cta, a fence for the work-group only, and on an H200 the device's sort-by-axis
   tree of a 70k torus then differed from the CPU twin's in 2 of 13 runs (a sibling's count
   read stale). With RK_NV_PTX (raykit_build_options on NVIDIA's platform) the fence is
   membar.gl, for the whole GPU: 0 of 13. */
#ifdef RK_NV_PTX
#define RK_GLOBAL_FENCE() asm volatile("membar.gl;" ::: "memory")
#else
#define RK_GLOBAL_FENCE() mem_fence(CLK_GLOBAL_MEM_FENCE)
#endif

/* max/min ignoring a NaN in the first argument (raykit::robust_max/min). */
RK_INLINE float rk_robust_max(float candidate, float current) { return candidate > current ? candidate : current; }
RK_INLINE float rk_robust_min(float candidate, float current) { return candidate < current ? candidate : current; }

/* Per-ray state of traversal: origin, 1/d, and per axis the offsets (in
   floats, into a node's min[3] max[3]) of the near and far planes — the
   octant choice of raykit::slab_test made once per ray. */
typedef struct {
    float org[3];
    float inv[3];
    int nearo[3];
    int faro[3];
    int wnear[3];  /* the same for a wide node: offsets of the near / far plane rows of rk_wnode */
    int wfar[3];
    float tmin;
} rk_slab_ray;

RK_INLINE rk_slab_ray rk_slab_prepare(const float* org, const float* dir, float tmin) {
    rk_slab_ray s;
    for (int a = 0; a < 3; ++a) {
        s.org[a] = org[a];
        s.inv[a] = 1.0f / dir[a];
        const int neg = signbit(dir[a]) ? 1 : 0;
        s.nearo[a] = neg ? 3 + a : a;
        s.faro[a] = neg ? a : 3 + a;
        s.wnear[a] = (2 * a + neg) * RK_WIDTH;
        s.wfar[a] = (2 * a + 1 - neg) * RK_WIDTH;
    }
    s.tmin = tmin;
    return s;
}

/* raykit::slab_test on a node's box: the same operations in the same order. */
RK_INLINE bool rk_slab(const rk_slab_ray* s, __global const rk_node* n, float tmax, float* tentry) {
    __global const float* f = (__global const float*)n;  /* min[3], max[3] */
    float t0 = s->tmin, t1 = tmax * RK_SLAB_EXIT_SCALE;
    for (int a = 0; a < 3; ++a) {
        const float tn = (f[s->nearo[a]] - s->org[a]) * s->inv[a];
        const float tf = (f[s->faro[a]] - s->org[a]) * s->inv[a] * RK_SLAB_EXIT_SCALE;
        t0 = rk_robust_max(tn, t0);
        t1 = rk_robust_min(tf, t1);
    }
    *tentry = t0;
    return t0 <= t1;
}

/* The RK_WIDTH children of a wide node at once (raykit::WideSlabRay::test, bvh/traverse_wide.hpp):
   per child the same (plane − origin)·(1/d) distances, NaN candidates never deciding, the axes
   in the CPU's order (z, y, x), the exit widened once after the minimum. Writes the entry
   distances to td[0 .. RK_WIDTH) and returns a bit per child entered. */
#if RK_WIDTH == 8
#define RK_FW float8
#define RK_IW int8
#define RK_VLOADW vload8
#define RK_VSTOREW vstore8
#define RK_CONVERT_FW convert_float8
#elif RK_WIDTH == 4
#define RK_FW float4
#define RK_IW int4
#define RK_VLOADW vload4
#define RK_VSTOREW vstore4
#define RK_CONVERT_FW convert_float4
#else
#error "RK_WIDTH must be 4 or 8"
#endif
/* The test of rk_wslab and rk_qslab, given the children's near (n*) and far (f*) planes per axis. */
RK_INLINE uint rk_wslab_planes(const rk_slab_ray* s, const RK_FW n0, const RK_FW f0, const RK_FW n1, const RK_FW f1,
                               const RK_FW n2, const RK_FW f2, float tmax, float* td) {
    RK_FW t0 = (RK_FW)(s->tmin), t1 = (RK_FW)(tmax);
#define RK_WSLAB_AXIS(a)                                                            \
    {                                                                               \
        const RK_FW tn = (n##a - s->org[a]) * s->inv[a];                            \
        const RK_FW tf = (f##a - s->org[a]) * s->inv[a];                            \
        t0 = select(t0, tn, isgreater(tn, t0));                                     \
        t1 = select(t1, tf, isless(tf, t1));                                        \
    }
    RK_WSLAB_AXIS(2) RK_WSLAB_AXIS(1) RK_WSLAB_AXIS(0)  /* unrolled: PoCL kept the loop */
#undef RK_WSLAB_AXIS
    t1 = t1 * RK_SLAB_EXIT_SCALE;
    RK_VSTOREW(t0, 0, td);
#if RK_WIDTH == 8
    const int8 h = islessequal(t0, t1) & (int8)(1, 2, 4, 8, 16, 32, 64, 128);
    const int4 h4 = h.lo | h.hi;
#else
    const int4 h4 = islessequal(t0, t1) & (int4)(1, 2, 4, 8);
#endif
    const int2 h2 = h4.lo | h4.hi;
    return (uint)(h2.x | h2.y);
}

RK_INLINE uint rk_wslab(const rk_slab_ray* s, __global const rk_wnode* n, float tmax, float* td) {
    __global const float* f = (__global const float*)n;
    return rk_wslab_planes(s, RK_VLOADW(0, f + s->wnear[0]), RK_VLOADW(0, f + s->wfar[0]), RK_VLOADW(0, f + s->wnear[1]),
                           RK_VLOADW(0, f + s->wfar[1]), RK_VLOADW(0, f + s->wnear[2]), RK_VLOADW(0, f + s->wfar[2]),
                           tmax, td);
}

/* 2^e for a quantized node's exponent e in [-126, 127] (raykit::cl::quantized_step). */
RK_INLINE float rk_qstep(const char e) { return as_float((uint)((int)e + 127) << 23); }

/* The row of a quantized node's planes at offset `offset` (rk_slab_ray's wnear / wfar) on axis
   `a`, decoded as the host's quantized_plane does it: origin + q * 2^e (the product is exact,
   so fusing changes nothing). */
RK_INLINE RK_FW rk_qrow(__global const rk_qnode* n, const int offset, const int a) {
    return RK_CONVERT_FW(RK_VLOADW(0, (__global const uchar*)n->q + offset)) * rk_qstep(n->exponent[a]) + n->origin[a];
}

/* rk_wslab on a quantized node: the same test of the decoded planes; unused slots are masked by
   `used` (they decode to a point). */
RK_INLINE uint rk_qslab(const rk_slab_ray* s, __global const rk_qnode* n, float tmax, float* td) {
    return rk_wslab_planes(s, rk_qrow(n, s->wnear[0], 0), rk_qrow(n, s->wfar[0], 0), rk_qrow(n, s->wnear[1], 1),
                           rk_qrow(n, s->wfar[1], 1), rk_qrow(n, s->wnear[2], 2), rk_qrow(n, s->wfar[2], 2), tmax,
                           td) &
           (uint)n->used;
}

/* raykit::cl::quantized_plane: origin + q * step, one rounding (the product is exact). */
RK_INLINE float rk_qdecode(const float origin, const int q, const float step) { return (float)q * step + origin; }

/* Plane `row * RK_WIDTH + child` (an offset as rk_slab_ray's wnear / wfar give it) of a
   quantized node, on axis `a`. */
RK_INLINE float rk_qplane(__global const rk_qnode* n, const int offset, const int a) {
    return rk_qdecode(n->origin[a], ((__global const uchar*)n->q)[offset], rk_qstep(n->exponent[a]));
}

/* raykit::Watertight */
typedef struct {
    float org[3];
    int kx, ky, kz;
    float sx, sy, sz;
} rk_wt_ray;

RK_INLINE rk_wt_ray rk_wt_prepare(const float* org, const float* dir) {
    rk_wt_ray d;
    for (int a = 0; a < 3; ++a) d.org[a] = org[a];
    const float ax = fabs(dir[0]), ay = fabs(dir[1]), az = fabs(dir[2]);
    /* raykit::max_axis and Watertight::prepare's picks, by arithmetic: random rays mispredict branches */
    const int xy = ax >= ay, xz = ax >= az, yz = ay >= az;
    d.kz = 2 - 2 * (xy & xz) - ((1 - xy) & yz);
    d.kx = d.kz + 1 - 3 * (d.kz == 2);
    d.ky = d.kx + 1 - 3 * (d.kx == 2);
    const int swap = (d.kx ^ d.ky) & -(int)(dir[d.kz] < 0.0f);
    d.kx ^= swap;
    d.ky ^= swap;
    d.sx = dir[d.kx] / dir[d.kz];
    d.sy = dir[d.ky] / dir[d.kz];
    d.sz = 1.0f / dir[d.kz];
    return d;
}

/* The two places where a compiler may fuse a multiply-add in the CPU's
   Watertight test: A[kx] - sx*A[kz] and the t numerator. The host fuses them
   exactly when RAYKIT_FMA is 1 (raykit::cl::host_float_config) and sets
   RK_FUSE_MSUB / RK_FUSE_T so the device does the same, explicitly. */
#ifndef RK_FUSE_MSUB
#define RK_FUSE_MSUB 1
#endif
#ifndef RK_FUSE_T
#define RK_FUSE_T 1
#endif
RK_INLINE float rk_msub(float a, float s, float b) {
#pragma OPENCL FP_CONTRACT OFF
#if RK_FUSE_MSUB
    return fma(-s, b, a);
#else
    return a - s * b;
#endif
}
RK_INLINE float rk_tnum(float U, float Az, float V, float Bz, float W, float Cz) {
#pragma OPENCL FP_CONTRACT OFF
#if RK_FUSE_T
    return fma(W, Cz, fma(U, Az, V * Bz));
#else
    return U * Az + V * Bz + W * Cz;
#endif
}

/* Edge function in float for devices without fp64: each product rounded on
   its own (no fused multiply-add), then subtracted. */
RK_INLINE float rk_edge_float(float a, float b, float c, float d) {
#pragma OPENCL FP_CONTRACT OFF
    const float p = a * b;
    const float q = c * d;
    return p - q;
}

/* raykit::Watertight::degenerate: the edges' cross product is exactly zero
   (in double where the device has fp64, else in float). */
RK_INLINE bool rk_degenerate(float3 p0, float3 p1, float3 p2) {
#if RK_EDGE_DOUBLE
    const double e1x = (double)p1.x - (double)p0.x, e1y = (double)p1.y - (double)p0.y, e1z = (double)p1.z - (double)p0.z;
    const double e2x = (double)p2.x - (double)p0.x, e2y = (double)p2.y - (double)p0.y, e2z = (double)p2.z - (double)p0.z;
    return e1y * e2z == e1z * e2y && e1z * e2x == e1x * e2z && e1x * e2y == e1y * e2x;  /* no subtraction: nothing to fuse */
#else
    const float3 n = cross(p1 - p0, p2 - p0);
    return n.x == 0.0f && n.y == 0.0f && n.z == 0.0f;
#endif
}

RK_INLINE bool rk_wt_intersect(const rk_wt_ray* d, float3 p0, float3 p1, float3 p2, float tmin, float tmax,
                     float* t_out, float* u_out, float* v_out) {
    const float A[3] = {p0.x - d->org[0], p0.y - d->org[1], p0.z - d->org[2]};
    const float B[3] = {p1.x - d->org[0], p1.y - d->org[1], p1.z - d->org[2]};
    const float C[3] = {p2.x - d->org[0], p2.y - d->org[1], p2.z - d->org[2]};
    const float Ax = rk_msub(A[d->kx], d->sx, A[d->kz]), Ay = rk_msub(A[d->ky], d->sy, A[d->kz]);
    const float Bx = rk_msub(B[d->kx], d->sx, B[d->kz]), By = rk_msub(B[d->ky], d->sy, B[d->kz]);
    const float Cx = rk_msub(C[d->kx], d->sx, C[d->kz]), Cy = rk_msub(C[d->ky], d->sy, C[d->kz]);
    float U, V, W, det;
#if RK_EDGE_DOUBLE
    const double Ud = (double)Cx * (double)By - (double)Cy * (double)Bx;
    const double Vd = (double)Ax * (double)Cy - (double)Ay * (double)Cx;
    const double Wd = (double)Bx * (double)Ay - (double)By * (double)Ax;
    if ((Ud < 0.0 || Vd < 0.0 || Wd < 0.0) && (Ud > 0.0 || Vd > 0.0 || Wd > 0.0)) return false;
    const double detd = Ud + Vd + Wd;
    if (!(detd != 0.0)) return false;
    U = (float)Ud;
    V = (float)Vd;
    W = (float)Wd;
    det = (float)detd;
#else
    U = rk_edge_float(Cx, By, Cy, Bx);
    V = rk_edge_float(Ax, Cy, Ay, Cx);
    W = rk_edge_float(Bx, Ay, By, Ax);
    if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return false;
    det = U + V + W;
#endif
    if (!(det != 0.0f)) return false;
    const float Az = d->sz * A[d->kz], Bz = d->sz * B[d->kz], Cz = d->sz * C[d->kz];
    const float T = rk_tnum(U, Az, V, Bz, W, Cz);
    const float inv = 1.0f / det;
    const float t = T * inv;
    if (!(t >= tmin && t <= tmax)) return false;
    if (rk_degenerate(p0, p1, p2)) return false;
    *t_out = t;
    *u_out = V * inv;
    *v_out = W * inv;
    return true;
}
/* raykit::Watertight4 (intersect/triangle4.hpp): rk_wt_intersect on the four lanes of a block at
   once, the same operations lane by lane (so every lane gives the scalar test's answer bit for
   bit). Returns a bit per lane hit in [tmin, tmax]; *t, *u, *v hold every lane's values. */
RK_INLINE float4 rk_msub4(float4 a, float s, float4 b) {
#pragma OPENCL FP_CONTRACT OFF
#if RK_FUSE_MSUB
    return fma((float4)(-s), b, a);
#else
    return a - s * b;
#endif
}
RK_INLINE uint rk_wt4_intersect(const rk_wt_ray* d, __global const rk_block* b, float tmin, float tmax,
                                float4* t_out, float4* u_out, float4* v_out) {
#pragma OPENCL FP_CONTRACT OFF
    __global const float* P = &b->p[0][0];
    const int ox = 4 * d->kx, oy = 4 * d->ky, oz = 4 * d->kz;
    const float orgx = d->org[d->kx], orgy = d->org[d->ky], orgz = d->org[d->kz];
    const float4 az = vload4(0, P + oz) - orgz, bz = vload4(0, P + 12 + oz) - orgz, cz = vload4(0, P + 24 + oz) - orgz;
    const float4 Ax = rk_msub4(vload4(0, P + ox) - orgx, d->sx, az), Ay = rk_msub4(vload4(0, P + oy) - orgy, d->sy, az);
    const float4 Bx = rk_msub4(vload4(0, P + 12 + ox) - orgx, d->sx, bz), By = rk_msub4(vload4(0, P + 12 + oy) - orgy, d->sy, bz);
    const float4 Cx = rk_msub4(vload4(0, P + 24 + ox) - orgx, d->sx, cz), Cy = rk_msub4(vload4(0, P + 24 + oy) - orgy, d->sy, cz);
    float4 U, V, W, det;
    int4 reject;
#if RK_EDGE_DOUBLE
    const double4 Ud = convert_double4(Cx) * convert_double4(By) - convert_double4(Cy) * convert_double4(Bx);
    const double4 Vd = convert_double4(Ax) * convert_double4(Cy) - convert_double4(Ay) * convert_double4(Cx);
    const double4 Wd = convert_double4(Bx) * convert_double4(Ay) - convert_double4(By) * convert_double4(Ax);
    const double4 detd = Ud + Vd + Wd;
    const long4 neg = (Ud < 0.0) | (Vd < 0.0) | (Wd < 0.0), pos = (Ud > 0.0) | (Vd > 0.0) | (Wd > 0.0);
    reject = convert_int4((neg & pos) | (detd == 0.0) | isnan(detd));
    if (all(reject)) return 0u;
    U = convert_float4(Ud);
    V = convert_float4(Vd);
    W = convert_float4(Wd);
    det = convert_float4(detd);
#else
    U = Cx * By - Cy * Bx;
    V = Ax * Cy - Ay * Cx;
    W = Bx * Ay - By * Ax;
    const int4 neg = (U < 0.0f) | (V < 0.0f) | (W < 0.0f), pos = (U > 0.0f) | (V > 0.0f) | (W > 0.0f);
    reject = neg & pos;
    if (all(reject)) return 0u;
    det = U + V + W;
#endif
    const float4 Az = d->sz * az, Bz = d->sz * bz, Cz = d->sz * cz;
#if RK_FUSE_T
    const float4 T = fma(W, Cz, fma(U, Az, V * Bz));
#else
    const float4 T = U * Az + V * Bz + W * Cz;
#endif
    const float4 inv = 1.0f / det;
    const float4 t = T * inv;
    const int4 ok = ~reject & (det != 0.0f) & (t >= tmin) & (t <= tmax);
    *t_out = t;
    *u_out = V * inv;
    *v_out = W * inv;
    uint m = (ok.x ? 1u : 0u) | (ok.y ? 2u : 0u) | (ok.z ? 4u : 0u) | (ok.w ? 8u : 0u);
    for (uint k = m; k; k &= k - 1u) {  /* the scalar test's last check, on hit lanes only */
        const int i = 31 - (int)clz(k & (0u - k));
        const float3 p0 = (float3)(P[i], P[4 + i], P[8 + i]), p1 = (float3)(P[12 + i], P[16 + i], P[20 + i]),
                     p2 = (float3)(P[24 + i], P[28 + i], P[32 + i]);
        if (rk_degenerate(p0, p1, p2)) m &= ~(1u << i);
    }
    return m;
}
)CLC";


}  // namespace raykit::kernels
