// benchmarks/common.hpp — scenes, ray sets and Embree helpers shared by raykit's benchmarks.
//
// Scenes (each loaded or generated once per process, on first use):
//   "bunny"      RAYKIT_SHARED_DATA_DIR/obj/stanford_bunny/stanford-bunny.obj (69 451 triangles);
//                absent data makes scene() return nullptr and the case skips itself
//   "torus100k"  raykit::make_bumpy_torus(100000)
//   "torus1M"    raykit::make_bumpy_torus(1000000)
//   "torus4M", "torus16M"  raykit::make_bumpy_torus(4000000 / 16000000): GPU-sized (bench_cl runs
//                them on GPUs only: 180 / 663 MB of 8-wide device nodes, beyond a GPU's L2)
//
// Ray sets (kRayCount = 512x512 = 262 144 rays each, deterministic, shared by
// raykit and Embree):
//   "primary"  pinhole camera at bbox centre + 1.5 * |bbox diagonal| * normalize(1, 0.6, 0.8),
//              looking at the bbox centre, up = +y, vertical fov 45 degrees, square
//              image, one ray through each pixel centre, row-major. The bounding
//              sphere (radius |diag|/2) subtends 19.5 degrees < 22.5, so the whole
//              object is in frame. Directions are normalized; tmin = 0, tmax = inf.
//   "tiles"    the same camera rays in 4x4-pixel tiles (the renderer's order): a batch's
//              16 consecutive rays, and Embree's rtcIntersect16 packets, are one tile.
//   "random"   origins uniform in the bbox, directions uniform on the unit sphere
//              (std::mt19937_64, fixed seed per scene), tmin = 0, tmax = inf:
//              incoherent rays from anywhere in the box (43% hit the bunny, 60% the torus).
// Any-hit ("shadow") queries use the same rays with tmax = inf (not shortened to
// the closest hit: that would make every ray unoccluded). So any-hit measures an
// occlusion query that may stop at the first triangle found.
//
// Threading: trace_parallel() splits the rays statically into chunks of
// kChunkRays consecutive rays dealt round-robin to T std::threads (raykit's
// parallel_chunks), the same scheme for raykit and Embree. Round-robin keeps
// the two threads' loads balanced on primary rays, where one half of the
// image may be sky.
#pragma once

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <mutex>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/scene/generate.hpp"

#ifdef RAYKIT_HAVE_EMBREE
#include <embree3/rtcore.h>
#endif

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

namespace rkbench {

inline constexpr std::size_t kImageSize = 512;
inline constexpr std::size_t kRayCount = kImageSize * kImageSize;
inline constexpr std::size_t kChunkRays = 256;

inline const std::vector<std::string>& scene_names() {
    static const std::vector<std::string> names{"bunny", "torus100k", "torus1M"};
    return names;
}
inline const std::vector<std::string>& ray_set_names() {
    static const std::vector<std::string> names{"primary", "tiles", "random"};
    return names;
}

inline std::filesystem::path bunny_path() {
    return std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / "obj" / "stanford_bunny" / "stanford-bunny.obj";
}
inline std::filesystem::path thesis_scene_path() {
    return std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / "obj" / "thesis_scene" / "Scene.obj";
}

/// One scene: its mesh and what benchmarks derive from it, each made once.
struct Scene {
    std::string name;
    raykit::Mesh mesh;
    raykit::AABB bounds;
    raykit::PrimitiveRefs refs;  ///< per-triangle boxes and centroids

    std::size_t triangles() const { return mesh.triangles.size(); }
};

namespace detail {
inline std::mutex& cache_mutex() {
    static std::mutex m;
    return m;
}
}  // namespace detail

/// The scene called `name`, or nullptr when its data file is missing.
/// Throws std::invalid_argument for an unknown name.
inline const Scene* scene(const std::string& name) {
    static std::map<std::string, std::unique_ptr<Scene>> cache;
    std::lock_guard lock(detail::cache_mutex());
    if (auto it = cache.find(name); it != cache.end()) return it->second.get();
    auto s = std::make_unique<Scene>();
    s->name = name;
    if (name == "bunny" || name == "thesis") {
        const std::filesystem::path p = name == "bunny" ? bunny_path() : thesis_scene_path();
        if (!std::filesystem::exists(p)) {
            cache[name] = nullptr;
            return nullptr;
        }
        s->mesh = raykit::load_obj(p);
    } else if (name == "torus100k") {
        s->mesh = raykit::make_bumpy_torus(100000);
    } else if (name == "torus1M") {
        s->mesh = raykit::make_bumpy_torus(1000000);
    } else if (name == "torus4M") {
        s->mesh = raykit::make_bumpy_torus(4000000);
    } else if (name == "torus16M") {
        s->mesh = raykit::make_bumpy_torus(16000000);
    } else {
        throw std::invalid_argument("rkbench::scene: unknown scene " + name);
    }
    s->refs = raykit::primitive_refs(s->mesh);
    for (const raykit::AABB& b : s->refs.boxes) s->bounds.grow(b);
    return (cache[name] = std::move(s)).get();
}

/// scene(name), or marks the benchmark as skipped (SkipWithError) and returns nullptr.
inline const Scene* scene_or_skip(benchmark::State& state, const std::string& name) {
    const Scene* s = scene(name);
    if (!s) {
        const std::string msg = name + ": " + (name == "thesis" ? thesis_scene_path() : bunny_path()).string() + " not found";
        state.SkipWithError(msg.c_str());
    }
    return s;
}

inline std::vector<raykit::Ray> make_primary_rays(const raykit::AABB& box) {
    using raykit::vec3;
    const vec3 c = box.center();
    const float diag = glm::length(box.max - box.min);
    const vec3 eye = c + glm::normalize(vec3(1.0f, 0.6f, 0.8f)) * (1.5f * diag);
    const vec3 fwd = glm::normalize(c - eye);
    const vec3 right = glm::normalize(glm::cross(fwd, vec3(0.0f, 1.0f, 0.0f)));
    const vec3 up = glm::cross(right, fwd);
    const float half = std::tan(0.5f * 45.0f * 3.14159265358979f / 180.0f);  // square image: same both ways
    std::vector<raykit::Ray> rays(kRayCount);
    for (std::size_t y = 0; y < kImageSize; ++y)
        for (std::size_t x = 0; x < kImageSize; ++x) {
            const float sx = (2.0f * (float(x) + 0.5f) / float(kImageSize) - 1.0f) * half;
            const float sy = (1.0f - 2.0f * (float(y) + 0.5f) / float(kImageSize)) * half;
            raykit::Ray& r = rays[y * kImageSize + x];
            r.org = eye;
            r.dir = glm::normalize(fwd + sx * right + sy * up);
            r.tmin = 0.0f;
            r.tmax = raykit::kInf;
        }
    return rays;
}

inline std::vector<raykit::Ray> make_random_rays(const raykit::AABB& box, std::uint64_t seed) {
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    std::vector<raykit::Ray> rays(kRayCount);
    for (raykit::Ray& r : rays) {
        const raykit::vec3 t(U(rng), U(rng), U(rng));
        r.org = box.min + t * (box.max - box.min);
        const float z = 2.0f * U(rng) - 1.0f;
        const float phi = 6.28318530717958647692f * U(rng);
        const float s = std::sqrt(std::max(0.0f, 1.0f - z * z));
        r.dir = raykit::vec3(s * std::cos(phi), s * std::sin(phi), z);
        r.tmin = 0.0f;
        r.tmax = raykit::kInf;
    }
    return rays;
}

/// The camera rays of make_primary_rays in 4×4-pixel tiles (tile after tile, each row by row):
/// the renderer's order, in which a batch's 16 consecutive rays are one tile (render_cpu.hpp);
/// "primary" keeps rows, where 16 consecutive rays are a 16 × 1 strip.
inline std::vector<raykit::Ray> make_tile_rays(const raykit::AABB& box) {
    const std::vector<raykit::Ray> rows = make_primary_rays(box);
    std::vector<raykit::Ray> rays;
    rays.reserve(rows.size());
    for (std::size_t ty = 0; ty < kImageSize; ty += 4)
        for (std::size_t tx = 0; tx < kImageSize; tx += 4)
            for (std::size_t y = ty; y < ty + 4; ++y)
                for (std::size_t x = tx; x < tx + 4; ++x) rays.push_back(rows[y * kImageSize + x]);
    return rays;
}

/// Ray set `set` ("primary", "tiles" or "random") for scene `s`, made once.
inline const std::vector<raykit::Ray>& rays(const Scene& s, const std::string& set) {
    static std::map<std::pair<std::string, std::string>, std::unique_ptr<std::vector<raykit::Ray>>> cache;
    std::lock_guard lock(detail::cache_mutex());
    auto& slot = cache[{s.name, set}];
    if (!slot) {
        if (set == "primary") {
            slot = std::make_unique<std::vector<raykit::Ray>>(make_primary_rays(s.bounds));
        } else if (set == "tiles") {
            slot = std::make_unique<std::vector<raykit::Ray>>(make_tile_rays(s.bounds));
        } else if (set == "random") {
            std::uint64_t seed = 0x9E3779B97F4A7C15ull;
            for (char ch : s.name) seed = seed * 1099511628211ull + static_cast<unsigned char>(ch);
            slot = std::make_unique<std::vector<raykit::Ray>>(make_random_rays(s.bounds, seed));
        } else {
            throw std::invalid_argument("rkbench::rays: unknown ray set " + set);
        }
    }
    return *slot;
}

/// raykit BVH over `s` with BinnedSahBuilder and its default Config, built once.
inline const raykit::Bvh& raykit_bvh(const Scene& s) {
    static std::map<std::string, std::unique_ptr<raykit::Bvh>> cache;
    std::lock_guard lock(detail::cache_mutex());
    auto& slot = cache[s.name];
    if (!slot) slot = std::make_unique<raykit::Bvh>(raykit::BinnedSahBuilder::build(s.refs.boxes, s.refs.centers));
    return *slot;
}

/// raykit_bvh(s) collapsed to a 4-wide tree, built once.
inline const raykit::WideBvh& raykit_wide_bvh(const Scene& s) {
    const raykit::Bvh& bvh = raykit_bvh(s);
    static std::map<std::string, std::unique_ptr<raykit::WideBvh>> cache;
    std::lock_guard lock(detail::cache_mutex());
    auto& slot = cache[s.name];
    if (!slot) slot = std::make_unique<raykit::WideBvh>(raykit::WideBvh::build(bvh));
    return *slot;
}

/// raykit_bvh(s) collapsed to an 8-wide tree, built once.
inline const raykit::WideBvh8& raykit_wide8_bvh(const Scene& s) {
    const raykit::Bvh& bvh = raykit_bvh(s);
    static std::map<std::string, std::unique_ptr<raykit::WideBvh8>> cache;
    std::lock_guard lock(detail::cache_mutex());
    auto& slot = cache[s.name];
    if (!slot) slot = std::make_unique<raykit::WideBvh8>(raykit::WideBvh8::build(bvh));
    return *slot;
}

/// BlockBvh8 over s: a binned-SAH tree built for 4-triangle blocks
/// (BlockBvh8::sah_config()), collapsed 8-wide, made once.
inline const raykit::BlockBvh8& raykit_block8_bvh(const Scene& s) {
    static std::map<std::string, std::unique_ptr<raykit::BlockBvh8>> cache;
    std::lock_guard lock(detail::cache_mutex());
    auto& slot = cache[s.name];
    if (!slot) slot = std::make_unique<raykit::BlockBvh8>(raykit::BlockBvh8::build(raykit::MeshView(s.mesh)));
    return *slot;
}

/// fn(begin, end) over [0, n) in chunks of kChunkRays dealt round-robin to `threads` threads.
template <class Fn>
void trace_parallel(std::size_t n, unsigned threads, Fn&& fn) {
    const std::size_t chunks = (n + kChunkRays - 1) / kChunkRays;
    raykit::parallel_chunks(n, chunks, threads, [&](std::size_t, std::size_t b, std::size_t e) { fn(b, e); });
}

#ifdef RAYKIT_HAVE_EMBREE

namespace detail {
struct EmbreeErrors {
    std::mutex m;
    std::string first;
};
inline EmbreeErrors& embree_errors() {
    static EmbreeErrors e;
    return e;
}
}  // namespace detail

/// Keeps the first Embree error message until take_embree_error() collects it.
inline void record_embree_error(const std::string& msg) {
    auto& e = detail::embree_errors();
    std::lock_guard lock(e.m);
    if (e.first.empty()) e.first = msg;
}
/// The first Embree error reported since the last call ("" if none). Embree
/// reports errors through a callback (possibly on one of its own threads), so
/// benchmarks poll this after their Embree calls.
inline std::string take_embree_error() {
    auto& e = detail::embree_errors();
    std::lock_guard lock(e.m);
    std::string out;
    out.swap(e.first);
    return out;
}

/// An Embree device; released with the object.
struct EmbreeDevice {
    RTCDevice device = nullptr;
    explicit EmbreeDevice(const char* config = nullptr) : device(rtcNewDevice(config)) {
        if (!device) throw std::runtime_error(std::string("rtcNewDevice failed: ") + (config ? config : "(default)"));
        rtcSetDeviceErrorFunction(
            device,
            [](void*, RTCError code, const char* msg) {
                record_embree_error("Embree error " + std::to_string(int(code)) + ": " + (msg ? msg : ""));
            },
            nullptr);
    }
    EmbreeDevice(const EmbreeDevice&) = delete;
    EmbreeDevice& operator=(const EmbreeDevice&) = delete;
    ~EmbreeDevice() {
        if (device) rtcReleaseDevice(device);
    }
};

/// The process-wide default-config device used for tracing (all hardware threads for builds).
inline RTCDevice default_embree_device() {
    static EmbreeDevice dev;
    return dev.device;
}

/// Vertex positions as Embree wants a shared FLOAT3 buffer: 16-byte stride and one
/// extra element, so that a 16-byte load of the last vertex stays in the buffer.
struct alignas(16) EmbreeVertex {
    float x, y, z, pad;
};
inline std::vector<EmbreeVertex> embree_vertices(const raykit::Mesh& m) {
    std::vector<EmbreeVertex> v(m.positions.size() + 1, EmbreeVertex{0, 0, 0, 0});
    for (std::size_t i = 0; i < m.positions.size(); ++i) v[i] = {m.positions[i].x, m.positions[i].y, m.positions[i].z, 0};
    return v;
}

/// A committed Embree scene with one triangle geometry (geomID 0) over `m`, the scene and
/// the geometry both at `quality`, as Embree's users set it: with only the scene's quality
/// set, the geometry stays MEDIUM and "LOW" timed a MEDIUM build (bunny 11.9 ms against
/// 3.8 ms for Embree's real LOW Morton build, 2 threads, measured in issue 14).
/// `verts` (from embree_vertices) and m.triangles are shared, not copied: both
/// must outlive the scene. The caller releases the scene.
inline RTCScene make_embree_scene(RTCDevice dev, const raykit::Mesh& m, const std::vector<EmbreeVertex>& verts,
                                  RTCBuildQuality quality) {
    RTCScene sc = rtcNewScene(dev);
    rtcSetSceneBuildQuality(sc, quality);
    RTCGeometry g = rtcNewGeometry(dev, RTC_GEOMETRY_TYPE_TRIANGLE);
    rtcSetGeometryBuildQuality(g, quality);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, verts.data(), 0,
                               sizeof(EmbreeVertex), m.positions.size());
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, m.triangles.data(), 0,
                               sizeof(raykit::Triangle), m.triangles.size());
    rtcCommitGeometry(g);
    rtcAttachGeometryByID(sc, g, 0);
    rtcReleaseGeometry(g);
    rtcCommitScene(sc);
    return sc;
}

inline RTCRayHit to_embree(const raykit::Ray& r) {
    RTCRayHit rh;
    rh.ray.org_x = r.org.x;
    rh.ray.org_y = r.org.y;
    rh.ray.org_z = r.org.z;
    rh.ray.tnear = r.tmin;
    rh.ray.dir_x = r.dir.x;
    rh.ray.dir_y = r.dir.y;
    rh.ray.dir_z = r.dir.z;
    rh.ray.time = 0.0f;
    rh.ray.tfar = r.tmax;
    rh.ray.mask = 0xFFFFFFFFu;
    rh.ray.id = 0;
    rh.ray.flags = 0;
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.primID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    return rh;
}

/// Lane k of a 16-ray packet from `r` (mask all, id k).
inline void set_lane(RTCRay16& p, unsigned k, const raykit::Ray& r) {
    p.org_x[k] = r.org.x, p.org_y[k] = r.org.y, p.org_z[k] = r.org.z, p.tnear[k] = r.tmin;
    p.dir_x[k] = r.dir.x, p.dir_y[k] = r.dir.y, p.dir_z[k] = r.dir.z, p.time[k] = 0.0f;
    p.tfar[k] = r.tmax, p.mask[k] = 0xFFFFFFFFu, p.id[k] = k, p.flags[k] = 0;
}

/// A context for packets of neighbouring rays (a tile's camera rays, shadow rays to one
/// light), so Embree may trace them as coherent packets.
inline RTCIntersectContext coherent_context() {
    RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    ctx.flags = RTC_INTERSECT_CONTEXT_FLAG_COHERENT;
    return ctx;
}

#endif  // RAYKIT_HAVE_EMBREE

}  // namespace rkbench
