// benchmarks/bench_render.cpp — renderer frame time, CPU and OpenCL device (Google Benchmark).
//
// Cases: render/<scene>/<variant>/spp:<N>/threads:<T> (CPU, render_cpu) and
//        render/<scene>/<variant>/spp:<N>/device:cl (raykit::cl::DeviceRenderer on
//        raykit::cl::Device::shared(): PoCL's CPU device here; RAYKIT_CL_DEVICE to choose;
//        built when CMake finds OpenCL), 640 x 480, one point light, the same images;
//        device:cl_q the same renderer walking quantized nodes (NodeForm::quantized), 1 spp.
//   scene    thesis  RAYKIT_SHARED_DATA_DIR/obj/thesis_scene/Scene.obj (24k triangles, 24 textured
//                    materials), camera (20, 8, 24) -> (0, 2.5, 0), fov 45, light at (-25, 35, 30)
//                    (the view of docs/thesis_scene.png). Its MTL has RGBA foliage textures, but no
//                    triangle uses those materials: nothing is alpha-tested in this frame
//            goblin  the thesis scene with the HL2 goblin (RAYKIT_SHARED_DATA_DIR/smd/hl2_goblin, 2.4k
//                    triangles) as `raykit animate REF ANIM OUT --scene Scene.obj` sets it up by
//                    default: a Scene of two objects (the static scene; the character, dynamic,
//                    placed by its instance's transform) moved to animation frame 100 by a
//                    FrameLoop (render/frame.hpp); full and primary at 1 spp render that frame
//            bunny   RAYKIT_SHARED_DATA_DIR/obj/stanford_bunny/stanford-bunny.obj (69k triangles, no
//                    materials), raykit::frame_scene + raykit::default_key_light
//   variant  primary   depth shader: camera rays + closest hit only
//            noshadow  whitted, max depth 1, no shadow rays
//            full      whitted, max depth 1 (one reflection bounce), shadow rays — the target
//            mirror    full, with every material made a mirror (illum 3, Ks 0.3): one reflection ray
//                      per hit, so the bounce is exercised (the thesis scene has no reflective material)
//            animate   goblin only: whole frames of the frame loop, animation frames 100, 101, ...
//                      per iteration: interpolation + skin matrices, the vertex hook (SkinHook's CPU
//                      twin), refit (or rebuild) of the character's trees, top level, full render;
//                      counters interp_ms, vertex_ms, refit_ms, top_ms, trace_ms, shade_ms, frame_ms
//   N        1, 4 samples per pixel;  T  1, 2 threads
// Load, tree builds, texture loading, the device upload and the device program
// build (one untimed frame) are done once, outside the timing.
//
// Counters (per frame): Mrays_s (all rays traced per second of wall time), rays, and per stage
//   CPU     from one extra untimed frame with RenderSettings::time_stages: trace_ms, shadow_ms,
//           shade_ms (thread time per frame divided by T, i.e. the wall-time share of each
//           stage; shade includes camera rays and texture lookups)
//   device  means over the timed frames, from the queue's profiling events: camera_ms (camera
//           kernel), trace_ms (closest hit), shade_ms (ray hook), shadow_ms (any hit), and
//           resolve_ms (read back, 1/spp; host)
// and per bounce b = 0, 1 (bounce 0: camera rays and their shadow rays; 1: reflection rays and
// theirs): b<b>_rays and b<b>_Mrays_s = rays of that bounce per second of its closest- and
// any-hit time (CPU: thread time / T; device: kernel time); CPU cases also frame_ms (mean wall
// time of render_cpu, i.e. the whole frame).
//
// Embree 3 peers (built when CMake finds Embree, see CMakeLists.txt):
//        render/<scene>/embree1/threads:<T> and render/<scene>/embree16/threads:<T>, scene thesis,
//        goblin, bunny. They trace exactly bounce 0 of the full variant's frame at 1 spp, trace
//        only, no shading: the renderer's camera ray of every pixel (PixelSampler at seed 0 with
//        jitter, then CameraFrame::ray, as render_cpu makes it), closest hit; then from every
//        hit, the shadow ray shade.hpp's Whitted shader traces toward the point light (its
//        surface_point, offset origin, unit direction, tmax = distance · (1 - 1e-4); none where
//        the light is behind the surface), any hit. embree1: rtcIntersect1 per camera ray, then
//        rtcOccluded1 per shadow ray; embree16: 4 x 4 pixel tiles, rtcIntersect16 on the tile's
//        camera rays, then rtcOccluded16 on its shadow rays (lanes without one are invalid),
//        coherent context. Rows (embree16: rows of tiles) are dealt round-robin to T threads as
//        render_cpu deals rows. Shadow rays are made from Embree's own hits each iteration,
//        untimed; the time of an iteration is the two traces. One default-config device
//        (common.hpp), one triangle geometry over the render mesh, RTC_BUILD_QUALITY_MEDIUM
//        (make_embree_scene); in a scene with alpha-tested materials (none of these three) a
//        filter function applies the renderer's cut-out test (detail::cut_out) for both queries.
//        Counters: camera_ms, shadow_ms (wall time per frame of each trace), rays (camera +
//        shadow), Mrays_s (per second of trace time), and the cross-check, computed once per
//        scene, untimed: hits_*, shadow_* (shadow rays traced), occl_* (occluded) for render
//        (render_cpu's own frame: covered pixels, bounce-0 shadow rays), rk (raykit's tracer of
//        the renderer on these rays), e1, e16; mism_cam_e1_rk and mism_cam_e16_e1 (pixels whose
//        hit or miss differs, or whose triangle differs at a distance more than 1e-4 · t apart),
//        mism_occl_e1_rk and mism_occl_e16_e1 (pixels whose shadow ray is traced by one and not
//        the other, or whose occlusion differs); goblin_px (pixels showing the goblin);
//        cutout_px and alpha_filter only for alpha-tested scenes.
//
//   build-bench-render/benchmarks/bench_render --benchmark_out=docs/bench_render.json --benchmark_out_format=json
#include <benchmark/benchmark.h>

#include <chrono>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "common.hpp"
#include "raykit.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/io/smd.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/anim/skin_hook.hpp"
#include "raykit/render/frame.hpp"
#if defined(RAYKIT_BENCH_HAVE_CL)
#include "raykit/cl.hpp"
#include "raykit/cl/render.hpp"
#endif

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

namespace {

using namespace raykit;

constexpr std::uint32_t kWidth = 640, kHeight = 480;

/// The goblin's animation and the frame loop that moves it (the goblin case).
struct GoblinAnim {
    SmdModel model;
    SmdSkeletonAnim anim;
    Skeleton skeleton;
    PackedSkin skin;
    std::unique_ptr<FrameLoop> loop;
    double interp_ms = 0.0;  ///< the last frame's interpolation + skin matrices
};

struct BenchScene {
    RenderScene rs;
    Camera cam;
    std::uint32_t goblin_inst = kInvalidIndex;  ///< the goblin case: the character's instance
    std::unique_ptr<GoblinAnim> goblin;
    /// The scene's triangles in world space as one mesh, for Embree: flat triangle k is
    /// triangle k - inst_base[inst] of instance inst = flat_inst[k].
    Mesh flat;
    std::vector<std::uint32_t> flat_inst, inst_base;

    /// A scene hit as a flat triangle index, and back.
    std::uint32_t flat_index(const Hit& h) const { return inst_base[h.inst] + h.prim; }
    Hit scene_hit(float t, float u, float v, std::uint32_t flat_prim) const {
        const std::uint32_t inst = flat_inst[flat_prim];
        return Hit{t, u, v, flat_prim - inst_base[inst], inst};
    }
};

std::filesystem::path data(const char* rel) { return std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / rel; }

/// Animation frame of the goblin case (the "frame 100 onward").
constexpr double kGoblinFrame = 100.0;

/// Moves the goblin to animation frame `f` through its frame loop (vertex hook, refit, top).
void goblin_to(BenchScene& s, double f, unsigned threads) {
    GoblinAnim& g = *s.goblin;
    const auto t0 = std::chrono::steady_clock::now();
    const std::vector<SkinMatrix> mats =
        skin_matrices(g.skeleton, sample_frame(g.anim, f, Interpolation::slerp, WrapMode::loop));
    g.interp_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
    const SkinHook::Host host{g.skin.offsets, g.skin.links, mats};
    g.loop->update(vertex_hook(
        [&](std::uint32_t, const Vertex& v, std::uint32_t i) { return SkinHook::apply(v, i, {}, host); }, threads));
}

/// The thesis scene with the HL2 goblin as `raykit animate Goblin_Reference.smd Goblin_Anim.smd
/// OUT --scene Scene.obj` sets it up with its defaults (examples/cli_animate.hpp): two objects,
/// the static scene and the dynamic character placed by its instance (1.8 units tall, yaw -50,
/// feet on the first surface below the scene's centre), moved to kGoblinFrame by a FrameLoop;
/// the camera frames the placed bind pose. False when a data file is missing.
bool thesis_with_goblin(BenchScene& s) {
    const auto ref = data("smd/hl2_goblin/Goblin_Reference.smd"), anim_file = data("smd/hl2_goblin/Goblin_Anim.smd");
    const auto obj = data("obj/thesis_scene/Scene.obj");
    if (!std::filesystem::exists(ref) || !std::filesystem::exists(anim_file) || !std::filesystem::exists(obj))
        return false;
    auto g = std::make_unique<GoblinAnim>();
    g->model = load_smd_reference(ref);
    g->anim = load_smd_animation(anim_file, g->model);
    g->skeleton = Skeleton(g->model);
    g->skin = pack_skin(g->model.weights, g->model.bones.size());
    const Mesh& cm = g->model.mesh;
    Mesh m = load_obj(obj);
    AABB rest, stat;
    for (const vec3& p : cm.positions) rest.grow(p);
    for (const vec3& p : m.positions) stat.grow(p);
    const BuildOptions build = render_build_options();
    const std::uint32_t town = s.rs.add_object(std::move(m), ObjectKind::static_object, build);
    const std::uint32_t body = s.rs.add_object(cm, ObjectKind::dynamic, build);

    const float scale = 1.8f / (rest.max.z - rest.min.z);  // SMD is Z-up
    const float px = 0.5f * (stat.min.x + stat.max.x), pz = 0.5f * (stat.min.z + stat.max.z);
    Ray down;
    down.org = vec3(px, stat.max.y + 1.0f, pz);
    down.dir = vec3(0.0f, -1.0f, 0.0f);
    const Hit ground_hit = intersect_closest(s.rs.scene.objects()[town].blocks, down);
    const float ground = ground_hit.valid() ? down.org.y - ground_hit.t : stat.min.y;
    mat4 P = glm::translate(mat4(1.0f), vec3(px, ground - rest.min.z * scale, pz));
    P = glm::rotate(P, glm::radians(-50.0f), vec3(0.0f, 1.0f, 0.0f));
    P = glm::scale(P, vec3(scale));
    P = glm::rotate(P, glm::radians(-90.0f), vec3(1.0f, 0.0f, 0.0f));
    s.rs.scene.add_instance(town);
    s.goblin_inst = s.rs.scene.add_instance(body, P);
    s.rs.scene.update_top_level();

    AABB placed;  // the placed vertices' box, as animate frames it
    for (const vec3& p : cm.positions) placed.grow(vec3(P * vec4(p, 1.0f)));
    const vec3 c = placed.center(), h = 1.5f * (placed.max - placed.min);
    AABB wide;
    wide.grow(c - h);
    wide.grow(c + h);
    s.cam = frame_scene(wide, kWidth, kHeight, 45.0f, vec3(0.8f, 0.35f, 1.0f));
    s.rs.lights.push_back(default_key_light(s.cam));
    g->loop = std::make_unique<FrameLoop>(s.rs);
    s.goblin = std::move(g);
    goblin_to(s, kGoblinFrame, 0);
    return true;
}

/// Fills s.flat and its maps from the scene as it stands.
void flatten(BenchScene& s) {
    auto [flat, origin] = s.rs.scene.world_mesh();
    s.flat = std::move(flat);
    s.flat_inst.resize(origin.size());
    s.inst_base.assign(s.rs.scene.instances().size(), 0);
    for (std::size_t k = 0; k < origin.size(); ++k) {
        s.flat_inst[k] = origin[k].first;
        if (origin[k].second == 0) s.inst_base[origin[k].first] = static_cast<std::uint32_t>(k);
    }
}

/// Loaded once per (scene, mirror) pair; nullptr when the data file is missing.
BenchScene* bench_scene(const std::string& name, bool mirror) {
    static std::mutex m;
    static std::map<std::pair<std::string, bool>, std::unique_ptr<BenchScene>> cache;
    std::lock_guard lock(m);
    auto key = std::make_pair(name, mirror);
    if (auto it = cache.find(key); it != cache.end()) return it->second.get();
    auto s = std::make_unique<BenchScene>();
    if (name == "goblin") {
        if (!thesis_with_goblin(*s)) return (cache[key] = nullptr).get();
    } else {
        const std::filesystem::path file =
            name == "thesis" ? data("obj/thesis_scene/Scene.obj") : data("obj/stanford_bunny/stanford-bunny.obj");
        if (!std::filesystem::exists(file)) return (cache[key] = nullptr).get();
        Mesh mesh = load_obj(file);
        if (mirror) {
            if (mesh.materials.empty()) {
                mesh.materials.emplace_back();
                for (auto& id : mesh.material_ids) id = 0;
            }
            for (Material& mat : mesh.materials) {
                mat.illum = 3;
                mat.ks = vec3(0.3f);
            }
        }
        s->rs = prepare_render_scene(std::move(mesh));
    }
    if (name == "thesis") {
        s->cam.position = vec3(20.0f, 8.0f, 24.0f);
        s->cam.target = vec3(0.0f, 2.5f, 0.0f);
        s->cam.vfov_degrees = 45.0f;
        s->cam.width = kWidth;
        s->cam.height = kHeight;
        s->rs.lights.push_back(Light::point(vec3(-25.0f, 35.0f, 30.0f)));
    } else if (name == "bunny") {
        s->cam = frame_scene(s->rs.bounds(), kWidth, kHeight);
        s->rs.lights.push_back(default_key_light(s->cam));
    }
    flatten(*s);
    return (cache[key] = std::move(s)).get();
}

RenderSettings settings(const std::string& variant, unsigned spp, unsigned threads) {
    RenderSettings set;
    set.spp = spp;
    set.threads = threads;
    set.shade.max_depth = 1;
    if (variant == "primary") set.shade.shader = ShaderKind::depth;
    if (variant == "noshadow") set.shade.shadows = false;
    return set;
}

/// b<b>_rays and b<b>_Mrays_s for the bounces that traced rays (the first two).
void bounce_counters(benchmark::State& state, const std::uint64_t* rays, const double* ms) {
    for (unsigned b = 0; b < 2; ++b) {
        if (rays[b] == 0) continue;
        const std::string k = "b" + std::to_string(b);
        state.counters[k + "_rays"] = double(rays[b]);
        state.counters[k + "_Mrays_s"] = ms[b] > 0.0 ? double(rays[b]) / (ms[b] * 1e3) : 0.0;
    }
}

void run(benchmark::State& state, const std::string& scene, const std::string& variant, unsigned spp,
         unsigned threads) {
    const BenchScene* s = bench_scene(scene, variant == "mirror");
    if (!s) {
        state.SkipWithError((scene + ": data file not found under " RAYKIT_SHARED_DATA_DIR).c_str());
        return;
    }
    const RenderSettings set = settings(variant, spp, threads);
    if (variant == "animate") {  // whole frames of the frame loop: animation frames 100, 101, ...
        BenchScene& bs = *bench_scene(scene, false);
        FrameLoop& loop = *bs.goblin->loop;
        loop.settings() = set;  // no time_stages: whole frames as a user runs them
        double f = kGoblinFrame, sum[7] = {};
        std::uint64_t frames = 0, rays = 0;
        for (auto _ : state) {
            goblin_to(bs, f, threads);
            Image img = loop.render(bs.cam);
            benchmark::DoNotOptimize(img.pixels.data());
            const FrameStats& st = loop.last();
            const double row[7] = {bs.goblin->interp_ms, st.ms.vertex, st.ms.refit, st.ms.top, st.ms.trace,
                                   st.ms.shade, bs.goblin->interp_ms + st.ms.total};
            for (int k = 0; k < 7; ++k) sum[k] += row[k];
            rays += st.render.rays.total();
            ++frames;
            f += 1.0;
        }
        const double fr = frames ? 1.0 / double(frames) : 0.0;
        const char* names[7] = {"interp_ms", "vertex_ms", "refit_ms", "top_ms", "trace_ms", "shade_ms", "frame_ms"};
        for (int k = 0; k < 7; ++k) state.counters[names[k]] = sum[k] * fr;
        // one more frame with time_stages for the trace / shade split (wall time shares)
        loop.settings().time_stages = true;
        goblin_to(bs, f, threads);
        (void)loop.render(bs.cam);
        state.counters["trace_ms"] = loop.last().ms.trace;
        state.counters["shade_ms"] = loop.last().ms.shade;
        loop.settings().time_stages = false;
        goblin_to(bs, kGoblinFrame, threads);  // the other goblin cases render frame 100
        state.counters["rays"] = double(rays) * fr;
        state.counters["Mrays_s"] = benchmark::Counter(double(rays) * 1e-6, benchmark::Counter::kIsRate);
        return;
    }
    const ShadeScene view = s->rs.view();
    RenderStats st;
    std::uint64_t rays = 0, frames = 0;
    double frame_ms = 0.0;
    for (auto _ : state) {
        Image img = render_cpu(view, s->cam, set, &st);
        benchmark::DoNotOptimize(img.pixels.data());
        rays += st.rays.total();
        frame_ms += st.total_ms;
        ++frames;
    }
    const std::uint64_t per_frame = st.rays.total();
    state.counters["Mrays_s"] = benchmark::Counter(double(rays) * 1e-6, benchmark::Counter::kIsRate);
    state.counters["frame_ms"] = frames ? frame_ms / double(frames) : 0.0;
    state.counters["rays"] = double(per_frame);
    RenderSettings prof = set;
    prof.time_stages = true;
    RenderStats ps;
    render_cpu(view, s->cam, prof, &ps);
    state.counters["trace_ms"] = ps.trace_thread_ms / ps.threads;
    state.counters["shadow_ms"] = ps.shadow_thread_ms / ps.threads;
    state.counters["shade_ms"] = ps.shade_thread_ms / ps.threads;
    double bounce_ms[kBounceSlots];
    for (unsigned b = 0; b < kBounceSlots; ++b) bounce_ms[b] = ps.bounce_thread_ms[b] / ps.threads;
    bounce_counters(state, ps.bounce_rays, bounce_ms);
}

#if defined(RAYKIT_BENCH_HAVE_CL)
/// The device renderer of a scene, made once (upload into its own DeviceScene: every object and
/// instance, the goblin as moved on the CPU) per (scene, mirror) pair.
raykit::cl::DeviceRenderer* device_renderer(const std::string& name, bool mirror, const BenchScene& s,
                                            raykit::cl::NodeForm form) {
    raykit::cl::Device& dev = raykit::cl::Device::shared();  // made first, so it outlives the cache
    static std::map<std::tuple<std::string, bool, raykit::cl::NodeForm>, std::unique_ptr<raykit::cl::DeviceRenderer>>
        cache;
    auto& r = cache[std::make_tuple(name, mirror, form)];
    if (!r) r = std::make_unique<raykit::cl::DeviceRenderer>(dev, s.rs.view(), form);
    return r.get();
}

void run_device(benchmark::State& state, const std::string& scene, const std::string& variant, unsigned spp,
                raykit::cl::NodeForm form) {
    const BenchScene* s = bench_scene(scene, variant == "mirror");
    if (!s) {
        state.SkipWithError((scene + ": data file not found under " RAYKIT_SHARED_DATA_DIR).c_str());
        return;
    }
    raykit::cl::DeviceRenderer* r = nullptr;
    try {
        r = device_renderer(scene, variant == "mirror", *s, form);
    } catch (const std::exception& e) {
        state.SkipWithError((std::string("no OpenCL device: ") + e.what()).c_str());
        return;
    }
    const RenderSettings set = settings(variant, spp, 0);
    (void)r->render(s->cam, set);  // builds the program, warms the queues
    raykit::cl::DeviceRenderStats st, sum;
    std::uint64_t rays = 0, frames = 0;
    for (auto _ : state) {
        Image img = r->render(s->cam, set, &st);
        benchmark::DoNotOptimize(img.pixels.data());
        rays += st.total();
        ++frames;
        sum.camera_ms += st.camera_ms, sum.trace_ms += st.trace_ms, sum.shade_ms += st.shade_ms;
        sum.shadow_ms += st.shadow_ms, sum.resolve_ms += st.resolve_ms;
        for (unsigned b = 0; b < kBounceSlots; ++b) sum.bounce_ms[b] += st.bounce_ms[b];
    }
    const double f = frames ? 1.0 / double(frames) : 0.0;
    state.counters["Mrays_s"] = benchmark::Counter(double(rays) * 1e-6, benchmark::Counter::kIsRate);
    state.counters["rays"] = double(st.total());
    state.counters["camera_ms"] = sum.camera_ms * f;
    state.counters["trace_ms"] = sum.trace_ms * f;
    state.counters["shade_ms"] = sum.shade_ms * f;
    state.counters["shadow_ms"] = sum.shadow_ms * f;
    state.counters["resolve_ms"] = sum.resolve_ms * f;
    double bounce_ms[kBounceSlots];
    for (unsigned b = 0; b < kBounceSlots; ++b) bounce_ms[b] = sum.bounce_ms[b] * f;
    bounce_counters(state, st.bounce_rays, bounce_ms);
}
#endif

#if defined(RAYKIT_HAVE_EMBREE)
using Clock = std::chrono::steady_clock;

/// Milliseconds from a to b.
double ms_between(Clock::time_point a, Clock::time_point b) {
    return std::chrono::duration<double, std::milli>(b - a).count();
}

/// fn(row) for every row in [0, rows), rows dealt round-robin to `threads` workers one at a
/// time, as render_cpu deals image rows.
template <class Fn>
void over_rows(std::size_t rows, unsigned threads, Fn&& fn) {
    parallel_chunks(rows, rows, threads, [&](std::size_t, std::size_t b, std::size_t e) {
        for (std::size_t r = b; r < e; ++r) fn(r);
    });
}

/// One frame's shadow rays, one slot per pixel (row-major).
struct ShadowRays {
    std::vector<Ray> ray;
    std::vector<std::uint8_t> traced;    ///< the renderer traces a shadow ray from this pixel's hit
    std::vector<std::uint8_t> occluded;  ///< meaningful where traced
    explicit ShadowRays(std::size_t n) : ray(n), traced(n, 0), occluded(n, 0) {}
};

/// Embree's view of a bench scene: the same triangles, the renderer's camera rays for the
/// frame, and the cross-check counts (computed once, untimed).
struct EmbreeFrame {
    const BenchScene* bs = nullptr;
    ShadeScene view;
    Camera cam;
    vec3 light{0.0f};
    std::vector<rkbench::EmbreeVertex> verts;
    RTCScene scene = nullptr;
    bool filtered = false;  ///< cut-outs rejected by filter functions
    std::string error;
    std::vector<Ray> camera;
    std::map<std::string, double> check;
};

/// The shadow ray the Whitted shader (render/shade.hpp) traces from camera hit `hit` of `cam`
/// toward the point light at `light`: its surface_point, origin offset along the facing
/// geometric normal, unit direction and tmax = distance · (1 - 1e-4). False where it traces
/// none (the light behind the shading or the geometric normal).
bool shadow_ray(const ShadeScene& s, const Ray& cam, const Hit& hit, vec3 light, Ray& out) {
    const SurfacePoint sp = surface_point(s, hit, glm::normalize(cam.dir), TextureFilter::bilinear);
    const vec3 org = offset_ray_origin(sp.p, sp.ng);
    const vec3 to = light - org;
    const float dist = glm::length(to);
    if (!(dist > 0.0f)) return false;
    const vec3 ldir = to / dist;
    if (!(glm::dot(sp.ns, ldir) > 0.0f) || !(glm::dot(sp.ng, ldir) > 0.0f)) return false;
    out = Ray{org, 0.0f, ldir, dist * (1.0f - 1e-4f)};
    return true;
}

/// The shadow rays from a frame's camera hits (untimed: not tracing, and it samples textures).
void make_shadow_rays(const EmbreeFrame& f, const std::vector<Hit>& hits, unsigned threads, ShadowRays& sr) {
    over_rows(kHeight, threads, [&](std::size_t y) {
        for (std::size_t i = y * kWidth; i < (y + 1) * kWidth; ++i)
            sr.traced[i] = hits[i].valid() && shadow_ray(f.view, f.camera[i], hits[i], f.light, sr.ray[i]);  // scene hits
    });
}

/// Embree's twin of the renderer's alpha test (shade.hpp detail::cut_out, the same function):
/// a candidate on a texel of an alpha-tested map_Kd with alpha < 0.5 is rejected, so the ray
/// goes on, for closest and any hit alike.
void cutout_filter(const RTCFilterFunctionNArguments* args) {
    const auto& f = *static_cast<const EmbreeFrame*>(args->geometryUserPtr);
    for (unsigned k = 0; k < args->N; ++k) {
        if (args->valid[k] != -1) continue;
        const Hit h = f.bs->scene_hit(0.0f, 0.0f, 0.0f, RTCHitN_primID(args->hit, args->N, k));
        if (detail::cut_out(f.view, TextureFilter::bilinear, h.inst, h.prim, RTCHitN_u(args->hit, args->N, k),
                            RTCHitN_v(args->hit, args->N, k)))
            args->valid[k] = 0;
    }
}

/// An Embree answer as the raykit scene Hit the shaders read (Embree's u, v weigh vertices 1
/// and 2, as raykit's do; its triangle is a flat index).
Hit embree_hit(const EmbreeFrame& f, bool hit, float t, float u, float v, std::uint32_t prim) {
    return hit ? f.bs->scene_hit(t, u, v, prim) : Hit{};
}

/// Closest hits of the camera rays, one rtcIntersect1 per ray.
void embree1_camera(const EmbreeFrame& f, unsigned threads, std::vector<Hit>& hits) {
    over_rows(kHeight, threads, [&](std::size_t y) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (std::size_t i = y * kWidth; i < (y + 1) * kWidth; ++i) {
            RTCRayHit rh = rkbench::to_embree(f.camera[i]);
            rtcIntersect1(f.scene, &ctx, &rh);
            hits[i] = embree_hit(f, rh.hit.geomID != RTC_INVALID_GEOMETRY_ID, rh.ray.tfar, rh.hit.u, rh.hit.v, rh.hit.primID);
        }
    });
}

/// The traced shadow rays, one rtcOccluded1 per ray.
void embree1_shadow(const EmbreeFrame& f, unsigned threads, ShadowRays& sr) {
    over_rows(kHeight, threads, [&](std::size_t y) {
        RTCIntersectContext ctx;
        rtcInitIntersectContext(&ctx);
        for (std::size_t i = y * kWidth; i < (y + 1) * kWidth; ++i) {
            if (!sr.traced[i]) continue;
            RTCRay r = rkbench::to_embree(sr.ray[i]).ray;
            rtcOccluded1(f.scene, &ctx, &r);
            sr.occluded[i] = r.tfar < 0.0f;  // Embree marks occlusion with tfar = -inf
        }
    });
}

constexpr std::uint32_t kTile = 4;  // 4 x 4 pixels: one 16-ray packet
static_assert(kWidth % kTile == 0 && kHeight % kTile == 0);

/// Pixel of lane k in the tile whose top-left pixel is (x0, y0); lanes run row-major.
std::size_t tile_pixel(std::size_t x0, std::size_t y0, unsigned k) {
    return (y0 + k / kTile) * kWidth + x0 + k % kTile;
}

/// Writes `r` into lane k of packet `p`.
using rkbench::coherent_context;
using rkbench::set_lane;

/// Closest hits of the camera rays, one rtcIntersect16 per 4 x 4 tile (all lanes valid).
void embree16_camera(const EmbreeFrame& f, unsigned threads, std::vector<Hit>& hits) {
    over_rows(kHeight / kTile, threads, [&](std::size_t ty) {
        RTCIntersectContext ctx = coherent_context();
        alignas(64) int valid[16];
        for (int& v : valid) v = -1;
        for (std::size_t x0 = 0; x0 < kWidth; x0 += kTile) {
            RTCRayHit16 rh;
            for (unsigned k = 0; k < 16; ++k) {
                set_lane(rh.ray, k, f.camera[tile_pixel(x0, ty * kTile, k)]);
                rh.hit.geomID[k] = RTC_INVALID_GEOMETRY_ID;
                rh.hit.instID[0][k] = RTC_INVALID_GEOMETRY_ID;
            }
            rtcIntersect16(valid, f.scene, &ctx, &rh);
            for (unsigned k = 0; k < 16; ++k)
                hits[tile_pixel(x0, ty * kTile, k)] = embree_hit(f, rh.hit.geomID[k] != RTC_INVALID_GEOMETRY_ID,
                                                                 rh.ray.tfar[k], rh.hit.u[k], rh.hit.v[k], rh.hit.primID[k]);
        }
    });
}

/// The traced shadow rays, one rtcOccluded16 per 4 x 4 tile; lanes without a shadow ray are
/// invalid and tiles without any are skipped.
void embree16_shadow(const EmbreeFrame& f, unsigned threads, ShadowRays& sr) {
    over_rows(kHeight / kTile, threads, [&](std::size_t ty) {
        RTCIntersectContext ctx = coherent_context();
        alignas(64) int valid[16];
        for (std::size_t x0 = 0; x0 < kWidth; x0 += kTile) {
            RTCRay16 r;
            bool any = false;
            for (unsigned k = 0; k < 16; ++k) {
                const std::size_t i = tile_pixel(x0, ty * kTile, k);
                valid[k] = sr.traced[i] ? -1 : 0;
                any |= sr.traced[i] != 0;
                set_lane(r, k, sr.ray[i]);
            }
            if (!any) continue;
            rtcOccluded16(valid, f.scene, &ctx, &r);
            for (unsigned k = 0; k < 16; ++k)
                if (valid[k]) sr.occluded[tile_pixel(x0, ty * kTile, k)] = r.tfar[k] < 0.0f;
        }
    });
}

/// Fills f.check: hit and occlusion counts of raykit (the renderer's own trace of these rays),
/// the renderer itself, Embree single rays and Embree packets, and where they disagree.
void cross_check(EmbreeFrame& f, const BenchScene& bs) {
    const std::size_t n = f.camera.size();
    auto& c = f.check;
    const detail::Tracer<SceneTrees::blocks, true> alpha{f.view, TextureFilter::bilinear};
    const detail::Tracer<SceneTrees::blocks, false> opaque{f.view, TextureFilter::bilinear};
    std::vector<Hit> rk(n), e1(n), e16(n);
    ShadowRays srk(n), s1(n), s16(n);
    std::size_t cutout = 0, goblin = 0;
    for (std::size_t i = 0; i < n; ++i) {
        rk[i] = f.view.alpha_testing ? alpha.closest(f.camera[i]) : opaque.closest(f.camera[i]);
        if (f.view.alpha_testing) cutout += opaque.closest(f.camera[i]).prim != rk[i].prim;
        goblin += rk[i].valid() && rk[i].inst == bs.goblin_inst;
    }
    make_shadow_rays(f, rk, 1, srk);
    for (std::size_t i = 0; i < n; ++i)
        if (srk.traced[i])
            srk.occluded[i] = f.view.alpha_testing
                                  ? f.view.scene->intersect_any<SceneTrees::blocks>(srk.ray[i], alpha.keep())
                                  : f.view.scene->intersect_any<SceneTrees::blocks>(srk.ray[i]);
    embree1_camera(f, 1, e1);
    make_shadow_rays(f, e1, 1, s1);
    embree1_shadow(f, 1, s1);
    embree16_camera(f, 1, e16);
    make_shadow_rays(f, e16, 1, s16);
    embree16_shadow(f, 1, s16);

    RenderStats st;
    const Image img = render_cpu(f.view, f.cam, settings("full", 1, 1), &st);
    std::size_t covered = 0;
    for (const vec4& p : img.pixels) covered += p.w > 0.0f;

    auto count = [&](auto pred) {
        double k = 0;
        for (std::size_t i = 0; i < n; ++i) k += pred(i) ? 1 : 0;
        return k;
    };
    // a different triangle at (nearly) the same distance is a tie, not a disagreement
    auto cam_differs = [&](const Hit& a, const Hit& b) {
        if (a.valid() != b.valid()) return true;
        return a.valid() && (a.prim != b.prim || a.inst != b.inst) && std::abs(a.t - b.t) > 1e-4f * a.t;
    };
    auto occl_differs = [&](const ShadowRays& a, const ShadowRays& b, std::size_t i) {
        return a.traced[i] != b.traced[i] || (a.traced[i] && a.occluded[i] != b.occluded[i]);
    };
    c["hits_render"] = double(covered);
    c["hits_rk"] = count([&](std::size_t i) { return rk[i].valid(); });
    c["hits_e1"] = count([&](std::size_t i) { return e1[i].valid(); });
    c["hits_e16"] = count([&](std::size_t i) { return e16[i].valid(); });
    c["shadow_render"] = double(st.bounce_rays[0] - st.rays.primary);
    c["shadow_rk"] = count([&](std::size_t i) { return srk.traced[i] != 0; });
    c["shadow_e1"] = count([&](std::size_t i) { return s1.traced[i] != 0; });
    c["shadow_e16"] = count([&](std::size_t i) { return s16.traced[i] != 0; });
    c["occl_rk"] = count([&](std::size_t i) { return srk.traced[i] && srk.occluded[i]; });
    c["occl_e1"] = count([&](std::size_t i) { return s1.traced[i] && s1.occluded[i]; });
    c["occl_e16"] = count([&](std::size_t i) { return s16.traced[i] && s16.occluded[i]; });
    c["mism_cam_e1_rk"] = count([&](std::size_t i) { return cam_differs(rk[i], e1[i]); });
    c["mism_cam_e16_e1"] = count([&](std::size_t i) { return cam_differs(e1[i], e16[i]); });
    c["mism_occl_e1_rk"] = count([&](std::size_t i) { return occl_differs(srk, s1, i); });
    c["mism_occl_e16_e1"] = count([&](std::size_t i) { return occl_differs(s1, s16, i); });
    if (f.view.alpha_testing) {
        c["cutout_px"] = double(cutout);
        c["alpha_filter"] = f.filtered ? 1.0 : 0.0;
    }
    if (bs.goblin_inst != kInvalidIndex) c["goblin_px"] = double(goblin);
}

/// Embree's frame for scene `name`, made once; nullptr when the data file is missing.
const EmbreeFrame* embree_frame(const std::string& name) {
    static std::mutex m;
    static std::map<std::string, std::unique_ptr<EmbreeFrame>> cache;
    std::lock_guard lock(m);
    if (auto it = cache.find(name); it != cache.end()) return it->second.get();
    const BenchScene* bs = bench_scene(name, false);
    if (!bs) return (cache[name] = nullptr).get();
    auto f = std::make_unique<EmbreeFrame>();
    f->bs = bs;
    f->view = bs->rs.view();
    f->cam = bs->cam;
    f->light = bs->rs.lights.front().position;

    const RTCDevice dev = rkbench::default_embree_device();
    rkbench::take_embree_error();
    f->verts = rkbench::embree_vertices(bs->flat);
    f->scene = rkbench::make_embree_scene(dev, bs->flat, f->verts, RTC_BUILD_QUALITY_MEDIUM);
    if (f->view.alpha_testing && rtcGetDeviceProperty(dev, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED)) {
        // filters change what counts as a hit, so the geometry and the scene are committed again
        const RTCGeometry g = rtcGetGeometry(f->scene, 0);
        rtcSetGeometryUserData(g, f.get());
        rtcSetGeometryIntersectFilterFunction(g, cutout_filter);
        rtcSetGeometryOccludedFilterFunction(g, cutout_filter);
        rtcCommitGeometry(g);
        rtcCommitScene(f->scene);
        f->filtered = true;
    }
    f->error = rkbench::take_embree_error();

    // render_cpu's camera ray of each pixel at 1 spp: PixelSampler's (jittered) position, then
    // CameraFrame::ray
    const RenderSettings set = settings("full", 1, 1);
    const CameraFrame fr = f->cam.frame();
    PixelSampler sampler(1, set.seed, set.jitter);
    f->camera.resize(std::size_t(kWidth) * kHeight);
    for (std::uint32_t y = 0; y < kHeight; ++y)
        for (std::uint32_t x = 0; x < kWidth; ++x) {
            const std::size_t i = std::size_t(y) * kWidth + x;
            sampler.begin_pixel(i);
            SampleRng rng;
            const vec2 j = sampler.sample(0, rng);
            f->camera[i] = fr.ray(x, y, j.x, j.y);
        }
    if (f->error.empty()) cross_check(*f, *bs);
    return (cache[name] = std::move(f)).get();
}

/// One Embree case: per iteration camera rays, shadow rays made from those hits, shadow rays;
/// the iteration's time is the two traces only.
void run_embree(benchmark::State& state, const std::string& scene, bool packets, unsigned threads) {
    const EmbreeFrame* f = embree_frame(scene);
    if (!f) {
        state.SkipWithError((scene + ": data file not found under " RAYKIT_SHARED_DATA_DIR).c_str());
        return;
    }
    if (!f->error.empty()) {
        state.SkipWithError(f->error.c_str());
        return;
    }
    const std::size_t n = f->camera.size();
    std::vector<Hit> hits(n);
    ShadowRays sr(n);
    double camera_ms = 0.0, shadow_ms = 0.0;
    std::uint64_t frames = 0, rays = 0;
    for (auto _ : state) {
        const auto t0 = Clock::now();
        if (packets) embree16_camera(*f, threads, hits);
        else embree1_camera(*f, threads, hits);
        const auto t1 = Clock::now();
        make_shadow_rays(*f, hits, threads, sr);
        const auto t2 = Clock::now();
        if (packets) embree16_shadow(*f, threads, sr);
        else embree1_shadow(*f, threads, sr);
        const auto t3 = Clock::now();
        camera_ms += ms_between(t0, t1);
        shadow_ms += ms_between(t2, t3);
        state.SetIterationTime((ms_between(t0, t1) + ms_between(t2, t3)) * 1e-3);
        ++frames;
        rays = n;
        for (std::uint8_t t : sr.traced) rays += t;
    }
    const double fr = frames ? 1.0 / double(frames) : 0.0;
    state.counters["camera_ms"] = camera_ms * fr;
    state.counters["shadow_ms"] = shadow_ms * fr;
    state.counters["rays"] = double(rays);
    state.counters["Mrays_s"] = camera_ms + shadow_ms > 0.0 ? double(rays) / ((camera_ms + shadow_ms) * fr * 1e3) : 0.0;
    for (const auto& [k, v] : f->check) state.counters[k] = v;
}
#endif

const bool registered = [] {
    for (const char* scene : {"thesis", "goblin", "bunny"})
        for (const char* variant : {"primary", "noshadow", "full", "mirror", "animate"})
            for (unsigned spp : {1u, 4u}) {
                // the goblin case is the frame (1 spp, shadows) and its camera-ray part only;
                // animate is a goblin variant
                const std::string sc = scene, va = variant;
                if (sc == "goblin" ? spp != 1 || (va != "full" && va != "primary" && va != "animate") : va == "animate")
                    continue;
                const std::string base =
                    std::string("render/") + scene + "/" + variant + "/spp:" + std::to_string(spp);
                for (unsigned threads : {1u, 2u})
                    benchmark::RegisterBenchmark((base + "/threads:" + std::to_string(threads)).c_str(),
                                                 [=](benchmark::State& st) { run(st, scene, variant, spp, threads); })
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime()
                        ->MinTime(spp == 1 ? 1.0 : 2.0);
#if defined(RAYKIT_BENCH_HAVE_CL)
                if (va == "animate") continue;  // the CPU frame loop's case (raykit animate --device cl has the device's)
                for (const raykit::cl::NodeForm form : {raykit::cl::NodeForm::full, raykit::cl::NodeForm::quantized}) {
                    if (form == raykit::cl::NodeForm::quantized && spp != 1) continue;
                    benchmark::RegisterBenchmark(
                        (base + (form == raykit::cl::NodeForm::full ? "/device:cl" : "/device:cl_q")).c_str(),
                        [=](benchmark::State& st) { run_device(st, scene, variant, spp, form); })
                        ->Unit(benchmark::kMillisecond)
                        ->UseRealTime()
                        ->MinTime(spp == 1 ? 1.0 : 2.0);
                }
#endif
            }
#if defined(RAYKIT_HAVE_EMBREE)
    for (const char* scene : {"thesis", "goblin", "bunny"})
        for (bool packets : {false, true})
            for (unsigned threads : {1u, 2u})
                benchmark::RegisterBenchmark((std::string("render/") + scene + (packets ? "/embree16" : "/embree1") +
                                              "/threads:" + std::to_string(threads))
                                                 .c_str(),
                                             [=](benchmark::State& st) { run_embree(st, scene, packets, threads); })
                    ->Unit(benchmark::kMillisecond)
                    ->UseManualTime()
                    ->MinTime(1.0);
#endif
    return true;
}();

}  // namespace
