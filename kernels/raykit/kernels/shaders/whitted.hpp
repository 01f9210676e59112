// raykit/kernels/shaders/whitted.hpp — the built-in ray hook ShaderKind::whitted: Whitted ray
// tracing, the twin of the CPU's (render/shade.hpp).
// Its C++ type is in include/raykit/cl/render.hpp; the ray-hook API it calls is the core's,
// kernels/raykit/kernels/shade.hpp. One header per shader: a program holds only the hooks it
// renders with.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kShadeWhitted = R"CLC(typedef struct {
    float pad;
} rk_whitted_params;

/* Exact dielectric Fresnel reflectance (raykit::detail::fresnel_dielectric). */
RK_INLINE float rk_fresnel(float cos_i, float eta, float* cos_t) {
    cos_i = clamp(cos_i, 0.0f, 1.0f);
    const float sin2_t = eta * eta * fmax(0.0f, 1.0f - cos_i * cos_i);
    if (sin2_t >= 1.0f) {
        *cos_t = 0.0f;
        return 1.0f;
    }
    *cos_t = sqrt(1.0f - sin2_t);
    const float rs = (eta * cos_i - *cos_t) / (eta * cos_i + *cos_t);
    const float rp = (cos_i - eta * *cos_t) / (cos_i + eta * *cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

/* Schlick's approximation with normal-incidence reflectance f0 (raykit::detail::schlick). */
RK_INLINE float3 rk_schlick(float3 f0, float cos_i) {
    const float m = clamp(1.0f - cos_i, 0.0f, 1.0f);
    const float m5 = m * m * m * m * m;
    return f0 + ((float3)(1.0f) - f0) * m5;
}

/* Whitted shading, the twin of the CPU's WhittedShader (render/shaders.hpp). */
void rk_whitted(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, rk_whitted_params p) {
    const float3 w = rk_f3(path->weight);
    if (hit->prim == RK_INVALID) {
        rk_add_color(ctx, w * rk_f3(ctx->set.background));
        return;
    }
    rk_set_alpha(ctx, 1.0f);
    const rk_material m = rk_get_material(ctx, s->material);
    const float opaque = 1.0f - m.transparency;
    const float3 ks = rk_f3(m.ks), d = s->d;
    rk_add_color(ctx, w * (rk_f3(m.ke) + opaque * (rk_f3(ctx->set.ambient) * s->base)));
    const uint nl_count = rk_light_count(ctx);
    if (nl_count > 0u) {
        const float3 org = rk_offset_origin(s->p, s->ng);
        const bool want_spec = rk_max3(ks) > 0.0f;
        for (uint li = 0; li < nl_count; ++li) {
            const rk_light l = rk_get_light(ctx, li);
            float3 ldir;
            float tmax;
            if (!rk_light_ray(l, org, &ldir, &tmax)) continue;
            const float nl = dot(s->ns, ldir);
            if (!(nl > 0.0f) || !(dot(s->ng, ldir) > 0.0f)) continue;
            const float3 lc = rk_f3(l.color);
            float3 c = opaque * (s->base * (nl * lc));
            if (want_spec) {
                const float3 hv = normalize(ldir - d);
                const float nh = fmax(0.0f, dot(s->ns, hv));
                const float lh = fmax(0.0f, dot(ldir, hv));
                c += rk_schlick(ks, lh) * (((m.ns + 8.0f) * 0.125f * pow(nh, m.ns) * nl) * lc);
            }
            c *= w;
            if (ctx->set.shadows) rk_emit_shadow(ctx, org, ldir, tmax, c);
            else rk_add_color(ctx, c);
        }
    }
    if (path->depth >= ctx->set.max_depth) return;
    const float cos_i = fmax(0.0f, -dot(d, s->ns));
    float3 refl = rk_f3(m.mirror);
    if (m.fresnel_mirror && rk_max3(refl) > 0.0f) refl = rk_schlick(refl, cos_i);
    float trans = 0.0f;
    float3 tdir = (float3)(0.0f);
    if (m.transparency > 0.0f) {
        const float eta = s->entering ? 1.0f / m.ni : m.ni;
        float cos_t = 0.0f;
        const float F = rk_fresnel(cos_i, eta, &cos_t);
        refl += (float3)(m.transparency * F);
        if (F < 1.0f) {
            trans = m.transparency * (1.0f - F);
            tdir = d * eta + s->ns * (eta * cos_i - cos_t);
            if (!(dot(tdir, s->ng) < 0.0f)) {
                const float ci = fmax(0.0f, -dot(d, s->ng));
                const float s2 = eta * eta * fmax(0.0f, 1.0f - ci * ci);
                if (s2 < 1.0f) tdir = d * eta + s->ng * (eta * ci - sqrt(1.0f - s2));
                else trans = 0.0f;
            }
        }
    }
    const float3 wt = w * trans;
    if (trans > 0.0f && rk_max3(wt) > ctx->set.min_weight)
        rk_emit_ray(ctx, rk_offset_origin(s->p, -s->ng), normalize(tdir), wt, 2u);
    const float3 wr = w * refl;
    if (rk_max3(wr) > ctx->set.min_weight) {
        float3 rdir = d - s->ns * (2.0f * dot(d, s->ns));
        if (!(dot(rdir, s->ng) > 0.0f)) rdir = d - s->ng * (2.0f * dot(d, s->ng));
        rk_emit_ray(ctx, rk_offset_origin(s->p, s->ng), rdir, wr, 1u);
    }
}
)CLC";

}  // namespace raykit::kernels
