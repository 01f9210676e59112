// raykit/kernels/shaders/ao.hpp — the built-in ray hook ShaderKind::ao: ambient occlusion from
// the sample's random numbers, as on the CPU.
// Its C++ type is in include/raykit/cl/render.hpp; the ray-hook API it calls is the core's,
// kernels/raykit/kernels/shade.hpp. One header per shader: a program holds only the hooks it
// renders with.
#pragma once

namespace raykit::kernels {

inline constexpr const char* kShadeAo = R"CLC(typedef struct {
    float pad;
} rk_ao_params;

/* raykit::detail::basis: an orthonormal basis (t, b) around unit n (Duff et al. 2017). */
RK_INLINE void rk_basis(float3 n, float3* t, float3* b) {
    const float sign = copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float bb = n.x * n.y * a;
    *t = (float3)(1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    *b = (float3)(bb, sign + n.y * n.y * a, -n.y);
}

/* Ambient occlusion, the twin of the CPU's ShaderKind::ao (render/shade.hpp): ao_samples
   cosine-weighted any-hit rays within ao_radius from the first hit, drawn from the sample's
   generator in the CPU's order; each unblocked one adds 1 / ao_samples. */
void rk_ao(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, rk_ao_params p) {
    if (hit->prim == RK_INVALID) {
        rk_add_color(ctx, rk_f3(ctx->set.background));
        return;
    }
    rk_set_alpha(ctx, 1.0f);
    const uint n = ctx->set.ao_samples;
    if (n == 0u) {
        rk_add_color(ctx, (float3)(1.0f));
        return;
    }
    const float3 org = rk_offset_origin(s->p, s->ng);
    float3 tb, bb;
    rk_basis(s->ns, &tb, &bb);
    const float w = 1.0f / (float)n;
    for (uint i = 0; i < n; ++i) {
        const float u1 = rk_random(ctx), u2 = rk_random(ctx);
        const float r = sqrt(u1), phi = 6.28318530717958647692f * u2;
        const float3 dir = tb * (r * cos(phi)) + bb * (r * sin(phi)) + s->ns * sqrt(1.0f - u1);
        if (!(dot(dir, s->ng) > 0.0f)) continue;
        rk_emit_shadow(ctx, org, dir, ctx->set.ao_radius, (float3)(w));
    }
}
)CLC";

}  // namespace raykit::kernels
