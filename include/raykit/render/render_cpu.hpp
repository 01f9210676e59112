// raykit/render/render_cpu.hpp — the CPU renderer: camera samples -> their camera rays traced a
// chunk at a time -> a ray hook shades each (render/ray_hook.hpp shade_hook; the built-in shaders
// of render/shaders.hpp or a user's) -> image.
//
//   RenderScene rs = prepare_render_scene(load_obj("scene.obj"));   // owns a Scene, materials, lights
//   Camera cam = frame_scene(rs.bounds(), 640, 480);                 // whole scene in view
//   rs.lights.push_back(default_key_light(cam));
//   RenderSettings set;  set.spp = 4;  set.shade.max_depth = 2;  set.threads = 2;
//   RenderStats stats;
//   Image img = render_cpu(rs.view(), cam, set, &stats);
//
//   Or with parts owned elsewhere: render_cpu(make_shade_scene(scene, materials, lights), cam, set),
//   any raykit::Scene (static and dynamic objects, instances, the top-level tree) with one
//   MaterialTable per object; FrameLoop (render/frame.hpp) moves, refits and renders per frame.
//
// Sampling: `spp` samples per pixel, stratified: a jittered m x m grid when spp = m², otherwise
// N-rooks (one sample per row and per column of an spp x spp grid, columns shuffled per pixel),
// each jittered uniformly inside its cell (RenderSettings::jitter = false puts every sample at
// its cell centre, so spp = 1 samples the pixel centre). The pixel value is the mean of its
// samples (box filter: sum · (1 / spp)); alpha is the fraction of samples whose camera ray hit
// geometry. The exact definition is PixelSampler's (below); the device renderer's camera
// kernel (cl/render.hpp) computes the same sample positions and generator states.
//
// Determinism: every random number of sample s of pixel i comes from a generator seeded with
// hash_seed(seed, i, s), and per-row counters are summed in row order, so the image and the
// ray counts do not depend on the number of threads.
//
// Parallelism: bands of kCameraBand rows are dealt to `threads` workers
// (raykit::parallel_chunks; 0 = all hardware threads). Each worker keeps one PathScratch (a
// growable stack of pending rays) and one chunk of camera samples (kCameraChunk), so memory does
// not grow with spp or depth beyond what one path and one chunk need.
//
// Batches: a chunk's camera rays are made in 4 x 4 pixel tiles and traced as one batch
// (Scene::intersect_closest over a span: packets of kPacketWidth neighbouring rays,
// bvh/traverse_packet.hpp); the chunk is then shaded sample by sample with its shadow rays
// deferred (DeferredShadows, render/ray_hook.hpp) and traced as a second batch, and each
// sample's colours are summed in the order the hook added them. Batches return the single-ray
// answers bit for bit and the sums keep their order, so images are those of ray-by-ray
// tracing. Thesis scene, 640 x 480, 1 spp, one light, 1 thread, CPU time (bench_render, one
// run, medians): 49.8 ms ray by ray, 39.7 ms with camera batches; see the README for both
// batches against Embree. A hook that reads traversal_steps() (debug_cost) traces its camera
// rays one by one, since packets visit nodes for the packet, not the ray.
//
// debug_cost: pixels hold the mean traversal steps; after rendering cost_heat_map maps them to
// a heat-map colour (blue, cyan, green, yellow, red) with `cost_scale` steps (or the frame's
// maximum when 0) at the red end.
//
// Statistics (RenderStats): rays traced per kind, and wall time per stage: setup (camera
// frame), render (all tracing and shading), resolve (heat map). With time_stages the thread
// time of the render stage is further split into trace (closest-hit), shadow (any-hit) and
// shade (everything else, camera rays included), timed with stage_ticks() (the x86 time-stamp
// counter, calibrated against steady_clock over the frame); the reads cost 15-25 % of a frame
// (bench_render, goblin at 1 thread: 91 ms with them, 75 without).
// Rays per bounce (bounce_rays) are always counted; their traversal thread time
// (bounce_thread_ms: closest- and any-hit queries of that bounce) only with time_stages.
#pragma once

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <functional>
#include <mutex>
#include <numeric>
#include <stdexcept>
#include <vector>

#include "raykit/render/image.hpp"
#include "raykit/render/material.hpp"
#include "raykit/render/ray_hook.hpp"
#include "raykit/render/shade.hpp"
#include "raykit/render/shaders.hpp"
#include "raykit/scene/build_options.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct RenderSettings {
    unsigned spp = 1;            ///< samples per pixel (>= 1)
    unsigned threads = 0;        ///< worker threads, 0 = all hardware threads
    std::uint64_t seed = 0;      ///< changes every random number
    bool jitter = true;          ///< false: samples at the centres of their strata
    ShadeSettings shade;         ///< shader, depth, ambient, lights' shadows, ...
    bool time_stages = false;    ///< split render time into trace / shadow / shade (thread time)
    float cost_scale = 0.0f;     ///< debug_cost: steps shown as red; 0 = the frame's maximum
    /// Called after each finished row with (rows done, rows in total), from worker threads but
    /// never concurrently. May be empty.
    std::function<void(std::size_t, std::size_t)> progress;
};

struct RenderStats {
    RayCounts rays;
    std::uint64_t bounce_rays[kBounceSlots] = {};  ///< rays traced per bounce slot (shade.hpp)
    std::uint64_t traversal_steps = 0;  ///< debug_cost: camera-ray traversal steps
    unsigned deepest = 0;               ///< deepest bounce traced
    unsigned threads = 1;               ///< workers used
    double setup_ms = 0.0, render_ms = 0.0, resolve_ms = 0.0, total_ms = 0.0;  ///< wall time
    // time_stages only: thread time summed over all workers
    double trace_thread_ms = 0.0, shadow_thread_ms = 0.0, shade_thread_ms = 0.0;
    double bounce_thread_ms[kBounceSlots] = {};  ///< traversal thread time per bounce slot

    /// Rays traced per second during the render stage, in millions.
    double mrays_per_second() const noexcept {
        return render_ms > 0.0 ? double(rays.total()) / (render_ms * 1e3) : 0.0;
    }
};

namespace detail {

/// Heat-map colour for t in [0, 1] (display values; blue, cyan, green, yellow, red).
inline vec3 heat_color(float t) noexcept {
    static constexpr float stops[5][3] = {{0, 0, 1}, {0, 1, 1}, {0, 1, 0}, {1, 1, 0}, {1, 0, 0}};
    t = std::clamp(std::isfinite(t) ? t : 0.0f, 0.0f, 1.0f) * 4.0f;
    const int i = std::min(3, int(t));
    const float f = t - float(i);
    return vec3(stops[i][0] + (stops[i + 1][0] - stops[i][0]) * f, stops[i][1] + (stops[i + 1][1] - stops[i][1]) * f,
                stops[i][2] + (stops[i + 1][2] - stops[i][2]) * f);
}

}  // namespace detail

/// Maps the debug_cost pixels (mean traversal steps in .x) to heat-map colours in place: `scale`
/// steps (the image's largest value when scale <= 0) are red, 0 is blue; the colours are
/// stored linear (decoded from sRGB), alpha is kept. Used by render_cpu and the device renderer.
inline void cost_heat_map(Image& img, float scale) {
    if (!(scale > 0.0f)) {
        scale = 0.0f;
        for (const vec4& p : img.pixels) scale = std::max(scale, p.x);
    }
    for (vec4& p : img.pixels) {
        const vec3 c = detail::heat_color(scale > 0.0f ? p.x / scale : 0.0f);
        p = vec4(srgb_to_linear(c.x), srgb_to_linear(c.y), srgb_to_linear(c.z), p.w);
    }
}

/// Where the samples of a pixel lie: the one definition of the stratified sampling, shared by
/// render_cpu and the device renderer's camera kernel (rk_dr_camera, kernels/raykit/kernels/
/// shade.hpp), which evaluates the same integer and float operations:
///   m = floor(sqrt(spp)); grid = (m · m == spp); inv_m = 1 / float(m); inv_spp = 1 / float(spp)
///   sample s of pixel i (i = y · width + x) draws from rng = SampleRng(hash_seed(seed, i, s)):
///   r1 = rng.next_float(), r2 = rng.next_float() with jitter, else r1 = r2 = 0.5 and nothing is
///   drawn; the sample's shading (ao) continues with that rng.
///   grid:    (jx, jy) = ((s mod m + r1) · inv_m, (s div m + r2) · inv_m)
///   N-rooks: (jx, jy) = ((s + r1) · inv_spp, (col[s] + r2) · inv_spp), col a permutation of
///            0 .. spp-1 per pixel: col = identity, then for k = spp-1 down to 1:
///            swap(col[k], col[u % (k + 1)]), u the successive next_u64() of
///            SampleRng(hash_seed(seed, i, ~0)).
///   The camera ray is CameraFrame::ray(x, y, jx, jy).
class PixelSampler {
public:
    PixelSampler(unsigned spp, std::uint64_t seed, bool jitter)
        : spp_(spp), m_(static_cast<unsigned>(std::sqrt(double(spp)))), seed_(seed), jitter_(jitter) {
        if (spp == 0) throw std::invalid_argument("raykit::PixelSampler: spp must be at least 1");
        grid_ = m_ * m_ == spp_;
        inv_m_ = 1.0f / float(m_);
        inv_spp_ = 1.0f / float(spp_);
        if (grid_) {
            cell_.resize(spp_);
            for (unsigned s = 0; s < spp_; ++s) cell_[s] = {float(s % m_), float(s / m_)};
        }
    }
    /// Prepares pixel i (the N-rooks column shuffle); call before sample() for that pixel.
    void begin_pixel(std::uint64_t pixel) {
        pixel_ = pixel;
        if (grid_) return;
        perm_.resize(spp_);
        std::iota(perm_.begin(), perm_.end(), 0u);
        SampleRng pr(hash_seed(seed_, pixel, ~std::uint64_t(0)));
        for (unsigned i = spp_ - 1; i > 0; --i) std::swap(perm_[i], perm_[pr.next_u64() % (i + 1)]);
    }
    /// Position (jx, jy) in [0, 1)² of sample s of the current pixel; `rng` receives the sample's
    /// generator, advanced past the jitter.
    vec2 sample(unsigned s, SampleRng& rng) const noexcept {
        rng = SampleRng(hash_seed(seed_, pixel_, s));
        const float r1 = jitter_ ? rng.next_float() : 0.5f;
        const float r2 = jitter_ ? rng.next_float() : 0.5f;
        if (grid_) return vec2((cell_[s].x + r1) * inv_m_, (cell_[s].y + r2) * inv_m_);
        return vec2((float(s) + r1) * inv_spp_, (float(perm_[s]) + r2) * inv_spp_);
    }
    unsigned spp() const noexcept { return spp_; }
    unsigned grid_side() const noexcept { return grid_ ? m_ : 0u; }  ///< m, or 0 for N-rooks
    float inv_grid_side() const noexcept { return inv_m_; }
    float inv_spp() const noexcept { return inv_spp_; }

private:
    unsigned spp_, m_;
    std::uint64_t seed_;
    bool jitter_, grid_ = true;
    float inv_m_ = 1.0f, inv_spp_ = 1.0f;
    std::uint64_t pixel_ = 0;
    std::vector<std::uint32_t> perm_;
    /// Grid: sample s's cell (s mod m, s div m) as floats, made once (the division per camera
    /// sample was 5 % of the renderer's own samples in perf at 1 spp).
    std::vector<vec2> cell_;
};

namespace detail {

/// Camera samples traced and shaded together: a band of kCameraBand rows is cut into chunks of
/// whole columns of at most this many samples (or one column's samples when spp is larger),
/// whose camera rays are traced first, as one batch, and then shaded pixel by pixel.
inline constexpr std::size_t kCameraChunk = 256;
/// Rows dealt to a worker together, so a chunk's samples form tiles of kCameraBand x
/// kCameraBand pixels: the batch's packets (bvh/traverse_packet.hpp) are 16 rays of one
/// 4 x 4 tile at 1 spp.
inline constexpr std::uint32_t kCameraBand = 4;

/// render_cpu's body with hook Hook (`heat_map`: map debug_cost steps to colours at the end).
template <class Hook>
Image render_samples(const ShadeScene& scene, const Camera& cam, const RenderSettings& set,
                     const typename Hook::Params& params, RenderStats* stats, bool heat_map) {
    using Clock = std::chrono::steady_clock;
    auto ms_since = [](Clock::time_point t0) { return std::chrono::duration<double, std::milli>(Clock::now() - t0).count(); };
    if (set.spp == 0) throw std::invalid_argument("raykit::render_cpu: spp must be at least 1");
    if (!scene.scene) throw std::invalid_argument("raykit::render_cpu: incomplete ShadeScene (use make_shade_scene)");
    const auto t_start = Clock::now();

    // ---- setup
    const CameraFrame frame = cam.frame();
    const std::uint32_t W = frame.width, H = frame.height;
    Image img(W, H, vec4(0.0f));
    const unsigned spp = set.spp;
    const std::size_t bands = (std::size_t(H) + kCameraBand - 1) / kCameraBand;
    const unsigned threads = static_cast<unsigned>(std::min<std::size_t>(resolve_threads(set.threads), bands));
    const ShadeSettings shade_set = resolve_shade_settings(set.shade, scene.bounds, frame.origin);
    std::vector<ShadeCounters> row_counters(H);
    std::vector<std::uint64_t> row_ticks(set.time_stages ? H : 0, 0);
    std::atomic<std::size_t> rows_done{0};
    std::mutex progress_mutex;
    const double setup_ms = ms_since(t_start);

    // ---- render
    const auto t_render = Clock::now();
    const std::uint64_t ticks_render = set.time_stages ? stage_ticks() : 0;
    const float inv_spp = 1.0f / float(spp);
    visit_queries(scene, [&]<class Q>(Q) {
    parallel_chunks(bands, bands, threads, [&](std::size_t, std::size_t b0, std::size_t b1) {
        PathScratch scratch;
        PixelSampler sampler(spp, set.seed, set.jitter);
        std::vector<CameraSample> samples;
        std::vector<std::uint32_t> rows;  // samples[k]'s image row (pixel / W without a division)
        std::vector<SampleRng> rngs;
        std::vector<Ray> rays;
        std::vector<Hit> hits;
        std::vector<float> alphas;
        std::vector<std::size_t> adds_end;
        for (std::size_t band = b0; band < b1; ++band) {
            const auto y0 = static_cast<std::uint32_t>(band * kCameraBand);
            const std::uint32_t y1 = std::min(H, y0 + kCameraBand);
            const std::uint64_t t_band = set.time_stages ? stage_ticks() : 0;
            for (std::uint32_t y = y0; y < y1; ++y) row_counters[y].time_stages = set.time_stages;
            const std::size_t column = std::size_t(y1 - y0) * spp;  // samples of one column of the band
            const auto chunk_cols = static_cast<std::uint32_t>(std::max<std::size_t>(1, kCameraChunk / column));
            for (std::uint32_t x0 = 0; x0 < W; x0 += chunk_cols) {
                const std::uint32_t x1 = std::min(W, x0 + chunk_cols);
                samples.resize(std::size_t(x1 - x0) * column);
                rows.resize(samples.size());
                rngs.resize(samples.size());
                rays.resize(samples.size());
                // camera samples in tile order (kCameraBand columns at a time, row by row in a
                // tile, a pixel's samples together), so consecutive rays are neighbours
                std::size_t k = 0;
                for (std::uint32_t tx = x0; tx < x1; tx += kCameraBand)
                    for (std::uint32_t y = y0; y < y1; ++y)
                        for (std::uint32_t x = tx; x < std::min(x1, tx + kCameraBand); ++x) {
                            const auto pixel = static_cast<std::uint32_t>(std::uint64_t(y) * W + x);
                            sampler.begin_pixel(pixel);
                            for (unsigned s = 0; s < spp; ++s, ++k) {
                                const vec2 j = sampler.sample(s, rngs[k]);
                                frame.ray_into(rays[k], x, y, j.x, j.y);
                                samples[k].pixel = pixel;
                                rows[k] = y;
                            }
                        }
                if constexpr (hook_counts_steps<Hook>()) {  // per-ray step counts: ray by ray
                    for (k = 0; k < samples.size(); ++k)
                        trace_camera<Q>(scene, shade_set.filter, rays[k], samples[k].pixel, true,
                                        row_counters[rows[k]], samples[k]);
                } else {
                    hits.resize(samples.size());
                    ShadeCounters& cnt = row_counters[y0];
                    timed(set.time_stages, cnt.times.trace_ticks, cnt.times.bounce_ticks[0], [&] {
                        Q::closest_batch(scene, shade_set.filter, rays, hits);
                        return 0;
                    });
                    for (k = 0; k < samples.size(); ++k) {
                        samples[k].ray = rays[k];
                        samples[k].hit = hits[k];
                        samples[k].steps = 0;
                        ShadeCounters& c = row_counters[rows[k]];
                        ++c.rays.primary;
                        ++c.bounce_rays[0];
                    }
                }
                // shaded sample by sample, the chunk's shadow rays deferred and traced as one batch
                DeferredShadows& shadows = scratch.shadows;
                shadows.clear();
                alphas.resize(samples.size());
                adds_end.resize(samples.size());
                for (k = 0; k < samples.size(); ++k) {  // only the alpha is kept: the colour is deferred
                    alphas[k] = shade_sample<Hook, Q>(scene, shade_set, samples[k], rngs[k], params,
                                                      row_counters[rows[k]], scratch.pending, shadows)
                                    .alpha;
                    adds_end[k] = shadows.adds.size();
                }
                trace_shadows<Q>(scene, shade_set.filter, shadows, row_counters[y0]);
                for (k = 0; k < samples.size(); k += spp) {  // pixel by pixel, samples in order
                    vec3 sum(0.0f);
                    float cover = 0.0f;
                    for (unsigned s = 0; s < spp; ++s) {
                        sum += shadows.color(k + s == 0 ? 0 : adds_end[k + s - 1], adds_end[k + s]);
                        cover += alphas[k + s];
                    }
                    img.pixels[samples[k].pixel] = vec4(sum * inv_spp, cover * inv_spp);  // pixel = y · W + x
                }
            }
            if (set.time_stages) row_ticks[y0] = stage_ticks() - t_band;
            const std::size_t done = rows_done += y1 - y0;
            if (set.progress) {
                std::lock_guard lock(progress_mutex);
                set.progress(done, H);
            }
        }
    });
    });
    const double render_ms = ms_since(t_render);
    const std::uint64_t render_ticks = set.time_stages ? stage_ticks() - ticks_render : 0;

    // ---- resolve
    const auto t_resolve = Clock::now();
    if (heat_map) cost_heat_map(img, set.cost_scale);
    const double resolve_ms = ms_since(t_resolve);

    if (stats) {
        RenderStats st;
        ShadeCounters total;
        for (const ShadeCounters& c : row_counters) total += c;
        st.rays = total.rays;
        for (unsigned i = 0; i < kBounceSlots; ++i) st.bounce_rays[i] = total.bounce_rays[i];
        st.traversal_steps = total.traversal_steps;
        st.deepest = total.deepest;
        st.threads = threads;
        st.setup_ms = setup_ms;
        st.render_ms = render_ms;
        st.resolve_ms = resolve_ms;
        st.total_ms = ms_since(t_start);
        if (set.time_stages && render_ticks > 0) {
            const double ms_per_tick = render_ms / double(render_ticks);  // calibrated on this frame
            std::uint64_t all = 0;
            for (std::uint64_t r : row_ticks) all += r;
            st.trace_thread_ms = double(total.times.trace_ticks) * ms_per_tick;
            st.shadow_thread_ms = double(total.times.shadow_ticks) * ms_per_tick;
            st.shade_thread_ms = std::max(0.0, double(all) * ms_per_tick - st.trace_thread_ms - st.shadow_thread_ms);
            for (unsigned i = 0; i < kBounceSlots; ++i)
                st.bounce_thread_ms[i] = double(total.times.bounce_ticks[i]) * ms_per_tick;
        }
        *stats = st;
    }
    return img;
}

}  // namespace detail

/// Renders `scene` through `cam` with the built-in shader set.shade.shader (render/shaders.hpp;
/// see the header comment). Throws std::invalid_argument for spp == 0 or an invalid camera
/// (Camera::frame()); exceptions from workers are rethrown.
inline Image render_cpu(const ShadeScene& scene, const Camera& cam, const RenderSettings& set,
                        RenderStats* stats = nullptr) {
    return visit_shader(set.shade.shader, [&]<class S>(S) {
        return detail::render_samples<S>(scene, cam, set, typename S::Params{}, stats,
                                         set.shade.shader == ShaderKind::debug_cost);
    });
}

/// Renders with ray hook H on the CPU (render/ray_hook.hpp): the twin of the device's
/// render_hook<H> (cl/render.hpp), same sampling, threads and statistics as render_cpu.
template <class H>
Image render_hook_cpu(const ShadeScene& scene, const Camera& cam, const RenderSettings& set,
                      const typename H::Params& params, RenderStats* stats = nullptr) {
    return detail::render_samples<H>(scene, cam, set, params, stats, false);
}

// ---------------------------------------------------------------- owning scene, framing, default light

/// The renderer's default tree: binned SAH with BlockBvh8::sah_config()'s leaf cost (blocks
/// of 4, leaves up to 12), which the CPU walks as 8-wide nodes over 4-triangle blocks.
inline BuildOptions render_build_options(unsigned threads = 0) {
    BuildOptions b;
    b.leaf = BlockBvh8::sah_config().leaf;
    b.threads = threads;
    return b;
}

/// Everything a render needs, owned: a Scene, one MaterialTable per object, lights.
/// view() is valid until the RenderScene is modified, moved or destroyed.
struct RenderScene {
    Scene scene;
    std::vector<MaterialTable> materials;  ///< one per object, in object order
    std::vector<Light> lights;
    double build_ms = 0.0;      ///< trees (binary build + blocks)
    double materials_ms = 0.0;  ///< material tables, texture loading included

    /// Adds `mesh` as an object with the tree `build` makes (BuildOptions: any builder) and
    /// its material table (textures through `cache` when given); no instance. Returns its index.
    std::uint32_t add_object(Mesh mesh, ObjectKind kind = ObjectKind::static_object, const BuildOptions& build = {},
                             TextureCache* cache = nullptr) {
        using Clock = std::chrono::steady_clock;
        auto t0 = Clock::now();
        Bvh bvh = build_bvh(MeshView(mesh), build);
        const std::uint32_t id = scene.add_object(std::move(mesh), std::move(bvh), kind, build.threads);
        build_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        t0 = Clock::now();
        materials.push_back(make_material_table(scene.objects()[id].mesh, cache, build.threads));
        materials_ms += std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
        return id;
    }
    /// The shaders' view (the top-level tree must be fresh: Scene::update_top_level()).
    ShadeScene view() const { return make_shade_scene(scene, materials, lights); }
    /// scene_bounds(scene): for one object at the identity, the bounds of its triangles.
    AABB bounds() const { return scene_bounds(scene); }
};

/// A RenderScene of one static object, `mesh`, at the identity, with the tree `build` makes
/// (BlockBvh8::sah_config()'s leaves by default: the fastest CPU path) and its material table
/// (textures through `cache` when given); no lights. Material warnings are in
/// result.materials[0].warnings.
inline RenderScene prepare_render_scene(Mesh mesh, BuildOptions build = render_build_options(),
                                        TextureCache* cache = nullptr) {
    RenderScene rs;
    rs.scene.add_instance(rs.add_object(std::move(mesh), ObjectKind::static_object, build, cache));
    rs.scene.update_top_level();
    return rs;
}

/// A camera that sees all of `bounds` (its bounding sphere fits the vertical field of view),
/// looking from direction `from` (default: front-right-above).
inline Camera frame_scene(const AABB& bounds, std::uint32_t width, std::uint32_t height, float vfov_degrees = 45.0f,
                          vec3 from = vec3(1.0f, 0.6f, 0.8f)) {
    Camera c = camera_looking_at(bounds, width, height, from, vfov_degrees);
    if (width < height) {  // fit the narrower horizontal field of view too
        const float half_v = 0.5f * vfov_degrees * 3.14159265f / 180.0f;
        const float half_h = std::atan(std::tan(half_v) * float(width) / float(height));
        const vec3 off = c.position - c.target;
        c.position = c.target + off * (std::sin(half_v) / std::sin(half_h));
    }
    return c;
}

/// A white point light above and to the left of the camera, as far from the target as the
/// camera is: a "key light" that casts visible shadows.
inline Light default_key_light(const Camera& cam, vec3 color = vec3(1.0f)) {
    const vec3 off = cam.position - cam.target;
    const float dist = glm::length(off);
    if (!(dist > 0.0f)) return Light::point(cam.position + vec3(0.0f, 1.0f, 0.0f), color);
    const vec3 fwd = -off / dist;
    vec3 right = glm::cross(fwd, cam.up);
    right = glm::length(right) > 0.0f ? glm::normalize(right) : vec3(1.0f, 0.0f, 0.0f);
    const vec3 up = glm::cross(right, fwd);
    return Light::point(cam.position + (up * 0.8f - right * 0.5f) * dist, color);
}

}  // namespace raykit
