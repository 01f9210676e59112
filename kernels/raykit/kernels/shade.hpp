// raykit/kernels/shade.hpp — the wavefront renderer's device side: path and
// shadow queues, the surface at a hit and the ray-hook API. The built-in
// shaders (normals, depth, whitted, ao, debug-cost) are hooks on this API, one
// header each in kernels/raykit/kernels/shaders/. Host side:
// include/raykit/cl/render.hpp. Two parts: kShadeData (the crossing structs,
// per-object material lookup and, with RK_LEAF_FILTER, the alpha cut-out
// filter the walk calls) goes before kernels/raykit/kernels/trace.hpp,
// kShade (everything else) after it. The closest-hit and shadow kernels run
// trace.hpp's rk_walk over the DeviceScene's two levels.
//
// A frame is one pass per sample index s = 0 .. spp-1, each a loop over
// bounces. rk_dr_camera fills queue 0 with sample s of every pixel (one
// camera ray per pixel in 4 x 4-pixel tiles, placed as raykit::PixelSampler
// places it, with the sample's generator state; pass 0 also clears the image).
// Per bounce:
//   rk_dr_closest        closest hit of every ray of the current queue (and,
//                        for hooks that ask, its traversal steps: bottom-level
//                        inner nodes + leaves, as the CPU counts them);
//                        rk_dr_closest_packet with RK_PACKET (16 rays a
//                        work-item, kernels/raykit/kernels/trace_packet.hpp)
//   rk_dr_shade_NAME     per ray: the surface at the hit, then the hook NAME,
//                        which may add colour to the ray's pixel and emit
//                        shadow rays (any-hit) and continuation rays (closest
//                        hit, next bounce). Ray i's shadow rays go to fixed
//                        slots i·max_shadows.. (unused ones marked empty), its
//                        continuation rays to fixed slots of a staging queue
//                        that the work-group copies, packed, into a range of
//                        the next queue: one global atomic add per work-group
//                        for each queue, none per ray
//   rk_dr_shadow         any hit of every emitted shadow ray (empty slots
//                        skipped); unblocked ones add their colour to their
//                        pixel; rk_dr_shadow_packet with RK_PACKET
// until the next queue is empty. The host sizes each queue before the shade
// launch as (rays of this bounce) × (the hook's maximum per hit), so queues
// grow with the rays alive, never with pixels × a fixed maximum.
//
// Colour accumulation: OpenCL 1.2 has no atomic float add, and several rays
// of one pixel (a reflection and a refraction, their shadow rays) may add to
// it in the same launch, so rk_add_color adds with an atomic_cmpxchg loop on
// the float's bits (rk_atomic_add_float). The order of additions, and so the
// last bits of a pixel, may vary between runs. The image holds sums over the
// samples; the host multiplies by 1 / spp (as render_cpu does).
//
// Random numbers: raykit::SampleRng (splitmix64) and raykit::hash_seed with
// the same 64-bit integer operations (rk_rng_*, rk_hash_seed). Each path ray
// carries its sample's generator state; camera-ray hooks draw the numbers the
// CPU shader draws for that sample (rk_random), continuation rays inherit the
// state at the time they are emitted.
//
// Ray-hook API (what a hook's source may call; ctx is the hook's first argument)
//   void  rk_add_color(rk_ctx* ctx, float3 c)      add c (linear RGB) to the path's pixel
//   void  rk_set_alpha(rk_ctx* ctx, float a)       set the coverage of this sample (camera rays
//                                                  only, depth 0; the pixel's alpha is the mean)
//   float rk_random(rk_ctx* ctx)                   next uniform float in [0, 1) of the sample's
//                                                  generator (SampleRng::next_float)
//   uint  rk_traversal_steps(const rk_ctx* ctx)    inner nodes + leaves the closest-hit walk of
//                                                  this ray visited (hooks that declare
//                                                  traversal_steps; else 0)
//   bool  rk_emit_shadow(rk_ctx* ctx, float3 org, float3 dir, float tmax, float3 c)
//                                                  any-hit query on [0, tmax]: adds c to the
//                                                  pixel when nothing blocks it; false when the
//                                                  hook's shadow-ray budget per hit is used up
//   bool  rk_emit_ray(rk_ctx* ctx, float3 org, float3 dir, float3 weight, uint kind)
//                                                  closest-hit continuation at depth + 1 with
//                                                  throughput `weight`; false (nothing emitted)
//                                                  when depth >= max_depth or the budget is used
//   rk_material rk_get_material(const rk_ctx* ctx, uint id)
//   float4 rk_texture_sample(const rk_ctx* ctx, int texture, float2 uv)   linear RGBA,
//                                                  the settings' filter, wrap addressing
//   float3 rk_offset_origin(float3 p, float3 n)    raykit::offset_ray_origin
//   bool  rk_light_ray(rk_light l, float3 org, float3* dir, float* tmax)
//                                                  raykit::light_ray: the shadow ray toward l
//   uint  rk_light_count(const rk_ctx*), rk_light rk_get_light(const rk_ctx*, uint i)
//   ctx->set                                       the frame's rk_render_settings
// The hook's signature:
//   void NAME(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit,
//             const rk_surface* s, NAME_params p)
// hit->prim == RK_INVALID on a miss (then *s is all zero). path->weight is the
// path's throughput, path->depth its bounce (0 = camera ray), path->pixel its
// pixel (y · width + x), path->kind what the emitter said (0 = camera ray).
//
// Layouts: every struct below that crosses to the host has its size and field
// offsets checked at compile time here (RK_DR_CHECK) and in cl/render.hpp
// (static_assert), with the same numbers.
#pragma once

namespace raykit::kernels {

/// The renderer's crossing structs, per-object material lookup and cut-out filter (before trace.hpp).
inline constexpr const char* kShadeData = R"CLC(
/* Path ray of a bounce queue (raykit::cl::PathRay). */
typedef struct {
    rk_ray ray;
    float weight[3];
    uint pixel;
    uint depth;
    uint kind;
    ulong rng;        /* state of the sample's generator (raykit::SampleRng::state) */
} rk_path_ray;

/* Shadow ray: colour added to `pixel` when nothing blocks it (raykit::cl::ShadowRay). */
typedef struct {
    rk_ray ray;
    float color[3];
    uint pixel;
} rk_shadow_ray;

/* Material (raykit::cl::MaterialRecord): see raykit::RenderMaterial. */
typedef struct {
    float kd[3];
    float ks[3];
    float ke[3];
    float mirror[3];
    float ns;
    float ni;
    float transparency;
    int texture;          /* map_Kd: index into the texture table, -1 = none */
    int fresnel_mirror;
    int alpha_tested;
    int illum;
    int pad;
} rk_material;

/* Texture (raykit::cl::TextureRecord): texels [offset, offset + width·height) of
   the texel buffer, RGBA bytes, row 0 = top row of the file. */
typedef struct {
    uint offset;
    uint width;
    uint height;
    uint srgb;
} rk_texture;

/* Light (raykit::cl::LightRecord): type 0 = point, 1 = directional. */
typedef struct {
    float position[3];
    uint type;
    float direction[3];
    float pad0;
    float color[3];
    float pad1;
} rk_light;

/* Per-frame settings (raykit::cl::RenderSettingsRecord). */
typedef struct {
    float ambient[3];
    float background[3];
    float min_weight;
    float depth_far;      /* resolved on the host: > 0, or 0 = depth shader gives 0 */
    uint width;
    uint height;
    uint max_depth;
    uint shadows;
    uint filter;          /* 0 bilinear, 1 nearest */
    uint light_count;
    uint object_count;    /* objects of the scene (rk_shade_object table) */
    uint pad3;
    uint pad4;
    uint material_count;  /* the concatenated table's, every object's default material included */
    uint alpha_testing;   /* some material has alpha cut-outs: the program has the leaf filter */
    uint ao_samples;      /* ao: rays per camera ray */
    float ao_radius;      /* ao: resolved on the host (> 0, or INFINITY) */
    uint pad0;
    uint pad1;
    uint pad2;
} rk_render_settings;

/* Compile-time layout checks, the twins of the static_asserts in cl/render.hpp. */
#define RK_DR_CHECK(name, cond) typedef char rk_dr_layout_check_##name[(cond) ? 1 : -1]
RK_DR_CHECK(path_size, sizeof(rk_path_ray) == 64);
RK_DR_CHECK(path_weight, __builtin_offsetof(rk_path_ray, weight) == 32);
RK_DR_CHECK(path_pixel, __builtin_offsetof(rk_path_ray, pixel) == 44);
RK_DR_CHECK(path_depth, __builtin_offsetof(rk_path_ray, depth) == 48);
RK_DR_CHECK(path_kind, __builtin_offsetof(rk_path_ray, kind) == 52);
RK_DR_CHECK(path_rng, __builtin_offsetof(rk_path_ray, rng) == 56);
RK_DR_CHECK(shadow_size, sizeof(rk_shadow_ray) == 48);
RK_DR_CHECK(shadow_color, __builtin_offsetof(rk_shadow_ray, color) == 32);
RK_DR_CHECK(shadow_pixel, __builtin_offsetof(rk_shadow_ray, pixel) == 44);
RK_DR_CHECK(material_size, sizeof(rk_material) == 80);
RK_DR_CHECK(material_ks, __builtin_offsetof(rk_material, ks) == 12);
RK_DR_CHECK(material_ke, __builtin_offsetof(rk_material, ke) == 24);
RK_DR_CHECK(material_mirror, __builtin_offsetof(rk_material, mirror) == 36);
RK_DR_CHECK(material_ns, __builtin_offsetof(rk_material, ns) == 48);
RK_DR_CHECK(material_ni, __builtin_offsetof(rk_material, ni) == 52);
RK_DR_CHECK(material_transparency, __builtin_offsetof(rk_material, transparency) == 56);
RK_DR_CHECK(material_texture, __builtin_offsetof(rk_material, texture) == 60);
RK_DR_CHECK(material_fresnel, __builtin_offsetof(rk_material, fresnel_mirror) == 64);
RK_DR_CHECK(material_alpha, __builtin_offsetof(rk_material, alpha_tested) == 68);
RK_DR_CHECK(material_illum, __builtin_offsetof(rk_material, illum) == 72);
RK_DR_CHECK(texture_size, sizeof(rk_texture) == 16);
RK_DR_CHECK(texture_width, __builtin_offsetof(rk_texture, width) == 4);
RK_DR_CHECK(texture_height, __builtin_offsetof(rk_texture, height) == 8);
RK_DR_CHECK(texture_srgb, __builtin_offsetof(rk_texture, srgb) == 12);
RK_DR_CHECK(light_size, sizeof(rk_light) == 48);
RK_DR_CHECK(light_type, __builtin_offsetof(rk_light, type) == 12);
RK_DR_CHECK(light_direction, __builtin_offsetof(rk_light, direction) == 16);
RK_DR_CHECK(light_color, __builtin_offsetof(rk_light, color) == 32);
RK_DR_CHECK(settings_size, sizeof(rk_render_settings) == 96);
RK_DR_CHECK(settings_background, __builtin_offsetof(rk_render_settings, background) == 12);
RK_DR_CHECK(settings_min_weight, __builtin_offsetof(rk_render_settings, min_weight) == 24);
RK_DR_CHECK(settings_depth_far, __builtin_offsetof(rk_render_settings, depth_far) == 28);
RK_DR_CHECK(settings_width, __builtin_offsetof(rk_render_settings, width) == 32);
RK_DR_CHECK(settings_max_depth, __builtin_offsetof(rk_render_settings, max_depth) == 40);
RK_DR_CHECK(settings_light_count, __builtin_offsetof(rk_render_settings, light_count) == 52);
RK_DR_CHECK(settings_material_count, __builtin_offsetof(rk_render_settings, material_count) == 68);
RK_DR_CHECK(settings_alpha_testing, __builtin_offsetof(rk_render_settings, alpha_testing) == 72);
RK_DR_CHECK(settings_ao_samples, __builtin_offsetof(rk_render_settings, ao_samples) == 76);
RK_DR_CHECK(settings_ao_radius, __builtin_offsetof(rk_render_settings, ao_radius) == 80);

/* Per-object shading data (raykit::cl::ShadeObjectRecord), in object order: the object's
   material table is materials[material_offset .. material_offset + material_count), its
   default material (the last) included; its triangles' material ids are material_ids from its
   rk_object's triangle_offset on (the first material_id_count triangles have one). */
typedef struct {
    uint material_offset;
    uint material_count;
    uint material_id_count;
    uint flags;             /* RK_SHADE_NORMALS: vertex normals, RK_SHADE_UVS: texture coordinates */
} rk_shade_object;
#define RK_SHADE_NORMALS 1u
#define RK_SHADE_UVS 2u
RK_DR_CHECK(shade_object_size, sizeof(rk_shade_object) == 16);
RK_DR_CHECK(shade_object_count, __builtin_offsetof(rk_shade_object, material_count) == 4);
RK_DR_CHECK(shade_object_ids, __builtin_offsetof(rk_shade_object, material_id_count) == 8);
RK_DR_CHECK(shade_object_flags, __builtin_offsetof(rk_shade_object, flags) == 12);

/* Index into the concatenated material table of triangle `prim` of object `object`
   (raykit::MaterialTable::for_triangle: no or a too large id gives the default material). */
RK_INLINE uint rk_material_of(__global const rk_shade_object* objects, __global const uint* material_ids,
                              const uint object, const rk_object* ob, const uint prim) {
    const rk_shade_object so = objects[object];
    const uint last = so.material_count - 1;
    uint id = last;
    if (prim < so.material_id_count) {
        id = material_ids[ob->triangle_offset + prim];
        if (id >= last) id = last;
    }
    return so.material_offset + id;
}

/* Texture coordinates of triangle `prim` of an object at barycentrics (u, v); (0, 0) for an
   object without them (raykit::detail::interpolate_uv). */
RK_INLINE float2 rk_uv_at(const rk_shade_object* so, const rk_object* ob, __global const rk_triangle* tris,
                          __global const rk_vertex* vertices, const uint prim, const float u, const float v) {
    if (!(so->flags & RK_SHADE_UVS)) return (float2)(0.0f);
    const rk_triangle t = tris[ob->triangle_offset + prim];
    __global const rk_vertex* vx = vertices + ob->vertex_offset;
    return vload2(0, vx[t.v[0]].uv) * (1.0f - u - v) + vload2(0, vx[t.v[1]].uv) * u + vload2(0, vx[t.v[2]].uv) * v;
}

RK_INLINE float rk_frac(float a) {
    if (!isfinite(a)) return 0.0f;
    const float f = a - floor(a);
    return f < 1.0f ? f : 0.0f;
}
RK_INLINE uint rk_wrap(long i, uint n) { return (uint)(i < 0 ? i + (long)n : (i >= (long)n ? i - (long)n : i)); }

/* Where raykit::Texture::sample reads (colour and alpha alike): nearest (filter 1) the texel
   (x0, y0); bilinear the texels x0|x1, y0|y1 weighted by ax, ay (wrap addressing). Rows are
   counted from the top of the file, v from the bottom. The texture must not be empty. */
typedef struct {
    uint x0, x1, y0, y1;
    float ax, ay;
} rk_taps;

RK_INLINE rk_taps rk_texture_taps(const rk_texture* t, float2 uv, uint filter) {
    rk_taps q;
    if (filter == 1u) {
        const float u = rk_frac(uv.x), v = rk_frac(uv.y);
        q.x0 = q.x1 = min((uint)(u * (float)t->width), t->width - 1);
        q.y0 = q.y1 = t->height - 1 - min((uint)(v * (float)t->height), t->height - 1);
        q.ax = q.ay = 0.0f;
        return q;
    }
    const float fx = rk_frac(uv.x) * (float)t->width - 0.5f;
    const float fy = rk_frac(uv.y) * (float)t->height - 0.5f;
    const float flx = floor(fx), fly = floor(fy);
    q.ax = fx - flx;
    q.ay = fy - fly;
    const long ix = (long)flx, iy = (long)fly;
    q.x0 = rk_wrap(ix, t->width);
    q.x1 = rk_wrap(ix + 1, t->width);
    q.y0 = t->height - 1 - rk_wrap(iy, t->height);
    q.y1 = t->height - 1 - rk_wrap(iy + 1, t->height);
    return q;
}

#ifdef RK_LEAF_FILTER
/* ---- alpha cut-outs, the walk's leaf filter (kernels/raykit/kernels/trace.hpp): the twins of
   raykit::detail::cut_out and Texture::sample_alpha. Compiled only for scenes with cut-outs. */
typedef struct {
    __global const rk_material* materials;
    __global const uint* material_ids;
    __global const rk_shade_object* shade_objects;
    __global const rk_vertex* vertices;
    __global const rk_triangle* tris;
    __global const rk_texture* textures;
    __global const uchar4* texels;
    uint filter;      /* 0 bilinear, 1 nearest */
} rk_filter;

RK_INLINE float rk_alpha_byte(const rk_filter* a, const rk_texture* t, uint x, uint y) {
    return (float)a->texels[t->offset + y * t->width + x].w;
}

RK_INLINE float rk_texture_alpha(const rk_filter* a, int texture, float2 uv) {
    if (texture < 0) return 1.0f;
    const rk_texture t = a->textures[texture];
    if (t.width == 0 || t.height == 0) return 1.0f;
    const float k = 1.0f / 255.0f;
    const rk_taps q = rk_texture_taps(&t, uv, a->filter);
    if (a->filter == 1u) return rk_alpha_byte(a, &t, q.x0, q.y0) * k;
    const float va = rk_alpha_byte(a, &t, q.x0, q.y0), vb = rk_alpha_byte(a, &t, q.x1, q.y0);
    const float vc = rk_alpha_byte(a, &t, q.x0, q.y1), vd = rk_alpha_byte(a, &t, q.x1, q.y1);
    return ((va * (1.0f - q.ax) + vb * q.ax) * (1.0f - q.ay) + (vc * (1.0f - q.ax) + vd * q.ax) * q.ay) * k;
}

/* False when the hit (prim, u, v) of object `object` lies on a cut-out texel of an
   alpha-tested material. */
RK_INLINE bool rk_keep(const rk_filter* f, uint object, const rk_object* ob, uint prim, float u, float v) {
    __global const rk_material* m = f->materials + rk_material_of(f->shade_objects, f->material_ids, object, ob, prim);
    if (!m->alpha_tested) return true;
    const rk_shade_object so = f->shade_objects[object];
    return !(rk_texture_alpha(f, m->texture, rk_uv_at(&so, ob, f->tris, f->vertices, prim, u, v)) < 0.5f);
}
#endif
)CLC";

/// The renderer's kernels (after kernels/raykit/kernels/trace.hpp).
inline constexpr const char* kShade = R"CLC(
/* ---- random numbers: the twins of raykit::SampleRng and raykit::hash_seed (render/shade.hpp) */
typedef struct {
    ulong state;
} rk_rng;

#define RK_GOLDEN 0x9E3779B97F4A7C15UL

/* SampleRng::next_u64 (splitmix64). */
RK_INLINE ulong rk_rng_next(rk_rng* r) {
    ulong z = (r->state += RK_GOLDEN);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9UL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBUL;
    return z ^ (z >> 31);
}
/* SampleRng::next_float: uniform in [0, 1). */
RK_INLINE float rk_rng_float(rk_rng* r) { return (float)(rk_rng_next(r) >> 40) * (1.0f / 16777216.0f); }
/* hash_seed(a, b, c). */
RK_INLINE ulong rk_hash_seed(ulong a, ulong b, ulong c) {
    rk_rng r;
    r.state = (a * 0xD6E8FEB86659FD93UL) ^ b;
    const ulong t = rk_rng_next(&r) + c * RK_GOLDEN;
    r.state ^= t;
    return rk_rng_next(&r);
}

/* The surface at a hit (raykit::SurfacePoint). */
typedef struct {
    float3 p;       /* position */
    float3 ng;      /* unit geometric normal facing the incoming ray */
    float3 ns;      /* unit shading normal facing the incoming ray */
    float3 d;       /* unit ray direction */
    float3 base;    /* Kd times the map_Kd colour */
    float2 uv;
    uint material;  /* index into the material table (default material resolved) */
    int entering;   /* the ray arrives from the outside */
} rk_surface;

typedef struct {
    __global const rk_material* materials;
    __global const rk_texture* textures;
    __global const uchar4* texels;
    __global const float* srgb_lut;
    __global const rk_light* lights;
    rk_render_settings set;
    __global float* image;            /* 4 floats per pixel: r, g, b, alpha */
    __global rk_path_ray* next;       /* this ray's staging slots: next_first .. + max_rays */
    uint next_first;
    uint max_rays;
    __global uint* counters;          /* [0] next-queue rays, [1] shadow rays */
    __global rk_shadow_ray* shadows;  /* this ray's slots: shadow_first .. + max_shadows */
    uint shadow_first;
    uint max_shadows;
    uint pixel;
    uint depth;
    uint rays_left;
    uint shadows_left;
    rk_rng rng;                       /* the sample's generator (see rk_random) */
    uint steps;                       /* closest-hit traversal steps (hooks that ask), else 0 */
    float alpha_before;               /* camera rays: the pixel's coverage from earlier samples */
    uint exclusive;                   /* no other ray of this launch adds to this pixel: plain adds */
} rk_ctx;

RK_INLINE float3 rk_f3(const float* a) { return (float3)(a[0], a[1], a[2]); }
RK_INLINE float3 rk_g3(__global const float* a) { return (float3)(a[0], a[1], a[2]); }
RK_INLINE float rk_max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }

/* Atomic float add by compare-and-swap on the bits (OpenCL 1.2 has no float atomics). */
RK_INLINE void rk_atomic_add_float(__global float* a, float v) {
    if (v == 0.0f) return;
    volatile __global uint* u = (volatile __global uint*)a;
    uint old = *u, assumed;
    do {
        assumed = old;
        old = atomic_cmpxchg(u, assumed, as_uint(as_float(assumed) + v));
    } while (old != assumed);
}

/* Adds c to pixel px: a plain add when no other work-item of the launch adds to the pixel
   (`exclusive`), else atomically. On a CPU device every atomic is a locked instruction, which
   keeps the work-item loop from overlapping its texel loads with the next item's: plain adds
   took the thesis frame's shade kernel on PoCL from 28.1 to 10.7 ms (bench_render). */
RK_INLINE void rk_add_to_pixel(__global float* px, float3 c, uint exclusive) {
    if (exclusive) {
        px[0] += c.x;
        px[1] += c.y;
        px[2] += c.z;
        return;
    }
    rk_atomic_add_float(px + 0, c.x);
    rk_atomic_add_float(px + 1, c.y);
    rk_atomic_add_float(px + 2, c.z);
}

RK_INLINE void rk_add_color(rk_ctx* ctx, float3 c) {
    rk_add_to_pixel(ctx->image + (size_t)4 * ctx->pixel, c, ctx->exclusive);
}

/* One camera ray per pixel is in flight per pass, so a plain store is race-free. */
RK_INLINE void rk_set_alpha(rk_ctx* ctx, float a) {
    if (ctx->depth == 0) ctx->image[(size_t)4 * ctx->pixel + 3] = ctx->alpha_before + a;
}

RK_INLINE float rk_random(rk_ctx* ctx) { return rk_rng_float(&ctx->rng); }
RK_INLINE uint rk_traversal_steps(const rk_ctx* ctx) { return ctx->steps; }

RK_INLINE rk_ray rk_make_ray(float3 org, float3 dir, float tmin, float tmax) {
    rk_ray r;
    r.org[0] = org.x; r.org[1] = org.y; r.org[2] = org.z;
    r.dir[0] = dir.x; r.dir[1] = dir.y; r.dir[2] = dir.z;
    r.tmin = tmin;
    r.tmax = tmax;
    return r;
}

RK_INLINE bool rk_emit_shadow(rk_ctx* ctx, float3 org, float3 dir, float tmax, float3 c) {
    if (ctx->shadows_left == 0) return false;
    const uint slot = ctx->shadow_first + (ctx->max_shadows - ctx->shadows_left);  /* no atomic: see the kernel */
    --ctx->shadows_left;
    rk_shadow_ray s;
    s.ray = rk_make_ray(org, dir, 0.0f, tmax);
    s.color[0] = c.x; s.color[1] = c.y; s.color[2] = c.z;
    s.pixel = ctx->pixel;
    ctx->shadows[slot] = s;
    return true;
}

RK_INLINE bool rk_emit_ray(rk_ctx* ctx, float3 org, float3 dir, float3 weight, uint kind) {
    if (ctx->depth >= ctx->set.max_depth || ctx->rays_left == 0) return false;
    const uint slot = ctx->next_first + (ctx->max_rays - ctx->rays_left);  /* staged: see the kernel */
    --ctx->rays_left;
    rk_path_ray r;
    r.ray = rk_make_ray(org, dir, 0.0f, INFINITY);
    r.weight[0] = weight.x; r.weight[1] = weight.y; r.weight[2] = weight.z;
    r.pixel = ctx->pixel;
    r.depth = ctx->depth + 1;
    r.kind = kind;
    r.rng = ctx->rng.state;
    ctx->next[slot] = r;
    return true;
}

RK_INLINE rk_material rk_get_material(const rk_ctx* ctx, uint id) {
    return ctx->materials[id < ctx->set.material_count ? id : ctx->set.material_count - 1];
}
RK_INLINE uint rk_light_count(const rk_ctx* ctx) { return ctx->set.light_count; }
RK_INLINE rk_light rk_get_light(const rk_ctx* ctx, uint i) { return ctx->lights[i]; }

/* raykit::offset_ray_origin (Wächter & Binder). */
/* The shadow ray toward light l from org (raykit::light_ray): unit direction, tmax =
   distance * (1 - 1e-4) for a point light, INFINITY for a directional one; false for a
   degenerate light. */
RK_INLINE bool rk_light_ray(rk_light l, float3 org, float3* dir, float* tmax) {
    if (l.type == 0u) {
        const float3 to = rk_f3(l.position) - org;
        const float dist = length(to);
        if (!(dist > 0.0f)) return false;
        *dir = to / dist;
        *tmax = dist * (1.0f - 1e-4f);
        return true;
    }
    const float ll = length(rk_f3(l.direction));
    if (!(ll > 0.0f)) return false;
    *dir = -rk_f3(l.direction) / ll;
    *tmax = INFINITY;
    return true;
}

RK_INLINE float3 rk_offset_origin(float3 p, float3 n) {
    const float pa[3] = {p.x, p.y, p.z}, na[3] = {n.x, n.y, n.z};
    float out[3];
    for (int a = 0; a < 3; ++a) {
        const int of = (int)(256.0f * na[a]);
        const int bits = as_int(pa[a]);
        const float moved = as_float(bits + (pa[a] < 0.0f ? -of : of));
        out[a] = fabs(pa[a]) < (1.0f / 32.0f) ? pa[a] + (1.0f / 65536.0f) * na[a] : moved;
    }
    return (float3)(out[0], out[1], out[2]);
}

/* ---- textures: the twins of raykit::Texture::sample */
RK_INLINE float4 rk_texel(const rk_ctx* ctx, const rk_texture* t, uint x, uint y) {
    const uchar4 b = ctx->texels[t->offset + y * t->width + x];
    const float k = 1.0f / 255.0f;
    if (t->srgb) return (float4)(ctx->srgb_lut[b.x], ctx->srgb_lut[b.y], ctx->srgb_lut[b.z], (float)b.w * k);
    return (float4)((float)b.x * k, (float)b.y * k, (float)b.z * k, (float)b.w * k);
}
RK_INLINE float4 rk_texture_sample(const rk_ctx* ctx, int texture, float2 uv) {
    if (texture < 0) return (float4)(1.0f);
    const rk_texture t = ctx->textures[texture];
    if (t.width == 0 || t.height == 0) return (float4)(0.0f);
    const rk_taps q = rk_texture_taps(&t, uv, ctx->set.filter);
    if (ctx->set.filter == 1u) return rk_texel(ctx, &t, q.x0, q.y0);
    const float4 a = rk_texel(ctx, &t, q.x0, q.y0), b = rk_texel(ctx, &t, q.x1, q.y0);
    const float4 c = rk_texel(ctx, &t, q.x0, q.y1), d = rk_texel(ctx, &t, q.x1, q.y1);
    return (a * (1.0f - q.ax) + b * q.ax) * (1.0f - q.ay) + (c * (1.0f - q.ax) + d * q.ax) * q.ay;
}

/* ---- the surface at a hit: the twin of raykit::surface_point */

/* Affine::point: M·(p, 1) with the same fused multiply-adds. */
RK_INLINE float3 rk_affine_point(__global const float* m, float3 p) {
    return (float3)(fma(m[0], p.x, fma(m[1], p.y, fma(m[2], p.z, m[3]))),
                    fma(m[4], p.x, fma(m[5], p.y, fma(m[6], p.z, m[7]))),
                    fma(m[8], p.x, fma(m[9], p.y, fma(m[10], p.z, m[11]))));
}
/* A normal in object space to the world: by the inverse transpose (world_to_object's 3x3
   transposed); an identity instance's is not mapped. */
RK_INLINE float3 rk_normal_to_world(__global const rk_instance* in, float3 n) {
    if (in->identity) return n;
    __global const float* a = in->world_to_object;
    return (float3)(a[0] * n.x + a[4] * n.y + a[8] * n.z, a[1] * n.x + a[5] * n.y + a[9] * n.z,
                    a[2] * n.x + a[6] * n.y + a[10] * n.z);
}

/* The surface of instance hit->inst at the hit, computed in object space and mapped to the
   world (identity instances are not mapped); d is the unit world ray direction. */
RK_INLINE rk_surface rk_surface_at(const rk_ctx* ctx, __global const rk_instance* instances,
                                   __global const rk_object* objects, __global const rk_shade_object* shade_objects,
                                   __global const rk_triangle* tris, __global const float* pos,
                                   __global const rk_vertex* vertices, __global const uint* material_ids,
                                   const rk_hit* h, float3 d) {
    __global const rk_instance* in = instances + h->inst;
    const uint object = in->object;
    const rk_object ob = objects[object];
    const rk_shade_object so = shade_objects[object];
    const rk_triangle t = tris[ob.triangle_offset + h->prim];
    __global const float* p = pos + (size_t)3 * ob.vertex_offset;
    __global const rk_vertex* vx = vertices + ob.vertex_offset;
    const float w0 = 1.0f - h->u - h->v;
    const float3 p0 = vload3(t.v[0], p), p1 = vload3(t.v[1], p), p2 = vload3(t.v[2], p);
    rk_surface s;
    s.p = p0 * w0 + p1 * h->u + p2 * h->v;
    if (!in->identity) s.p = rk_affine_point(in->object_to_world, s.p);
    s.d = d;
    float3 ng = rk_normal_to_world(in, cross(p1 - p0, p2 - p0));
    const float lg = length(ng);
    ng = lg > 0.0f && isfinite(lg) ? ng / lg : -d;
    int entering = dot(ng, d) < 0.0f;
    float3 ns = ng;
    if (so.flags & RK_SHADE_NORMALS) {
        const float3 n = rk_normal_to_world(in, vload3(0, vx[t.v[0]].normal) * w0 + vload3(0, vx[t.v[1]].normal) * h->u +
                                                    vload3(0, vx[t.v[2]].normal) * h->v);
        const float ln = length(n);
        if (ln > 1e-12f && isfinite(ln)) {
            ns = n / ln;
            entering = dot(ns, d) < 0.0f;
        }
    }
    s.entering = entering;
    s.ng = dot(ng, d) > 0.0f ? -ng : ng;
    s.ns = dot(ns, d) > 0.0f ? -ns : ns;
    s.uv = rk_uv_at(&so, &ob, tris, vertices, h->prim, h->u, h->v);
    s.material = rk_material_of(shade_objects, material_ids, object, &ob, h->prim);
    const rk_material m = ctx->materials[s.material];
    s.base = rk_f3(m.kd);
    if (m.texture >= 0) s.base *= rk_texture_sample(ctx, m.texture, s.uv).xyz;
    return s;
}

/* ---- fixed kernels */

/* The N-rooks column of sample s (raykit::PixelSampler): the forward shuffle is
   "for k = spp-1 down to 1: swap(col[k], col[u_k % (k + 1)])" with u_k the (spp - k)-th draw of
   SampleRng(hash_seed(seed, pixel, ~0)) from the identity; undoing the swaps from the last one
   (k = 1) to the first tells which original position, i.e. which column, ends at s. splitmix64
   is counter-based (the state before draw d is seed + (d - 1)·golden), so no array is needed. */
RK_INLINE uint rk_nrooks_column(ulong seed, ulong pixel, uint s, uint spp) {
    const ulong base = rk_hash_seed(seed, pixel, ~(ulong)0);
    uint pos = s;
    for (uint k = 1; k < spp; ++k) {
        rk_rng r;
        r.state = base + (ulong)(spp - 1u - k) * RK_GOLDEN;
        const uint j = (uint)(rk_rng_next(&r) % (ulong)(k + 1u));
        if (pos == k) pos = j;
        else if (pos == j) pos = k;
    }
    return pos;
}

/* The pixel of queue slot q: bands of four rows in 4 x 4-pixel tiles (the columns past the last
   whole tile row by row within the band), the rows past the last whole band row by row — a
   bijection on [0, w·h), so neighbouring slots hold neighbouring pixels in both directions and
   the packet walk's 16 consecutive rays are a tile, as the CPU renderer's are. */
RK_INLINE uint rk_tile_pixel(const uint q, const uint w, const uint h) {
    const uint band = 4u * w;
    if (q >= (h / 4u) * band) return q;
    const uint b = q / band, j = q - b * band, tiles = w / 4u;
    uint x, y;
    if (j < 16u * tiles) {
        x = 4u * (j / 16u) + (j & 3u);
        y = 4u * b + ((j & 15u) >> 2);
    } else {
        const uint r = j - 16u * tiles, rest = w - 4u * tiles;
        x = 4u * tiles + r % rest;
        y = 4u * b + r / rest;
    }
    return y * w + x;
}

/* Sample `sample` of every pixel into queue 0, slot q holding pixel rk_tile_pixel(q)
   (raykit::PixelSampler: grid_m = m for an m x m grid, 0 for N-rooks; inv_m = 1 / m and
   inv_spp = 1 / spp computed on the host); pass 0 clears the image. */
__kernel void rk_dr_camera(const rk_camera cam, __global rk_path_ray* queue, __global float4* image,
                           const ulong seed, const uint sample, const uint spp, const uint grid_m,
                           const float inv_m, const float inv_spp, const uint jitter) {
    const uint q = (uint)get_global_id(0);
    if (q >= cam.width * cam.height) return;
    const uint i = rk_tile_pixel(q, cam.width, cam.height);
    const uint y = i / cam.width;
    const uint x = i - y * cam.width;
    rk_rng rng;
    rng.state = rk_hash_seed(seed, (ulong)i, (ulong)sample);
    const float r1 = jitter ? rk_rng_float(&rng) : 0.5f;
    const float r2 = jitter ? rk_rng_float(&rng) : 0.5f;
    float jx, jy;
    if (grid_m != 0u) {
        jx = ((float)(sample % grid_m) + r1) * inv_m;
        jy = ((float)(sample / grid_m) + r2) * inv_m;
    } else {
        jx = ((float)sample + r1) * inv_spp;
        jy = ((float)rk_nrooks_column(seed, (ulong)i, sample, spp) + r2) * inv_spp;
    }
    rk_path_ray r;
    r.ray = rk_camera_ray(&cam, x, y, jx, jy);
    r.weight[0] = 1.0f; r.weight[1] = 1.0f; r.weight[2] = 1.0f;
    r.pixel = i;
    r.depth = 0u;
    r.kind = 0u;
    r.rng = rng.state;
    queue[q] = r;
    if (sample == 0u) image[i] = (float4)(0.0f);
}

/* The renderer's scene arguments after RK_SCENE_PARAMS (kernels/raykit/kernels/trace.hpp):
   what shading and the cut-out filter read. */
#define RK_DR_SHADE_PARAMS __global const rk_vertex* vertices, __global const uint* material_ids, \
    __global const rk_shade_object* shade_objects, __global const rk_material* materials, \
    __global const rk_texture* textures, __global const uchar4* texels, const rk_render_settings set
#ifdef RK_LEAF_FILTER
#define RK_DR_FILTER(fp) const rk_filter rk_dr_filter_value = {materials, material_ids, shade_objects, vertices, \
    tris, textures, texels, set.filter}; const rk_filter* fp = &rk_dr_filter_value
#else
#define RK_DR_FILTER(fp) const rk_filter* fp = 0
#endif

/* Closest hits of queue[0 .. n); with RK_DR_STEPS (defined for hooks that declare
   traversal_steps) also the traversal steps of each ray into steps[i]. */
__kernel void rk_dr_closest(RK_SCENE_PARAMS, __global const rk_path_ray* queue, __global rk_hit* hits,
                            __global uint* steps, const uint n, RK_DR_SHADE_PARAMS) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    RK_SCENE_MAKE(sc);
    RK_DR_FILTER(f);
    const rk_ray r = queue[i].ray;
    rk_hit h = rk_miss();
#ifdef RK_DR_STEPS
    uint st = 0u;
    rk_walk(&sc, &r, 0, &h, f, &st);
    steps[i] = st;
#else
    rk_walk(&sc, &r, 0, &h, f, 0);
#endif
    hits[i] = h;
}

/* `exclusive`: at most one shadow ray per pixel in this launch (the host knows: one ray per
   pixel in the bounce and at most one shadow ray per shaded ray), so colours add plainly. */
__kernel void rk_dr_shadow(RK_SCENE_PARAMS, __global const rk_shadow_ray* queue, const uint n, __global float* image,
                           RK_DR_SHADE_PARAMS, const uint exclusive) {
    const uint i = (uint)get_global_id(0);
    if (i >= n) return;
    RK_SCENE_MAKE(sc);
    RK_DR_FILTER(f);
    const rk_shadow_ray s = queue[i];
    if (s.pixel == RK_INVALID) return;  /* an empty slot */
    rk_hit h = rk_miss();
    if (rk_walk(&sc, &s.ray, 1, &h, f, 0)) return;
    rk_add_to_pixel(image + (size_t)4 * s.pixel, (float3)(s.color[0], s.color[1], s.color[2]), exclusive);
}

#ifdef RK_PACKET
/* rk_dr_closest and rk_dr_shadow with RK_PACKET rays per work-item (kernels/raykit/kernels/
   trace_packet.hpp: packets where the rays are coherent; the same hits bit for bit). Never in a
   program with RK_DR_STEPS. */
__kernel void rk_dr_closest_packet(RK_SCENE_PARAMS, __global const rk_path_ray* queue, __global rk_hit* hits,
                                   __global uint* steps, const uint n, RK_DR_SHADE_PARAMS) {
    const uint first = (uint)get_global_id(0) * RK_PACKET;
    if (first >= n) return;
    RK_SCENE_MAKE(sc);
    RK_DR_FILTER(f);
    const uint m = min((uint)RK_PACKET, n - first);
    rk_ray r[RK_PACKET];
    rk_hit h[RK_PACKET];
    for (uint k = 0; k < m; ++k) r[k] = queue[first + k].ray;
    rk_walk_batch(&sc, r, m, 0, h, f);
    for (uint k = 0; k < m; ++k) hits[first + k] = h[k];
}

__kernel void rk_dr_shadow_packet(RK_SCENE_PARAMS, __global const rk_shadow_ray* queue, const uint n,
                                  __global float* image, RK_DR_SHADE_PARAMS, const uint exclusive) {
    const uint first = (uint)get_global_id(0) * RK_PACKET;
    if (first >= n) return;
    RK_SCENE_MAKE(sc);
    RK_DR_FILTER(f);
    const uint end = min(first + (uint)RK_PACKET, n);
    rk_ray r[RK_PACKET];
    rk_hit h[RK_PACKET];
    uint slot[RK_PACKET];
    uint m = 0u;
    for (uint k = first; k < end; ++k)  /* the non-empty slots, in order */
        if (queue[k].pixel != RK_INVALID) {
            slot[m] = k;
            r[m++] = queue[k].ray;
        }
    if (m == 0u) return;
    const uint blocked = rk_walk_batch(&sc, r, m, 1, h, f);
    for (uint k = 0; k < m; ++k) {
        if ((blocked >> k) & 1u) continue;
        const rk_shadow_ray s = queue[slot[k]];
        rk_add_to_pixel(image + (size_t)4 * s.pixel, (float3)(s.color[0], s.color[1], s.color[2]), exclusive);
    }
}
#endif
)CLC";

/// The shade kernel of hook @NAME@ (the host replaces @NAME@ by the hook's name).
inline constexpr const char* kShadeStage = R"CLC(
__kernel void rk_dr_shade_@NAME@(__global const rk_path_ray* queue, __global const rk_hit* hits,
                                 __global const uint* steps, const uint n,
                                 __global const rk_instance* instances, __global const rk_object* objects,
                                 __global const rk_triangle* tris, __global const float* pos,
                                 __global const rk_vertex* vertices, __global const uint* material_ids,
                                 __global const rk_shade_object* shade_objects, __global const rk_material* materials,
                                 __global const rk_texture* textures, __global const uchar4* texels,
                                 __global const float* srgb_lut, __global const rk_light* lights,
                                 const rk_render_settings set, __global float* image,
                                 __global rk_path_ray* next, __global rk_path_ray* stage, __global uint* counters,
                                 __global rk_shadow_ray* shadows, const uint max_rays, const uint max_shadows,
                                 const uint exclusive, const @NAME@_params params) {
    /* the work-group's shadow rays (a count) and continuation rays (packed into one range of next) */
    __local uint group_shadows, group_rays, group_base;
    if (get_local_id(0) == 0) group_shadows = group_rays = 0u;
    barrier(CLK_LOCAL_MEM_FENCE);
    const uint i = (uint)get_global_id(0);
    uint rays = 0u, offset = 0u;
    if (i < n) {
        const rk_path_ray path = queue[i];
        const rk_hit hit = hits[i];
        rk_ctx ctx;
        ctx.materials = materials;
        ctx.textures = textures;
        ctx.texels = texels;
        ctx.srgb_lut = srgb_lut;
        ctx.lights = lights;
        ctx.set = set;
        ctx.image = image;
        ctx.next = stage;
        ctx.next_first = i * max_rays;
        ctx.max_rays = max_rays;
        ctx.counters = counters;
        ctx.shadows = shadows;
        ctx.shadow_first = i * max_shadows;
        ctx.max_shadows = max_shadows;
        ctx.pixel = path.pixel;
        ctx.depth = path.depth;
        ctx.rays_left = max_rays;
        ctx.shadows_left = max_shadows;
        ctx.rng.state = path.rng;
#ifdef RK_DR_STEPS
        ctx.steps = steps[i];
#else
        ctx.steps = 0u;
#endif
        ctx.alpha_before = path.depth == 0u ? image[(size_t)4 * path.pixel + 3] : 0.0f;
        ctx.exclusive = exclusive;
        rk_surface s;
        s.p = s.ng = s.ns = s.d = s.base = (float3)(0.0f);
        s.uv = (float2)(0.0f);
        s.material = 0u;
        s.entering = 1;
        if (hit.prim != RK_INVALID)
            s = rk_surface_at(&ctx, instances, objects, shade_objects, tris, pos, vertices, material_ids, &hit,
                              normalize(rk_f3(path.ray.dir)));
        @NAME@(&ctx, &path, &hit, &s, params);
        const uint used = max_shadows - ctx.shadows_left;
        for (uint k = used; k < max_shadows; ++k) shadows[ctx.shadow_first + k].pixel = RK_INVALID;  /* empty slot */
        if (used) atomic_add(&group_shadows, used);
        rays = max_rays - ctx.rays_left;
        if (rays) offset = atomic_add(&group_rays, rays);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (get_local_id(0) == 0) {
        if (group_shadows) atomic_add(counters + 1, group_shadows);
        if (group_rays) group_base = atomic_add(counters + 0, group_rays);
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    for (uint k = 0; k < rays; ++k) next[group_base + offset + k] = stage[i * max_rays + k];
}
)CLC";

}  // namespace raykit::kernels
