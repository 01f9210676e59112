// raykit/render/shaders.hpp — the built-in shaders as ray hooks (render/ray_hook.hpp): what one
// camera ray sees, shaded by the one per-sample driver, shade_hook.
//
// Each type here is the CPU twin of a device hook: cl/render.hpp derives NormalsRayHook,
// DepthRayHook, WhittedRayHook, AoRayHook and DebugCostRayHook from them, adding only their
// OpenCL source (kernels/raykit/kernels/shaders/*.hpp, the same arithmetic line for line) and
// name. A ShaderKind picks one with visit_shader.
//
// Shaders (ShaderKind, names for parse_shader in brackets)
// --------------------------------------------------------
//  whitted ("whitted")   Whitted-style ray tracing. At each hit:
//      colour = Ke + (1 - transparency) · (ambient · base + Σ_lights visible · base · max(0, N·L) · Lc)
//                  + Σ_lights visible · F(L·H) · (Ns + 8) / 8 · max(0, N·H)^Ns · max(0, N·L) · Lc
//      base = Kd · map_Kd(uv) (linear), N the shading normal, H = normalize(L + V) (Blinn-Phong),
//      F(x) = Ks + (1 - Ks)(1 - x)^5 (Schlick's Fresnel, Ks as the reflectance at normal
//      incidence). The lobe is the energy-normalised Blinn-Phong one, (Ns + 8) / (8π) ·
//      (N·H)^Ns, in the units of the diffuse term (base · N·L · Lc is Lambert's base / π times
//      π · Lc), so a material reflects about Ks of the light whatever its Ns, and more at grazing
//      angles; the unnormalised Ks · (N·H)^Ns used before had no N·L and no Fresnel term
//      (docs/whitted_specular.png compares them). Materials with Ks = 0 have no specular.
//      "visible" = a shadow ray (any-hit) from the offset hit point to the light is unblocked
//      (ShadeSettings::shadows). Lights have no distance falloff. The ambient term uses the
//      diffuse colour (MTL Ka is ignored: exporters routinely write Ka 1 1 1). Then, while the
//      path is shorter than max_depth bounces, it spawns
//        - a mirror ray weighted by Ks for illum 3, 5, 7 (Schlick-Fresnel weighted for 5, 7), and
//        - for transparent materials (see material.hpp) a refracted ray with weight
//          transparency · (1 - F) and a reflected ray with weight transparency · F, F the exact
//          dielectric Fresnel reflectance for index Ni (1 on total internal reflection).
//      Child rays whose weight drops below min_weight (all channels) are not traced. Shadow rays
//      treat every surface as opaque except alpha cut-outs.
//  normals ("normals")   0.5 · N + 0.5 of the shading normal at the first hit.
//  depth ("depth")       1 - distance / far at the first hit (far: ShadeSettings::depth_far, or the
//                        distance from the camera to the farthest corner of the scene bounds).
//  ao ("ao")             ambient occlusion: of ao_samples cosine-weighted rays from the first hit,
//                        each that escapes within ao_radius (default 0.1 · scene diagonal) adds
//                        1 / ao_samples. Ray i takes the next two numbers u1, u2 of the sample's
//                        generator (after the camera's jitter, see PixelSampler in
//                        render_cpu.hpp): dir = T·(√u1 cos φ) + B·(√u1 sin φ) + N·√(1 - u1),
//                        φ = 2π·u2, (T, B) = basis(N) around the shading normal N; a dir not above
//                        the geometric surface counts as occluded and is not traced. Origin offset
//                        along the geometric normal, tmin 0, tmax ao_radius.
//  debug_cost ("debug-cost")  the inner nodes + leaves visited by the camera ray's traversal
//                        (TraversalStats of bvh/traverse.hpp: the root counts when its box is hit,
//                        alpha cut-outs are skipped inside the walk) as a grey level, to be mapped
//                        by the caller (render_cpu maps it with cost_heat_map).
// Misses give ShadeSettings::background (and alpha 0 for a camera ray).
#pragma once

#include <cmath>
#include <stdexcept>

#include "raykit/render/ray_hook.hpp"

namespace raykit {

/// 0.5 · N + 0.5 at the first hit (ShaderKind::normals).
struct NormalsShader {
    struct Params {
        float pad = 0.0f;
    };
    static constexpr unsigned max_rays = 0;
    static constexpr unsigned max_shadow_rays = 0;
    static void shade(RayHookContext& ctx, const PathRay&, const Hit& hit, const SurfacePoint& s, const Params&) {
        if (!hit.valid()) return ctx.add_color(ctx.settings().background);
        ctx.set_alpha(1.0f);
        ctx.add_color(s.ns * 0.5f + vec3(0.5f));
    }
};

/// 1 - distance / far at the first hit (ShaderKind::depth).
struct DepthShader {
    struct Params {
        float pad = 0.0f;
    };
    static constexpr unsigned max_rays = 0;
    static constexpr unsigned max_shadow_rays = 0;
    static void shade(RayHookContext& ctx, const PathRay& path, const Hit& hit, const SurfacePoint&, const Params&) {
        if (!hit.valid()) return ctx.add_color(ctx.settings().background);
        ctx.set_alpha(1.0f);
        const float far = ctx.settings().depth_far;
        const float dist = hit.t * glm::length(path.ray.dir);
        ctx.add_color(vec3(far > 0.0f ? std::clamp(1.0f - dist / far, 0.0f, 1.0f) : 0.0f));
    }
};

/// Whitted ray tracing (ShaderKind::whitted): Blinn-Phong, ambient, shadow rays, mirror
/// reflection, refraction, emission.
struct WhittedShader {
    struct Params {
        float pad = 0.0f;
    };
    static constexpr unsigned max_rays = 2;
    static constexpr unsigned max_shadow_rays = kPerLight;
    static void shade(RayHookContext& ctx, const PathRay& path, const Hit& hit, const SurfacePoint& s, const Params&) {
        const ShadeSettings& set = ctx.settings();
        const vec3& w = path.weight;
        if (!hit.valid()) return ctx.add_color(w * set.background);
        ctx.set_alpha(1.0f);
        const RenderMaterial& m = *s.material;
        const float opaque = 1.0f - m.transparency;
        const vec3& d = s.d;
        ctx.add_color(w * (m.ke + opaque * (set.ambient * s.base)));
        if (!ctx.lights().empty()) {
            const vec3 org = offset_ray_origin(s.p, s.ng);
            const bool want_spec = detail::max3(m.ks) > 0.0f;
            for (const Light& l : ctx.lights()) {
                vec3 ldir;
                float tmax;
                if (!light_ray(l, org, ldir, tmax)) continue;
                const float nl = glm::dot(s.ns, ldir);
                if (!(nl > 0.0f) || !(glm::dot(s.ng, ldir) > 0.0f)) continue;
                vec3 c = opaque * (s.base * (nl * l.color));
                if (want_spec) {  // normalised Blinn-Phong, Fresnel-weighted (header comment)
                    const vec3 hv = glm::normalize(ldir - d);
                    const float nh = std::max(0.0f, glm::dot(s.ns, hv));
                    const float lh = std::max(0.0f, glm::dot(ldir, hv));
                    c += detail::schlick(m.ks, lh) * (((m.ns + 8.0f) * 0.125f * std::pow(nh, m.ns) * nl) * l.color);
                }
                c *= w;
                if (set.shadows) ctx.emit_shadow(org, ldir, tmax, c);
                else ctx.add_color(c);
            }
        }
        if (path.depth >= set.max_depth) return;
        const float cos_i = std::max(0.0f, -glm::dot(d, s.ns));
        vec3 refl = m.mirror;
        if (m.fresnel_mirror && detail::max3(refl) > 0.0f) refl = detail::schlick(refl, cos_i);
        float trans = 0.0f;
        vec3 tdir(0.0f);
        if (m.transparency > 0.0f) {
            const float eta = s.entering ? 1.0f / m.ni : m.ni;
            float cos_t = 0.0f;
            const float F = detail::fresnel_dielectric(cos_i, eta, cos_t);
            refl += vec3(m.transparency * F);
            if (F < 1.0f) {
                trans = m.transparency * (1.0f - F);
                tdir = d * eta + s.ns * (eta * cos_i - cos_t);
                if (!(glm::dot(tdir, s.ng) < 0.0f)) {  // the shading normal bent it back: use ng
                    const float ci = std::max(0.0f, -glm::dot(d, s.ng));
                    const float s2 = eta * eta * std::max(0.0f, 1.0f - ci * ci);
                    if (s2 < 1.0f) tdir = d * eta + s.ng * (eta * ci - std::sqrt(1.0f - s2));
                    else trans = 0.0f;
                }
            }
        }
        const vec3 wt = w * trans;
        if (trans > 0.0f && detail::max3(wt) > set.min_weight)
            ctx.emit_ray(offset_ray_origin(s.p, -s.ng), glm::normalize(tdir), wt, 2u);
        const vec3 wr = w * refl;
        if (detail::max3(wr) > set.min_weight) {
            vec3 rdir = d - s.ns * (2.0f * glm::dot(d, s.ns));
            if (!(glm::dot(rdir, s.ng) > 0.0f)) rdir = d - s.ng * (2.0f * glm::dot(d, s.ng));
            ctx.emit_ray(offset_ray_origin(s.p, s.ng), rdir, wr, 1u);
        }
    }
};

/// Ambient occlusion (ShaderKind::ao): ShadeSettings::ao_samples cosine-weighted any-hit rays
/// per camera ray, from the sample's random numbers.
struct AoShader {
    struct Params {
        float pad = 0.0f;
    };
    static constexpr unsigned max_rays = 0;
    static constexpr unsigned max_shadow_rays = kPerAoSample;
    static void shade(RayHookContext& ctx, const PathRay&, const Hit& hit, const SurfacePoint& s, const Params&) {
        const ShadeSettings& set = ctx.settings();
        if (!hit.valid()) return ctx.add_color(set.background);
        ctx.set_alpha(1.0f);
        const unsigned n = set.ao_samples;
        if (n == 0) return ctx.add_color(vec3(1.0f));
        const vec3 org = offset_ray_origin(s.p, s.ng);
        vec3 tb, bb;
        detail::basis(s.ns, tb, bb);
        const float w = 1.0f / float(n);
        for (unsigned i = 0; i < n; ++i) {
            const float u1 = ctx.random(), u2 = ctx.random();
            const float r = std::sqrt(u1), phi = 6.28318530717958647692f * u2;
            const vec3 dir = tb * (r * std::cos(phi)) + bb * (r * std::sin(phi)) + s.ns * std::sqrt(1.0f - u1);
            if (!(glm::dot(dir, s.ng) > 0.0f)) continue;
            ctx.emit_shadow(org, dir, set.ao_radius, vec3(w));
        }
    }
};

/// Traversal steps of the camera ray (ShaderKind::debug_cost), before the heat map.
struct DebugCostShader {
    struct Params {
        float pad = 0.0f;
    };
    static constexpr unsigned max_rays = 0;
    static constexpr unsigned max_shadow_rays = 0;
    static constexpr bool traversal_steps = true;
    static void shade(RayHookContext& ctx, const PathRay&, const Hit& hit, const SurfacePoint&, const Params&) {
        ctx.set_alpha(hit.valid() ? 1.0f : 0.0f);
        ctx.add_color(vec3(float(ctx.traversal_steps())));
    }
};

static_assert(CpuRayHook<NormalsShader> && CpuRayHook<DepthShader> && CpuRayHook<WhittedShader> &&
              CpuRayHook<AoShader> && CpuRayHook<DebugCostShader>);

/// Calls f(Shader{}) with the built-in hook type of `kind` (f's result is returned), so a
/// renderer instantiates one path per shader instead of switching per sample.
template <class F>
decltype(auto) visit_shader(ShaderKind kind, F&& f) {
    switch (kind) {
        case ShaderKind::normals: return f(NormalsShader{});
        case ShaderKind::depth: return f(DepthShader{});
        case ShaderKind::ao: return f(AoShader{});
        case ShaderKind::debug_cost: return f(DebugCostShader{});
        case ShaderKind::whitted: break;
    }
    return f(WhittedShader{});
}

/// Shades one camera ray with the built-in shader settings.shader: traces it, then runs the
/// shader's hook (shade_hook). `scene` from make_shade_scene; reentrant (all mutable state is
/// in the arguments).
inline SampleResult shade_ray(const ShadeScene& scene, const ShadeSettings& settings, const Ray& camera_ray,
                              SampleRng& rng, ShadeCounters& counters, PathScratch& scratch) {
    if (!scene.scene) throw std::invalid_argument("raykit::shade_ray: incomplete ShadeScene (use make_shade_scene)");
    const ShadeSettings set = resolve_shade_settings(settings, scene.bounds, camera_ray.org);
    return visit_shader(settings.shader, [&]<class S>(S) {
        const CameraSample cam =
            trace_camera_ray(scene, set.filter, camera_ray, 0, hook_counts_steps<S>(), counters);
        return shade_hook<S>(scene, set, cam, rng, typename S::Params{}, counters, scratch);
    });
}

}  // namespace raykit
