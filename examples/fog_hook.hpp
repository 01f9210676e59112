// examples/fog_hook.hpp — a user-written ray hook that renders on the CPU and on the device:
// diffuse shading with shadow rays, seen through exponential fog.
//
//   RenderSettings set;  set.shade.ambient = vec3(0.1f);
//   const FogHook::Params fog{0.04f, 0.7f, 0.75f, 0.8f};            // density, fog colour
//   Image cpu = raykit::render_hook_cpu<FogHook>(rs.view(), cam, set, fog);           // CPU
//   Image dev = device_renderer.render_hook<FogHook>(cam, set, fog);                   // OpenCL
//
// One type carries both sides: `source` is the OpenCL C the device renderer compiles into its
// program (the rk_ API of kernels/raykit/kernels/shade.hpp), `shade` its C++ twin on the API
// of render/ray_hook.hpp, line for line. At a hit at distance t·|dir| the fog takes the
// fraction f = 1 - exp(-density · distance); the surface keeps 1 - f of its ambient and
// (shadowed) Lambert light, and the fog adds f of its colour. Rays that miss see the fog.
// With density 0 this is Whitted shading without bounces or specular (tested).
#pragma once

#include <cmath>

#include "raykit/render/ray_hook.hpp"

struct FogHook {
    static constexpr const char* name = "fog";
    struct Params {
        float density = 0.05f;  ///< per unit distance
        float r = 0.7f, g = 0.75f, b = 0.8f;  ///< fog colour (linear)
    };
    static constexpr unsigned max_rays = 0;                      ///< no continuation rays
    static constexpr unsigned max_shadow_rays = raykit::kPerLight;  ///< one shadow ray per light
    static constexpr const char* source = R"CLC(typedef struct {
    float density, r, g, b;
} fog_params;

void fog(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, fog_params p) {
    const float3 fog_color = (float3)(p.r, p.g, p.b);
    const float3 w = rk_f3(path->weight);
    if (hit->prim == RK_INVALID) {
        rk_add_color(ctx, w * fog_color);
        return;
    }
    rk_set_alpha(ctx, 1.0f);
    const float dist = hit->t * length(rk_f3(path->ray.dir));
    const float f = 1.0f - exp(-p.density * dist);
    const float keep = 1.0f - f;
    rk_add_color(ctx, w * (keep * (rk_f3(ctx->set.ambient) * s->base) + f * fog_color));
    const float3 org = rk_offset_origin(s->p, s->ng);
    for (uint i = 0; i < rk_light_count(ctx); ++i) {
        const rk_light l = rk_get_light(ctx, i);
        float3 ldir;
        float tmax;
        if (!rk_light_ray(l, org, &ldir, &tmax)) continue;
        const float nl = dot(s->ns, ldir);
        if (!(nl > 0.0f) || !(dot(s->ng, ldir) > 0.0f)) continue;
        const float3 c = w * (keep * nl) * s->base * rk_f3(l.color);
        if (ctx->set.shadows) rk_emit_shadow(ctx, org, ldir, tmax, c);
        else rk_add_color(ctx, c);
    }
}
)CLC";

    /// The CPU twin of `source`.
    static void shade(raykit::RayHookContext& ctx, const raykit::PathRay& path, const raykit::Hit& hit,
                      const raykit::SurfacePoint& s, const Params& p) {
        using raykit::vec3;
        const vec3 fog_color(p.r, p.g, p.b);
        const vec3 w = path.weight;
        if (!hit.valid()) {
            ctx.add_color(w * fog_color);
            return;
        }
        ctx.set_alpha(1.0f);
        const float dist = hit.t * glm::length(path.ray.dir);
        const float f = 1.0f - std::exp(-p.density * dist);
        const float keep = 1.0f - f;
        ctx.add_color(w * (keep * (ctx.settings().ambient * s.base) + f * fog_color));
        const vec3 org = raykit::offset_ray_origin(s.p, s.ng);
        for (const raykit::Light& l : ctx.lights()) {
            vec3 ldir;
            float tmax;
            if (!raykit::light_ray(l, org, ldir, tmax)) continue;
            const float nl = glm::dot(s.ns, ldir);
            if (!(nl > 0.0f) || !(glm::dot(s.ng, ldir) > 0.0f)) continue;
            const vec3 c = w * (keep * nl) * s.base * l.color;
            if (ctx.settings().shadows) ctx.emit_shadow(org, ldir, tmax, c);
            else ctx.add_color(c);
        }
    }
};
