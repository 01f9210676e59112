// raykit/render/ray_hook.hpp — ray hooks on the CPU: the twin of the device's ray-hook API
// (kernels/raykit/kernels/shade.hpp), so one hook type renders on both sides.
//
//   struct FogHook {                                   // examples/fog_hook.hpp
//       static constexpr const char* name = "fog";
//       struct Params { float density, r, g, b; };
//       static constexpr unsigned max_rays = 0, max_shadow_rays = kPerLight;
//       static constexpr const char* source = R"(...OpenCL C: void fog(rk_ctx*, ...)...)";   // device
//       static void shade(RayHookContext& ctx, const PathRay& path, const Hit& hit,
//                         const SurfacePoint& s, const Params& p);                             // CPU
//   };
//   Image cpu = render_hook_cpu<FogHook>(rs.view(), cam, set, {0.05f, 0.6f, 0.7f, 0.8f});
//   Image dev = device_renderer.render_hook<FogHook>(cam, set, params);                         // cl/render.hpp
//
// The CPU driver follows the device's rules one sample at a time: the camera ray (placed as
// PixelSampler places it) is traced, the hook shades it (hit or miss: hit.prim ==
// kInvalidIndex on a miss, and `s` is then all zero with no material); what it emits is traced
// too — shadow rays (any hit on [0, tmax]; their colour is added when nothing blocks them) at
// once, continuation rays (closest hit, depth + 1) depth first — until nothing is left. A
// continuation ray carries the sample's generator as it was when the ray was emitted (the
// device stores that state in the ray). Budgets as on the device: at most H::max_rays
// continuation rays and H::max_shadow_rays (kPerLight: one per light; kPerAoSample:
// ShadeSettings::ao_samples) shadow rays per shaded ray; emit_* return false past them, and
// emit_ray also at depth >= max_depth. Colours from one sample are added in a different order
// than the device's atomics add them: images agree to the last bits.
//
// The API (methods of RayHookContext), each the twin of the rk_ function named:
//   add_color(c)        rk_add_color       set_alpha(a)        rk_set_alpha (camera rays only)
//   random()            rk_random          traversal_steps()   rk_traversal_steps (H::traversal_steps)
//   emit_shadow(o, d, tmax, c)  rk_emit_shadow      emit_ray(o, d, weight, kind)  rk_emit_ray
//   lights()            rk_light_count / rk_get_light      settings()  ctx->set (ShadeSettings)
//   texture(material)->sample(uv, settings().filter)       rk_texture_sample of a material's map_Kd
//   offset_ray_origin(p, n) (math/offset.hpp)               rk_offset_origin
#pragma once

#include <cstdint>
#include <span>
#include <type_traits>
#include <vector>

#include "raykit/math/offset.hpp"
#include "raykit/render/shade.hpp"

namespace raykit {

/// max_shadow_rays value meaning "one per light of the scene".
inline constexpr unsigned kPerLight = 0xFFFFFFFFu;
/// max_shadow_rays value meaning "ShadeSettings::ao_samples".
inline constexpr unsigned kPerAoSample = 0xFFFFFFFEu;

/// A ray as a hook sees it (the twin of rk_path_ray).
struct PathRay {
    Ray ray;
    vec3 weight{1.0f};       ///< the path's throughput
    std::uint32_t pixel = 0; ///< y · width + x
    std::uint32_t depth = 0; ///< bounce: 0 = camera ray
    std::uint32_t kind = 0;  ///< what the emitter said (0 = camera ray)
};

/// A ray hook with a CPU twin: H::shade(ctx, path, hit, surface, params).
template <class H>
concept CpuRayHook = std::is_trivially_copyable_v<typename H::Params> &&
                     requires(class RayHookContext& ctx, const PathRay& path, const Hit& hit, const SurfacePoint& s,
                              const typename H::Params& p) {
                         { H::max_rays } -> std::convertible_to<unsigned>;
                         { H::max_shadow_rays } -> std::convertible_to<unsigned>;
                         H::shade(ctx, path, hit, s, p);
                     };

/// What a CPU hook may call while it shades one ray (see the header comment).
class RayHookContext {
public:
    void add_color(const vec3& c) noexcept { color_ += c; }
    void set_alpha(float a) noexcept {
        if (path_->depth == 0) alpha_ = a;
    }
    float random() noexcept { return rng_.next_float(); }
    unsigned traversal_steps() const noexcept { return steps_; }
    std::span<const Light> lights() const noexcept { return scene_->lights; }
    const ShadeSettings& settings() const noexcept { return *set_; }
    /// Any hit of (org, dir) on [0, tmax]: adds c when nothing blocks it. False past the budget.
    bool emit_shadow(const vec3& org, const vec3& dir, float tmax, const vec3& c) {
        if (shadows_left_ == 0) return false;
        --shadows_left_;
        ++counters_->rays.shadow;
        ++counters_->bounce_rays[bounce_slot(path_->depth)];
        const Ray r{org, 0.0f, dir, tmax};
        const bool blocked = scene_->alpha_testing
                                 ? detail::Tracer<SceneTrees::blocks, true>{*scene_, set_->filter}.any(r)
                                 : detail::Tracer<SceneTrees::blocks, false>{*scene_, set_->filter}.any(r);
        if (!blocked) color_ += c;
        return true;
    }
    /// Closest-hit continuation at depth + 1 with throughput `weight`; false (nothing emitted)
    /// at max_depth or past the budget.
    bool emit_ray(const vec3& org, const vec3& dir, const vec3& weight, std::uint32_t kind) {
        if (path_->depth >= set_->max_depth || rays_left_ == 0) return false;
        --rays_left_;
        PathRay next{Ray{org, 0.0f, dir, kInf}, weight, path_->pixel, path_->depth + 1, kind};
        pending_->push_back({next, rng_.state});
        return true;
    }

    /// A continuation ray waiting to be traced, with its generator's state.
    struct Pending {
        PathRay path;
        std::uint64_t rng;
    };

private:
    template <class H>
    friend SampleResult shade_hook(const ShadeScene&, const ShadeSettings&, const Ray&, SampleRng&, std::uint32_t,
                                   const typename H::Params&, ShadeCounters&, std::vector<Pending>&);
    const ShadeScene* scene_ = nullptr;
    const ShadeSettings* set_ = nullptr;
    const PathRay* path_ = nullptr;
    ShadeCounters* counters_ = nullptr;
    std::vector<Pending>* pending_ = nullptr;
    SampleRng rng_;
    vec3 color_{0.0f};
    float alpha_ = 0.0f;
    unsigned steps_ = 0, rays_left_ = 0, shadows_left_ = 0;
};

/// Shades one camera ray with hook H (see the header comment): the CPU twin of one sample of
/// the device's render_hook<H>. `rng` is the sample's generator after the camera's jitter;
/// `pending` is reusable scratch (one per thread).
template <class H>
SampleResult shade_hook(const ShadeScene& scene, const ShadeSettings& set, const Ray& camera_ray, SampleRng& rng,
                        std::uint32_t pixel, const typename H::Params& params, ShadeCounters& cnt,
                        std::vector<RayHookContext::Pending>& pending) {
    static_assert(CpuRayHook<H>, "a CPU ray hook needs Params, max_rays, max_shadow_rays and a static shade()");
    constexpr bool kSteps = requires { requires H::traversal_steps; };
    pending.clear();
    RayHookContext ctx;
    ctx.scene_ = &scene;
    ctx.set_ = &set;
    ctx.counters_ = &cnt;
    ctx.pending_ = &pending;
    const bool alpha = scene.alpha_testing;
    pending.push_back({PathRay{camera_ray, vec3(1.0f), pixel, 0, 0}, rng.state});
    ++cnt.rays.primary;
    ++cnt.bounce_rays[0];
    const unsigned per_hit_shadows = H::max_shadow_rays == kPerLight      ? unsigned(scene.lights.size())
                                     : H::max_shadow_rays == kPerAoSample ? set.ao_samples
                                                                          : unsigned(H::max_shadow_rays);
    while (!pending.empty()) {
        const RayHookContext::Pending item = pending.back();
        pending.pop_back();
        const PathRay& path = item.path;
        if (path.depth > 0) {
            if (path.kind == 1) ++cnt.rays.reflection;
            else ++cnt.rays.refraction;
            ++cnt.bounce_rays[bounce_slot(path.depth)];
        }
        cnt.deepest = std::max(cnt.deepest, path.depth);
        TraversalStats st;
        Hit h;
        if (alpha) {
            const detail::Tracer<SceneTrees::blocks, true> tr{scene, set.filter};
            h = kSteps ? tr.closest(path.ray, &st) : tr.closest(path.ray);
        } else {
            const detail::Tracer<SceneTrees::blocks, false> tr{scene, set.filter};
            h = kSteps ? tr.closest(path.ray, &st) : tr.closest(path.ray);
        }
        SurfacePoint s;
        if (h.valid()) s = surface_point(scene, h, glm::normalize(path.ray.dir), set.filter);
        ctx.path_ = &path;
        ctx.rng_ = SampleRng(0);
        ctx.rng_.state = item.rng;
        ctx.steps_ = st.nodes + st.leaves;
        ctx.rays_left_ = H::max_rays;
        ctx.shadows_left_ = per_hit_shadows;
        H::shade(ctx, path, h, s, params);
        if (path.depth == 0) rng = ctx.rng_;  // the sample's generator goes on from the camera ray's
    }
    SampleResult res;
    res.color = ctx.color_;
    res.alpha = ctx.alpha_;
    return res;
}

}  // namespace raykit
