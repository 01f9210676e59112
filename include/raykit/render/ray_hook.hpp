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
// The CPU driver (shade_hook, the only per-sample shading loop of the CPU: the built-in shaders
// of render/shaders.hpp are hooks too) follows the device's rules one sample at a time: the
// camera ray (placed as PixelSampler places it) is traced by the renderer, a chunk of camera
// rays at a time (trace_camera_ray), the hook shades it (hit or miss: hit.prim ==
// kInvalidIndex on a miss, and `s` is then all zero with no material); what it emits is traced
// too — shadow rays (any hit on [0, tmax]; their colour is added when nothing blocks them;
// recorded and traced as one batch after the sample, or after a chunk of samples in the
// renderer: DeferredShadows), continuation rays (closest hit, depth + 1) depth first — until
// nothing is left. A
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

#include <algorithm>
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

/// A camera ray with its closest hit, traced by the renderer before shading (so camera rays
/// can be traced as batches) — what shade_hook starts a sample from.
struct CameraSample {
    Ray ray;
    Hit hit;                 ///< closest hit of `ray` (alpha cut-outs skipped)
    unsigned steps = 0;      ///< inner nodes + leaves its traversal visited (hooks with traversal_steps)
    std::uint32_t pixel = 0; ///< y · width + x
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

/// True when hook H reads traversal_steps() (H::traversal_steps is true).
template <class H>
constexpr bool hook_counts_steps() noexcept {
    if constexpr (requires { H::traversal_steps; }) return bool(H::traversal_steps);
    else return false;
}

namespace detail {

/// One shading query of the hooks' driver over the scene's trees, alpha cut-outs filtered
/// when kAlpha, timed into `ticks` and `bounce_ticks` when `timed` (ShadeCounters::time_stages).
template <SceneTrees kTrees, bool kAlpha>
struct HookTracer {
    RAYKIT_INLINE static Hit closest(const ShadeScene& s, TextureFilter f, const Ray& r, TraversalStats* st) {
        const Tracer<kTrees, kAlpha> tr{s, f};
        return st ? tr.closest(r, st) : tr.closest(r);
    }
    /// Any hits of a batch (packets where the scene's trees allow).
    static void any_batch(const ShadeScene& s, TextureFilter f, std::span<const Ray> rays, std::span<std::uint8_t> blocked) {
        Tracer<kTrees, kAlpha>{s, f}.any_batch(rays, blocked);
    }
    /// Closest hits of a batch (the scene's packets where its trees allow).
    static void closest_batch(const ShadeScene& s, TextureFilter f, std::span<const Ray> rays, std::span<Hit> hits) {
        Tracer<kTrees, kAlpha>{s, f}.closest_batch(rays, hits);
    }
};

/// Calls f(HookTracer<trees, alpha>{}) for the trees and alpha testing of `s`: the queries are
/// chosen once per frame or sample and inlined below that, not chosen per ray.
template <class F>
decltype(auto) visit_queries(const ShadeScene& s, F&& f) {
    const bool blocks = s.trees == SceneTrees::blocks;
    if (blocks && s.alpha_testing) return f(HookTracer<SceneTrees::blocks, true>{});
    if (blocks) return f(HookTracer<SceneTrees::blocks, false>{});
    if (s.alpha_testing) return f(HookTracer<SceneTrees::binary, true>{});
    return f(HookTracer<SceneTrees::binary, false>{});
}

}  // namespace detail

/// A continuation ray waiting to be traced, with its generator's state.
struct PendingRay {
    PathRay path;
    std::uint64_t rng;
};

/// Shadow rays emitted while a chunk of samples is shaded, traced afterwards as one batch
/// (packets: a tile's shadow rays toward one light are neighbours), and every colour the
/// samples added, in order, each either unconditional or waiting on one shadow ray. A sample's
/// colour is then summed in the order it was added. Every CPU shading goes this way (the
/// renderer defers a chunk's samples, shade_hook one sample's), so the two give the same bits.
/// (Against adding at once: a compiler that fuses multiply-adds can no longer fuse a hook's
/// `w * x` into the running sum, so colours moved in the last bit: 10,026 of 76,800 pixels by
/// at most 6e-8 on the thesis scene at 320 x 240, Whitted, 2 spp.)
struct DeferredShadows {
    struct Add {
        vec3 c;
        std::uint32_t shadow;  ///< index into rays, or kInvalidIndex: added unconditionally
    };
    std::vector<Ray> rays;
    std::vector<std::uint8_t> blocked;  ///< per ray, filled by the batch trace
    std::vector<Add> adds;

    void clear() noexcept {
        rays.clear();
        adds.clear();
    }
    /// The colour of adds [first, last) once `blocked` holds the trace's answers.
    vec3 color(std::size_t first, std::size_t last) const noexcept {
        vec3 c(0.0f);
        for (std::size_t i = first; i < last; ++i)
            if (adds[i].shadow == kInvalidIndex || !blocked[adds[i].shadow]) c += adds[i].c;
        return c;
    }
};

/// Reusable work space of the hooks' driver (one per thread): the pending continuation rays
/// of a sample and the deferred shadow rays and colours of the samples shaded since the last
/// trace of them.
struct PathScratch {
    std::vector<PendingRay> pending;
    DeferredShadows shadows;
};

namespace detail {
template <class H, class Q>
SampleResult shade_sample(const ShadeScene&, const ShadeSettings&, const CameraSample&, SampleRng&,
                          const typename H::Params&, ShadeCounters&, std::vector<PendingRay>&, DeferredShadows&);
}  // namespace detail

/// What a CPU hook may call while it shades one ray (see the header comment).
class RayHookContext {
public:
    RAYKIT_INLINE void add_color(const vec3& c) { shadows_->adds.push_back({c, kInvalidIndex}); }
    void set_alpha(float a) noexcept {
        if (path_->depth == 0) alpha_ = a;
    }
    float random() noexcept { return rng_.next_float(); }
    unsigned traversal_steps() const noexcept { return steps_; }
    std::span<const Light> lights() const noexcept { return scene_->lights; }
    /// The frame's settings, depth_far and ao_radius resolved (resolve_shade_settings).
    const ShadeSettings& settings() const noexcept { return *set_; }
    /// Any hit of (org, dir) on [0, tmax]: adds c when nothing blocks it. False past the budget.
    RAYKIT_INLINE bool emit_shadow(const vec3& org, const vec3& dir, float tmax, const vec3& c) {
        if (shadows_left_ == 0) return false;
        --shadows_left_;
        ++counters_->rays.shadow;
        const unsigned slot = bounce_slot(path_->depth);
        ++counters_->bounce_rays[slot];
        // traced later with the other deferred shadow rays; the colour waits on it
        shadows_->adds.push_back({c, static_cast<std::uint32_t>(shadows_->rays.size())});
        // written field by field in place: a Ray built on the stack was copied with one 32-byte
        // load that waited on its four smaller stores (a failed store forward, 20 % of the
        // Whitted shader's time in perf)
        Ray& r = shadows_->rays.emplace_back();
        r.org = org;
        r.tmin = 0.0f;
        r.dir = dir;
        r.tmax = tmax;
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

private:
    template <class H, class Q>
    friend SampleResult detail::shade_sample(const ShadeScene&, const ShadeSettings&, const CameraSample&, SampleRng&,
                                             const typename H::Params&, ShadeCounters&, std::vector<PendingRay>&,
                                             DeferredShadows&);
    const ShadeScene* scene_ = nullptr;
    const ShadeSettings* set_ = nullptr;
    const PathRay* path_ = nullptr;
    ShadeCounters* counters_ = nullptr;
    std::vector<PendingRay>* pending_ = nullptr;
    DeferredShadows* shadows_ = nullptr;  ///< where colours and shadow rays are recorded
    SampleRng rng_;
    float alpha_ = 0.0f;
    unsigned steps_ = 0, rays_left_ = 0, shadows_left_ = 0;
};

namespace detail {

/// shade_hook's body with the scene queries Q (a HookTracer) fixed: shadow rays and colours
/// are recorded in `shadows` (the result's colour is zero) for the caller to trace as a batch
/// (trace_shadows) and sum (DeferredShadows::color).
template <class H, class Q>
SampleResult shade_sample(const ShadeScene& scene, const ShadeSettings& set, const CameraSample& camera, SampleRng& rng,
                          const typename H::Params& params, ShadeCounters& cnt, std::vector<PendingRay>& pending,
                          DeferredShadows& shadows) {
    static_assert(CpuRayHook<H>, "a CPU ray hook needs Params, max_rays, max_shadow_rays and a static shade()");
    pending.clear();
    RayHookContext ctx;
    ctx.scene_ = &scene;
    ctx.set_ = &set;
    ctx.counters_ = &cnt;
    ctx.pending_ = &pending;
    ctx.shadows_ = &shadows;
    const unsigned per_hit_shadows = H::max_shadow_rays == kPerLight      ? unsigned(scene.lights.size())
                                     : H::max_shadow_rays == kPerAoSample ? set.ao_samples
                                                                          : unsigned(H::max_shadow_rays);
    // one shading call site, first for the camera ray (traced by the caller), then for each
    // continuation ray popped from `pending` and traced here, depth first
    const PathRay camera_path{camera.ray, vec3(1.0f), camera.pixel, 0, 0};
    if constexpr (hook_counts_steps<H>()) cnt.traversal_steps += camera.steps;
    PendingRay item;
    const PathRay* path = &camera_path;
    Hit h = camera.hit;
    unsigned steps = camera.steps;
    ctx.rng_.state = rng.state;
    for (;;) {
        SurfacePoint s;
        if (h.valid()) s = surface_point(scene, h, glm::normalize(path->ray.dir), set.filter);
        ctx.path_ = path;
        ctx.steps_ = steps;
        ctx.rays_left_ = H::max_rays;
        ctx.shadows_left_ = per_hit_shadows;
        H::shade(ctx, *path, h, s, params);
        if (path == &camera_path) rng = ctx.rng_;  // the sample's generator goes on from the camera ray's
        if (pending.empty()) break;
        item = pending.back();
        pending.pop_back();
        path = &item.path;
        if (path->kind == 1) ++cnt.rays.reflection;
        else ++cnt.rays.refraction;
        const unsigned slot = bounce_slot(path->depth);
        ++cnt.bounce_rays[slot];
        cnt.deepest = std::max(cnt.deepest, path->depth);
        TraversalStats st;
        h = timed(cnt.time_stages, cnt.times.trace_ticks, cnt.times.bounce_ticks[slot], [&] {
            return Q::closest(scene, set.filter, path->ray, hook_counts_steps<H>() ? &st : nullptr);
        });
        steps = st.nodes + st.leaves;
        ctx.rng_.state = item.rng;
    }
    SampleResult res;
    res.alpha = ctx.alpha_;
    if constexpr (hook_counts_steps<H>()) res.cost = float(camera.steps);
    return res;
}

/// Traces the deferred shadow rays of `shadows` as one batch into shadows.blocked (timed into
/// cnt's shadow stage when cnt.time_stages).
template <class Q>
void trace_shadows(const ShadeScene& scene, TextureFilter filter, DeferredShadows& shadows, ShadeCounters& cnt) {
    shadows.blocked.resize(shadows.rays.size());
    if (shadows.rays.empty()) return;
    timed(cnt.time_stages, cnt.times.shadow_ticks, cnt.times.bounce_ticks[0], [&] {
        Q::any_batch(scene, filter, shadows.rays, shadows.blocked);
        return 0;
    });
}

/// trace_camera_ray with the scene queries Q fixed, into `c` (traced from `ray`, not from the
/// copy just stored in c.ray: loading a ray right after storing it stalls the setup's vector loads).
template <class Q>
RAYKIT_INLINE void trace_camera(const ShadeScene& scene, TextureFilter filter, const Ray& ray, std::uint32_t pixel,
                                bool steps, ShadeCounters& cnt, CameraSample& c) {
    TraversalStats st;
    c.hit = timed(cnt.time_stages, cnt.times.trace_ticks, cnt.times.bounce_ticks[0],
                  [&] { return Q::closest(scene, filter, ray, steps ? &st : nullptr); });
    c.ray = ray;
    c.pixel = pixel;
    c.steps = st.nodes + st.leaves;
    ++cnt.rays.primary;
    ++cnt.bounce_rays[0];
}

}  // namespace detail

/// Shades one sample with hook H from its traced camera ray (see the header comment): the CPU
/// twin of one sample of the device's render_hook<H>. `set` as resolve_shade_settings gives
/// it; `rng` is the sample's generator after the camera's jitter; `pending` is reusable
/// scratch (one per thread). Counts the continuation and shadow rays it traces (the camera
/// ray is counted by whoever traced it).
template <class H>
SampleResult shade_hook(const ShadeScene& scene, const ShadeSettings& set, const CameraSample& camera, SampleRng& rng,
                        const typename H::Params& params, ShadeCounters& cnt, PathScratch& scratch) {
    return detail::visit_queries(scene, [&]<class Q>(Q) {
        scratch.shadows.clear();
        SampleResult r = detail::shade_sample<H, Q>(scene, set, camera, rng, params, cnt, scratch.pending, scratch.shadows);
        detail::trace_shadows<Q>(scene, set.filter, scratch.shadows, cnt);
        r.color = scratch.shadows.color(0, scratch.shadows.adds.size());
        return r;
    });
}

/// The camera sample of `ray` through pixel `pixel`: its closest hit in `scene` (with its
/// traversal steps when `steps`), counted as a primary ray in `cnt` (and timed when
/// cnt.time_stages). The renderers trace camera rays with this before shade_hook.
inline CameraSample trace_camera_ray(const ShadeScene& scene, TextureFilter filter, const Ray& ray,
                                     std::uint32_t pixel, bool steps, ShadeCounters& cnt) {
    CameraSample c;
    detail::visit_queries(scene, [&]<class Q>(Q) { detail::trace_camera<Q>(scene, filter, ray, pixel, steps, cnt, c); });
    return c;
}

}  // namespace raykit
