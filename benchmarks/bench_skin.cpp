// Skinning on the CPU against the OpenCL device (raykit::SkinHook), and the
// per-frame cost of the skinned goblin alone and inside the thesis scene.
//
//   BM_SkinCpu/T           skin_vertices (positions + normals) of the goblin's
//                          1,679 vertices tiled 600x (1,007,400 vertices, the
//                          goblin's own links, 35 bones), T threads (0 = all).
//                          Counter Mverts/s.
//   BM_SkinDevice          the same vertices as one dynamic object of a
//                          DeviceScene<SkinHook>: per iteration the bone
//                          matrices upload + the vertex stage (no refit;
//                          DeviceScene::update's vertex_ms is the manual time).
//                          Counter Mverts/s.
//   BM_SkinDeviceRefit     the same with the refit (update()'s vertex + refit).
//   BM_GoblinFrame/D/S     one animation frame of the goblin (its 800 frames
//                          sampled with a stride of 12.5 frames: 64 distinct
//                          half and whole frames, cycled), D = 0 CPU, 1 device;
//                          S = 0 alone, 1 inside the thesis scene (24,145 static
//                          triangles, uploaded once). A frame is: sample_frame
//                          (slerp) + skin matrices, skinning, refit of the
//                          goblin's tree, top level, and 320x240 primary rays
//                          traced (closest hit) with a camera on the goblin.
//                          CPU: Scene::move_vertices with SkinHook's CPU twin
//                          (parallel), Scene::update_top_level,
//                          Scene::intersect_closest over parallel_for. Device:
//                          upload + DeviceScene::update + camera_rays + closest
//                          (finish()ed). Counter ms/frame.
//
// Build: in benchmarks/CMakeLists.txt, inside `if(TARGET raykit_cl)`:
//   raykit_benchmark(bench_skin)
//   target_link_libraries(bench_skin PRIVATE raykit::cl)
// Data: RAYKIT_SHARED_DATA_DIR (compile definition) / smd/hl2_goblin and
// obj/thesis_scene; cases whose data is absent, or with no OpenCL device,
// skip themselves (SkipWithError).
#include <benchmark/benchmark.h>

#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "raykit.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skin_hook.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/cl.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/io/smd.hpp"
#include "raykit/scene/camera.hpp"
#include "raykit/scene/scene.hpp"
#include "raykit/util/parallel.hpp"

namespace {

namespace fs = std::filesystem;
namespace rcl = raykit::cl;
using namespace raykit;

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

struct Goblin {
    SmdModel model;
    SmdSkeletonAnim anim;
    std::unique_ptr<Skeleton> skeleton;
    PackedSkin skin;
};

const Goblin* goblin() {
    static std::unique_ptr<Goblin> g = []() -> std::unique_ptr<Goblin> {
        const fs::path dir = fs::path(RAYKIT_SHARED_DATA_DIR) / "smd" / "hl2_goblin";
        if (!fs::exists(dir / "Goblin_Reference.smd")) return nullptr;
        auto out = std::make_unique<Goblin>();
        out->model = load_smd_reference(dir / "Goblin_Reference.smd");
        out->anim = load_smd_animation(dir / "Goblin_Anim.smd", out->model);
        out->skeleton = std::make_unique<Skeleton>(out->model);
        out->skin = pack_skin(out->model.weights, out->model.bones.size());
        return out;
    }();
    return g.get();
}

rcl::Device* device_or_skip(benchmark::State& state) {
    try {
        return &rcl::Device::shared();
    } catch (const rcl::NoDeviceError& e) {
        state.SkipWithError(e.what());
        return nullptr;
    }
}

constexpr std::size_t kTiles = 600;

/// The goblin tiled kTiles times (each tile shifted), with its skin tiled too.
struct Tiled {
    Mesh mesh;
    PackedSkin skin;
    std::vector<SkinMatrix> mats;
};

const Tiled* tiled() {
    static std::unique_ptr<Tiled> t = []() -> std::unique_ptr<Tiled> {
        const Goblin* g = goblin();
        if (!g) return nullptr;
        auto out = std::make_unique<Tiled>();
        const Mesh& m = g->model.mesh;
        out->skin.bone_count = g->skin.bone_count;
        for (std::size_t k = 0; k < kTiles; ++k) {
            const auto v0 = static_cast<std::uint32_t>(out->mesh.positions.size());
            const vec3 shift(20.0f * float(k % 30), 20.0f * float(k / 30), 0.0f);
            for (const vec3& p : m.positions) out->mesh.positions.push_back(p + shift);
            out->mesh.normals.insert(out->mesh.normals.end(), m.normals.begin(), m.normals.end());
            for (Triangle tr : m.triangles) {
                for (auto& v : tr.v) v += v0;
                out->mesh.triangles.push_back(tr);
            }
            const auto l0 = static_cast<std::uint32_t>(out->skin.links.size());
            out->skin.links.insert(out->skin.links.end(), g->skin.links.begin(), g->skin.links.end());
            for (std::size_t v = 1; v < g->skin.offsets.size(); ++v) out->skin.offsets.push_back(l0 + g->skin.offsets[v]);
        }
        out->mats = skin_matrices(*g->skeleton, sample_frame(g->anim, 123.5, Interpolation::slerp, WrapMode::loop));
        return out;
    }();
    return t.get();
}

void BM_SkinCpu(benchmark::State& state) {
    const Tiled* t = tiled();
    if (!t) {
        state.SkipWithError("goblin data not found");
        return;
    }
    const auto threads = static_cast<unsigned>(state.range(0));
    const std::size_t n = t->mesh.positions.size();
    std::vector<vec3> p(n), nn(n);
    for (auto _ : state) {
        skin_vertices(t->skin, t->mats, t->mesh.positions, t->mesh.normals, p, nn, threads);
        benchmark::DoNotOptimize(p.data());
    }
    state.counters["Mverts/s"] = benchmark::Counter(double(n) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}
BENCHMARK(BM_SkinCpu)->Arg(1)->Arg(0)->UseRealTime()->Unit(benchmark::kMillisecond);

struct DeviceTiled {
    Scene scene;
    std::unique_ptr<rcl::DeviceScene<SkinHook>> ds;
    std::uint32_t body = 0;
};

DeviceTiled* device_tiled(rcl::Device& dev) {
    static std::unique_ptr<DeviceTiled> d = [&]() -> std::unique_ptr<DeviceTiled> {
        const Tiled* t = tiled();
        if (!t) return nullptr;
        auto out = std::make_unique<DeviceTiled>();
        out->body = out->scene.add_object(t->mesh, ObjectKind::dynamic);
        out->scene.add_instance(out->body);
        out->ds = std::make_unique<rcl::DeviceScene<SkinHook>>(dev, out->scene);
        upload_skin(*out->ds, out->scene, out->body, t->skin);
        upload_skin_matrices(*out->ds, std::span<const SkinMatrix>(t->mats));
        out->ds->update();  // compiles the program
        return out;
    }();
    return d.get();
}

void skin_device(benchmark::State& state, bool with_refit) {
    rcl::Device* dev = device_or_skip(state);
    if (!dev) return;
    DeviceTiled* d = device_tiled(*dev);
    if (!d) {
        state.SkipWithError("goblin data not found");
        return;
    }
    const Tiled* t = tiled();
    for (auto _ : state) {
        const auto t0 = std::chrono::steady_clock::now();
        upload_skin_matrices(*d->ds, std::span<const SkinMatrix>(t->mats));
        const double upload_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
        const rcl::FrameTimes ft = d->ds->update();
        state.SetIterationTime(1e-3 * (upload_ms + ft.vertex_ms + (with_refit ? ft.refit_ms : 0.0)));
    }
    state.counters["Mverts/s"] =
        benchmark::Counter(double(t->mesh.positions.size()) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
}
void BM_SkinDevice(benchmark::State& state) { skin_device(state, false); }
void BM_SkinDeviceRefit(benchmark::State& state) { skin_device(state, true); }
BENCHMARK(BM_SkinDevice)->UseManualTime()->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SkinDeviceRefit)->UseManualTime()->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------- per-frame

struct FrameSetup {
    Scene scene;
    std::uint32_t body = 0;
    mat4 place{1.0f};
    Camera cam;
    std::unique_ptr<rcl::DeviceScene<SkinHook>> ds;
    rcl::Buffer<Ray> rays;
    rcl::Buffer<Hit> hits;
};

FrameSetup* frame_setup(bool in_scene, rcl::Device* dev) {
    static std::unique_ptr<FrameSetup> cache[2][2];
    auto& slot = cache[in_scene][dev != nullptr];
    if (slot) return slot.get();
    const Goblin* g = goblin();
    if (!g) return nullptr;
    const fs::path obj = fs::path(RAYKIT_SHARED_DATA_DIR) / "obj" / "thesis_scene" / "Scene.obj";
    if (in_scene && !fs::exists(obj)) return nullptr;
    auto s = std::make_unique<FrameSetup>();
    if (in_scene) s->scene.add_instance(s->scene.add_object(load_obj(obj)));
    s->body = s->scene.add_object(g->model.mesh, ObjectKind::dynamic);
    // The placement of `raykit animate --place 1 6` (1.8 units tall, z-up -> y-up), folded into the matrices.
    AABB rb;
    for (const vec3& p : g->model.mesh.positions) rb.grow(p);
    const float sc = 1.8f / (rb.max.z - rb.min.z);
    s->place = glm::translate(mat4(1.0f), vec3(1.0f, -rb.min.z * sc, 6.0f));
    s->place = glm::scale(s->place, vec3(sc));
    s->place = glm::rotate(s->place, glm::radians(-90.0f), vec3(1.0f, 0.0f, 0.0f));
    s->scene.add_instance(s->body);
    s->scene.update_top_level();
    s->cam.width = 320;
    s->cam.height = 240;
    s->cam.position = vec3(4.0f, 2.0f, 10.0f);
    s->cam.target = vec3(1.0f, 0.9f, 6.0f);
    if (dev) {
        s->ds = std::make_unique<rcl::DeviceScene<SkinHook>>(*dev, s->scene);
        upload_skin(*s->ds, s->scene, s->body, g->skin);
        s->rays.reserve(*dev, 320 * 240);
        s->hits.reserve(*dev, 320 * 240);
    }
    slot = std::move(s);
    return slot.get();
}

std::vector<SkinMatrix> placed_matrices(const Goblin& g, const mat4& P, double frame) {
    std::vector<SkinMatrix> m = skin_matrices(*g.skeleton, sample_frame(g.anim, frame, Interpolation::slerp, WrapMode::loop));
    for (SkinMatrix& x : m) {
        SkinMatrix o;
        for (int r = 0; r < 3; ++r)
            for (int c = 0; c < 4; ++c) {
                float v = c == 3 ? P[3][r] : 0.0f;
                for (int k = 0; k < 3; ++k) v += P[k][r] * x.m[4 * k + c];
                o.m[4 * r + c] = v;
            }
        x = o;
    }
    return m;
}

void BM_GoblinFrame(benchmark::State& state) {
    const bool on_device = state.range(0) != 0, in_scene = state.range(1) != 0;
    rcl::Device* dev = nullptr;
    if (on_device && !(dev = device_or_skip(state))) return;
    FrameSetup* s = frame_setup(in_scene, dev);
    const Goblin* g = goblin();
    if (!s || !g) {
        state.SkipWithError("goblin or thesis scene data not found");
        return;
    }
    const CameraFrame cf = s->cam.frame();
    const std::size_t nrays = std::size_t(cf.width) * cf.height;
    std::vector<Hit> hits(nrays);
    int k = 0;
    auto one_frame = [&]() {
        const double frame = 12.5 * double(k++ % 64);
        const std::vector<SkinMatrix> mats = placed_matrices(*g, s->place, frame);
        if (on_device) {
            upload_skin_matrices(*s->ds, std::span<const SkinMatrix>(mats));
            s->ds->update();
            s->ds->camera_rays(cf, s->rays);
            s->ds->closest(s->rays, s->hits, nrays);
            dev->finish();
        } else {
            const SkinHook::Host host{g->skin.offsets, g->skin.links, mats};
            s->scene.move_vertices(s->body, [&](const Vertex& v, std::uint32_t i) { return SkinHook::apply(v, i, {}, host); });
            s->scene.update_top_level();
            parallel_for(nrays, 0, [&](std::size_t i) {
                hits[i] = s->scene.intersect_closest(cf.ray(std::uint32_t(i % cf.width), std::uint32_t(i / cf.width)));
            });
        }
    };
    one_frame();  // warm-up (device: program build)
    for (auto _ : state) one_frame();
    state.counters["ms/frame"] =
        benchmark::Counter(1e-3, benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
    state.counters["static_tris"] = in_scene ? double(s->scene.objects()[0].mesh.triangles.size()) : 0.0;
}
BENCHMARK(BM_GoblinFrame)->ArgsProduct({{0, 1}, {0, 1}})->ArgNames({"device", "scene"})->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace
