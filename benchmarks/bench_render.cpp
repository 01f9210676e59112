// benchmarks/bench_render.cpp — renderer frame time, CPU and OpenCL device (Google Benchmark).
//
// Cases: render/<scene>/<variant>/spp:<N>/threads:<T> (CPU, render_cpu) and
//        render/<scene>/<variant>/spp:<N>/device:cl (raykit::cl::DeviceRenderer on
//        raykit::cl::Device::shared(): PoCL's CPU device here; RAYKIT_CL_DEVICE to choose;
//        built when CMake finds OpenCL), 640 x 480, one point light, the same images.
//   scene    thesis  RAYKIT_SHARED_DATA_DIR/obj/thesis_scene/Scene.obj (24k triangles, 21 textured
//                    materials, alpha-tested foliage), camera (20, 8, 24) -> (0, 2.5, 0), fov 45,
//                    light at (-25, 35, 30)  (the view of docs/thesis_scene.png)
//            bunny   RAYKIT_SHARED_DATA_DIR/obj/stanford_bunny/stanford-bunny.obj (69k triangles, no
//                    materials), raykit::frame_scene + raykit::default_key_light
//   variant  primary   depth shader: camera rays + closest hit only
//            noshadow  whitted, max depth 1, no shadow rays
//            full      whitted, max depth 1 (one reflection bounce), shadow rays — the target
//            mirror    full, with every material made a mirror (illum 3, Ks 0.3): one reflection ray
//                      per hit, so the bounce is exercised (the thesis scene has no reflective material)
//   N        1, 4 samples per pixel;  T  1, 2 threads
// Load, BVH build, LeafTriangles, texture loading, the device upload and the device program
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
// any-hit time (CPU: thread time / T; device: kernel time).
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

struct BenchScene {
    RenderScene rs;
    Camera cam;
};

std::filesystem::path data(const char* rel) { return std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / rel; }

/// Animation frame of the goblin case (the "frame 100 onward", taken as one still frame).
constexpr double kGoblinFrame = 100.0;

/// The thesis scene with the HL2 goblin skinned at kGoblinFrame, and the camera, as
/// `raykit animate Goblin_Reference.smd Goblin_Anim.smd OUT --scene Scene.obj` makes them with
/// its defaults (examples/cli_animate.hpp): 1.8 units tall, yaw -50, feet on the first surface
/// below the scene's centre, static triangles first; the camera frames the placed bind pose.
/// nullopt when a data file is missing.
std::optional<std::pair<Mesh, Camera>> thesis_with_goblin() {
    const auto ref = data("smd/hl2_goblin/Goblin_Reference.smd"), anim_file = data("smd/hl2_goblin/Goblin_Anim.smd");
    const auto obj = data("obj/thesis_scene/Scene.obj");
    if (!std::filesystem::exists(ref) || !std::filesystem::exists(anim_file) || !std::filesystem::exists(obj))
        return std::nullopt;
    const SmdModel model = load_smd_reference(ref);
    const SmdSkeletonAnim anim = load_smd_animation(anim_file, model);
    const Mesh& cm = model.mesh;
    Mesh m = load_obj(obj);

    AABB rest, stat;
    for (const vec3& p : cm.positions) rest.grow(p);
    for (const vec3& p : m.positions) stat.grow(p);
    const float scale = 1.8f / (rest.max.z - rest.min.z);  // SMD is Z-up
    const float px = 0.5f * (stat.min.x + stat.max.x), pz = 0.5f * (stat.min.z + stat.max.z);
    Ray down;
    down.org = vec3(px, stat.max.y + 1.0f, pz);
    down.dir = vec3(0.0f, -1.0f, 0.0f);
    const Hit ground_hit = intersect_closest(MeshView(m), build_bvh(MeshView(m), BuildOptions{}), down);
    const float ground = ground_hit.valid() ? down.org.y - ground_hit.t : stat.min.y;
    mat4 P = glm::translate(mat4(1.0f), vec3(px, ground - rest.min.z * scale, pz));
    P = glm::rotate(P, glm::radians(-50.0f), vec3(0.0f, 1.0f, 0.0f));
    P = glm::scale(P, vec3(scale));
    P = glm::rotate(P, glm::radians(-90.0f), vec3(1.0f, 0.0f, 0.0f));

    // animate folds P into the bone matrices; placing the skinned vertices afterwards gives the
    // same pose up to rounding.
    const std::size_t nv = cm.positions.size();
    std::vector<vec3> pos(nv), nor(cm.normals.empty() ? 0 : nv);
    const std::vector<SkinMatrix> mats = skin_matrices(
        Skeleton(model), sample_frame(anim, kGoblinFrame, Interpolation::slerp, WrapMode::loop));
    skin_vertices(pack_skin(model.weights, model.bones.size()), mats, cm.positions, cm.normals, pos, nor, 1);

    const std::size_t v0 = m.positions.size(), t0 = m.triangles.size();
    const auto m0 = static_cast<std::uint32_t>(m.materials.size());
    if (m.normals.empty()) m.normals.assign(v0, vec3(0.0f));  // zero: the shader falls back to the face normal
    const bool with_uv = !m.texcoords.empty() || !cm.texcoords.empty();
    if (with_uv) m.texcoords.resize(v0, vec2(0.0f));
    const mat3 R(P);  // rotation times a uniform scale: normals keep their direction
    for (std::size_t i = 0; i < nv; ++i) {
        m.positions.push_back(vec3(P * vec4(pos[i], 1.0f)));
        m.normals.push_back(nor.empty() ? vec3(0.0f) : R * nor[i]);
        if (with_uv) m.texcoords.push_back(cm.texcoords.empty() ? vec2(0.0f) : cm.texcoords[i]);
    }
    m.material_ids.resize(t0, kNoMaterial);
    for (std::size_t t = 0; t < cm.triangles.size(); ++t) {
        Triangle tri = cm.triangles[t];
        for (auto& v : tri.v) v += static_cast<std::uint32_t>(v0);
        m.triangles.push_back(tri);
        const std::uint32_t id = t < cm.material_ids.size() ? cm.material_ids[t] : kNoMaterial;
        m.material_ids.push_back(id == kNoMaterial ? kNoMaterial : id + m0);
    }
    m.materials.insert(m.materials.end(), cm.materials.begin(), cm.materials.end());

    AABB placed;
    for (const vec3& p : cm.positions) placed.grow(vec3(P * vec4(p, 1.0f)));
    const vec3 c = placed.center(), h = 1.5f * (placed.max - placed.min);
    AABB wide;
    wide.grow(c - h);
    wide.grow(c + h);
    return std::make_pair(std::move(m), frame_scene(wide, kWidth, kHeight, 45.0f, vec3(0.8f, 0.35f, 1.0f)));
}

/// Loaded once per (scene, mirror) pair; nullptr when the data file is missing.
const BenchScene* bench_scene(const std::string& name, bool mirror) {
    static std::mutex m;
    static std::map<std::pair<std::string, bool>, std::unique_ptr<BenchScene>> cache;
    std::lock_guard lock(m);
    auto key = std::make_pair(name, mirror);
    if (auto it = cache.find(key); it != cache.end()) return it->second.get();
    auto s = std::make_unique<BenchScene>();
    Mesh mesh;
    if (name == "goblin") {
        auto g = thesis_with_goblin();
        if (!g) return (cache[key] = nullptr).get();
        mesh = std::move(g->first);
        s->cam = g->second;
    } else {
        const std::filesystem::path file =
            name == "thesis" ? data("obj/thesis_scene/Scene.obj") : data("obj/stanford_bunny/stanford-bunny.obj");
        if (!std::filesystem::exists(file)) return (cache[key] = nullptr).get();
        mesh = load_obj(file);
    }
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
    if (name == "thesis") {
        s->cam.position = vec3(20.0f, 8.0f, 24.0f);
        s->cam.target = vec3(0.0f, 2.5f, 0.0f);
        s->cam.vfov_degrees = 45.0f;
        s->cam.width = kWidth;
        s->cam.height = kHeight;
        s->rs.lights.push_back(Light::point(vec3(-25.0f, 35.0f, 30.0f)));
    } else if (name == "goblin") {
        s->rs.lights.push_back(default_key_light(s->cam));
    } else {
        s->cam = frame_scene(s->rs.bounds(), kWidth, kHeight);
        s->rs.lights.push_back(default_key_light(s->cam));
    }
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
/// The device renderer of a scene, made once (upload) per (scene, mirror) pair.
raykit::cl::DeviceRenderer* device_renderer(const std::string& name, bool mirror, const BenchScene& s) {
    raykit::cl::Device& dev = raykit::cl::Device::shared();  // made first, so it outlives the cache
    static std::map<std::pair<std::string, bool>, std::unique_ptr<raykit::cl::DeviceRenderer>> cache;
    auto& r = cache[std::make_pair(name, mirror)];
    if (!r) r = std::make_unique<raykit::cl::DeviceRenderer>(dev, s.rs.view());
    return r.get();
}

void run_device(benchmark::State& state, const std::string& scene, const std::string& variant, unsigned spp) {
    const BenchScene* s = bench_scene(scene, variant == "mirror");
    if (!s) {
        state.SkipWithError((scene + ": data file not found under " RAYKIT_SHARED_DATA_DIR).c_str());
        return;
    }
    raykit::cl::DeviceRenderer* r = nullptr;
    try {
        r = device_renderer(scene, variant == "mirror", *s);
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

const bool registered = [] {
    for (const char* scene : {"thesis", "goblin", "bunny"})
        for (const char* variant : {"primary", "noshadow", "full", "mirror"})
            for (unsigned spp : {1u, 4u}) {
                // the goblin case is the frame (1 spp, shadows) and its camera-ray part only
                if (std::string(scene) == "goblin" && (spp != 1 || (std::string(variant) != "full" &&
                                                                    std::string(variant) != "primary")))
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
                benchmark::RegisterBenchmark((base + "/device:cl").c_str(),
                                             [=](benchmark::State& st) { run_device(st, scene, variant, spp); })
                    ->Unit(benchmark::kMillisecond)
                    ->UseRealTime()
                    ->MinTime(spp == 1 ? 1.0 : 2.0);
#endif
            }
    return true;
}();

}  // namespace
