// raykit/render/shade.hpp — what the shaders see: the scene view (ShadeScene), lights, settings,
// counters, the surface at a hit (surface_point) and the two scene queries (Tracer).
//
//   Scene sc;  sc.add_instance(sc.add_object(mesh));  sc.update_top_level();   // scene/scene.hpp
//   std::vector<MaterialTable> mt{make_material_table(sc.objects()[0].mesh)};   // one per object
//   std::vector<Light> lights{Light::point({0, 5, 0}, vec3(1))};
//   ShadeScene scene = make_shade_scene(sc, mt, lights);             // non-owning view
//
// The shaders themselves are ray hooks: the built-in ones (whitted, normals, depth, ao,
// debug-cost) in render/shaders.hpp, run per sample by the hooks' one driver, shade_hook
// (render/ray_hook.hpp); render_cpu (render_cpu.hpp) renders with either.
//
// Geometry
// --------
//  * Scenes: every query is a Scene query (objects, instances, the top-level tree; the object
//    trees walked are ShadeScene::trees). Surfaces are computed in object space and mapped to
//    the world by the instance's transform (normals by its inverse transpose, renormalised);
//    an identity instance is not mapped, so a one-object scene shades as its mesh alone.
//  * Shading normal: the interpolated vertex normals when the mesh has them (and they do not
//    cancel), else the geometric normal; both flipped to face the incoming ray.
//  * Inside/outside for refraction: the side of the interpolated vertex normal when present,
//    else the side given by the triangle's winding (counter-clockwise = front).
//  * Texture coordinates: interpolated per vertex (0, 0) when the mesh has none.
//  * Alpha cut-outs: triangles whose material's map_Kd has alpha < 0.5 at the hit are skipped
//    inside the traversal itself (for closest-hit and any-hit queries alike), so the ray simply
//    continues through foliage cut-outs; scenes without such materials pay nothing.
//  * Secondary ray origins use offset_ray_origin (math/offset.hpp) on the side the ray leaves to.
//  * Triangle test: raykit's default (Watertight); ties as in scene/trace.hpp (smaller index wins).
#pragma once

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "raykit/bvh/traverse.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/math/offset.hpp"
#include "raykit/render/material.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/scene/scene.hpp"

namespace raykit {

enum class ShaderKind { whitted, normals, depth, ao, debug_cost };

inline const char* shader_name(ShaderKind k) noexcept {
    switch (k) {
        case ShaderKind::normals: return "normals";
        case ShaderKind::depth: return "depth";
        case ShaderKind::ao: return "ao";
        case ShaderKind::debug_cost: return "debug-cost";
        default: return "whitted";
    }
}
/// "whitted", "normals", "depth", "ao", "debug-cost"; throws std::invalid_argument otherwise.
inline ShaderKind parse_shader(std::string_view s) {
    if (s == "whitted") return ShaderKind::whitted;
    if (s == "normals") return ShaderKind::normals;
    if (s == "depth") return ShaderKind::depth;
    if (s == "ao") return ShaderKind::ao;
    if (s == "debug-cost" || s == "debug_cost") return ShaderKind::debug_cost;
    throw std::invalid_argument("unknown shader '" + std::string(s) +
                                "' (known: whitted, normals, depth, ao, debug-cost)");
}

/// A light without distance falloff: `color` is the radiance scale it contributes.
struct Light {
    enum class Type { point, directional };
    Type type = Type::point;
    vec3 position{0.0f};               ///< point lights
    vec3 direction{0.0f, -1.0f, 0.0f};  ///< directional lights: the direction the light travels
    vec3 color{1.0f};

    static Light point(vec3 p, vec3 c = vec3(1.0f)) { return {Type::point, p, vec3(0.0f, -1.0f, 0.0f), c}; }
    static Light directional(vec3 dir, vec3 c = vec3(1.0f)) { return {Type::directional, vec3(0.0f), dir, c}; }
};

/// The shadow ray toward light `l` from `org`: unit direction `dir` and `tmax` = distance ·
/// (1 - 1e-4) for a point light (the light's own position is not an occluder), infinity for a
/// directional one. False for a degenerate light (at `org`, or a zero direction).
inline bool light_ray(const Light& l, const vec3& org, vec3& dir, float& tmax) noexcept {
    if (l.type == Light::Type::point) {
        const vec3 to = l.position - org;
        const float dist = glm::length(to);
        if (!(dist > 0.0f)) return false;
        dir = to / dist;
        tmax = dist * (1.0f - 1e-4f);
        return true;
    }
    const float ll = glm::length(l.direction);
    if (!(ll > 0.0f)) return false;
    dir = -l.direction / ll;
    tmax = kInf;
    return true;
}

struct ShadeSettings {
    ShaderKind shader = ShaderKind::whitted;
    unsigned max_depth = 5;        ///< reflection/refraction bounces after the camera ray (0 = none)
    vec3 ambient{0.1f};            ///< ambient light (times the diffuse colour)
    vec3 background{0.0f};         ///< radiance of rays that hit nothing
    TextureFilter filter = TextureFilter::bilinear;
    bool shadows = true;           ///< trace shadow rays (false: every light is visible)
    unsigned ao_samples = 16;      ///< ao: rays per camera ray
    float ao_radius = 0.0f;        ///< ao: occlusion distance; 0 = 0.1 · scene diagonal
    float depth_far = 0.0f;        ///< depth: distance mapped to 0; 0 = farthest scene corner
    float min_weight = 1e-3f;      ///< whitted: child rays below this weight are not traced
};

/// `s` with its scene-dependent defaults made explicit, the one rule of the CPU and device
/// renderers: depth_far 0 becomes the distance from `eye` to the farthest corner of `bounds`,
/// ao_radius 0 becomes 0.1 · the diagonal of `bounds` (infinity when that is 0).
inline ShadeSettings resolve_shade_settings(ShadeSettings s, const AABB& bounds, const vec3& eye) noexcept {
    if (!(s.depth_far > 0.0f)) {
        float far = 0.0f;
        for (int c = 0; c < 8; ++c) {
            const vec3 corner((c & 1) ? bounds.max.x : bounds.min.x, (c & 2) ? bounds.max.y : bounds.min.y,
                              (c & 4) ? bounds.max.z : bounds.min.z);
            far = std::max(far, glm::length(corner - eye));
        }
        s.depth_far = far;
    }
    if (!(s.ao_radius > 0.0f)) {
        s.ao_radius = 0.1f * glm::length(bounds.extent());
        if (!(s.ao_radius > 0.0f)) s.ao_radius = kInf;
    }
    return s;
}

/// Rays traced, by kind.
struct RayCounts {
    std::uint64_t primary = 0, shadow = 0, reflection = 0, refraction = 0, ao = 0;
    std::uint64_t total() const noexcept { return primary + shadow + reflection + refraction + ao; }
    RayCounts& operator+=(const RayCounts& o) noexcept {
        primary += o.primary, shadow += o.shadow, reflection += o.reflection, refraction += o.refraction, ao += o.ao;
        return *this;
    }
};

/// A cheap timestamp for stage timing: the CPU's time-stamp counter on x86 (a few ns to read;
/// constant-rate on every x86 CPU of the last 15 years), else steady_clock nanoseconds. Only
/// differences mean something; render_cpu converts them to milliseconds against steady_clock.
inline std::uint64_t stage_ticks() noexcept {
#if (defined(__GNUC__) || defined(__clang__)) && (defined(__x86_64__) || defined(__i386__))
    return __builtin_ia32_rdtsc();
#else
    return std::uint64_t(std::chrono::duration_cast<std::chrono::nanoseconds>(
                             std::chrono::steady_clock::now().time_since_epoch())
                             .count());
#endif
}

/// Per-bounce statistics keep this many slots: bounces 0, 1, 2 and "3 or deeper" (bounce 0 =
/// the camera ray and the shadow / ambient-occlusion rays from its hit; bounce k = the
/// reflection and refraction rays of depth k and the shadow rays from their hits).
inline constexpr unsigned kBounceSlots = 4;
/// The slot of bounce `depth`.
constexpr unsigned bounce_slot(unsigned depth) noexcept { return depth < kBounceSlots ? depth : kBounceSlots - 1; }

/// Thread time spent in the traversals, in stage_ticks() units (filled only when
/// ShadeCounters::time_stages is set).
struct StageTimes {
    std::uint64_t trace_ticks = 0;   ///< closest-hit queries (camera, reflection, refraction rays)
    std::uint64_t shadow_ticks = 0;  ///< any-hit queries (shadow and ambient-occlusion rays)
    std::uint64_t bounce_ticks[kBounceSlots] = {};  ///< closest- and any-hit queries per bounce slot
    StageTimes& operator+=(const StageTimes& o) noexcept {
        trace_ticks += o.trace_ticks, shadow_ticks += o.shadow_ticks;
        for (unsigned i = 0; i < kBounceSlots; ++i) bounce_ticks[i] += o.bounce_ticks[i];
        return *this;
    }
};

/// What shade_ray adds to as it works (one per thread; merge with +=).
struct ShadeCounters {
    RayCounts rays;
    std::uint64_t bounce_rays[kBounceSlots] = {};  ///< rays traced (all kinds) per bounce slot
    std::uint64_t traversal_steps = 0;  ///< debug_cost only: inner nodes + leaves of camera rays
    unsigned deepest = 0;               ///< largest bounce depth reached by a traced ray
    bool time_stages = false;           ///< measure StageTimes (two stage_ticks() reads per query)
    StageTimes times;
    ShadeCounters& operator+=(const ShadeCounters& o) noexcept {
        rays += o.rays;
        for (unsigned i = 0; i < kBounceSlots; ++i) bounce_rays[i] += o.bounce_rays[i];
        traversal_steps += o.traversal_steps;
        deepest = std::max(deepest, o.deepest);
        times += o.times;
        return *this;
    }
};

/// World box of a scene: its identity instances' tree root boxes (the triangles' finite
/// bounds) and the world boxes (Scene::world_box) of the others — the device renderer's rule
/// too (cl/render.hpp), and O(instances): static geometry is not read again each frame.
inline AABB scene_bounds(const Scene& scene) {
    AABB b;
    for (std::uint32_t i = 0; i < scene.instances().size(); ++i) {
        const SceneInstance& in = scene.instances()[i];
        b.grow(in.identity ? scene.objects()[in.object].bounds() : scene.world_box(i));
    }
    return b;
}

/// Non-owning view of everything the shaders read. Make it with make_shade_scene.
struct ShadeScene {
    const Scene* scene = nullptr;
    std::span<const MaterialTable> materials;  ///< one per object of the scene, in object order
    std::span<const Light> lights;
    AABB bounds;                 ///< scene_bounds() (depth and ao defaults)
    bool alpha_testing = false;  ///< some material is alpha-tested
    SceneTrees trees = SceneTrees::blocks;  ///< what the traversals walk (blocks: also the device's trees and node counts)

    /// The mesh of instance `inst`'s object.
    const Mesh& mesh_of(std::uint32_t inst) const noexcept { return scene->objects()[scene->instances()[inst].object].mesh; }
    /// The material of triangle `prim` of instance `inst`'s object.
    const RenderMaterial& material_of(std::uint32_t inst, std::uint32_t prim) const noexcept {
        const std::uint32_t o = scene->instances()[inst].object;
        return materials[o].for_triangle(scene->objects()[o].mesh, prim);
    }
};

/// Checks the parts fit together and fills bounds and alpha_testing. Throws
/// std::invalid_argument when there is not one material table per object, and
/// std::logic_error when the scene's top-level tree is stale (update_top_level()).
/// All arguments must outlive the returned view; make it again after the scene changes.
inline ShadeScene make_shade_scene(const Scene& scene, std::span<const MaterialTable> materials,
                                   std::span<const Light> lights) {
    if (materials.size() != scene.objects().size())
        throw std::invalid_argument("raykit::make_shade_scene: one MaterialTable per object needed (" +
                                    std::to_string(scene.objects().size()) + " objects, " +
                                    std::to_string(materials.size()) + " tables)");
    if (scene.stale()) throw std::logic_error("raykit::make_shade_scene: call Scene::update_top_level() first");
    ShadeScene s;
    s.scene = &scene;
    s.materials = materials;
    s.lights = lights;
    s.bounds = scene_bounds(scene);
    for (const MaterialTable& m : materials) s.alpha_testing = s.alpha_testing || m.any_alpha_tested();
    return s;
}

/// Small deterministic generator (splitmix64). Seed it from (pixel, sample) for images that do
/// not depend on the thread count.
struct SampleRng {
    std::uint64_t state = 0;
    explicit SampleRng(std::uint64_t seed = 0) noexcept : state(seed) {}
    std::uint64_t next_u64() noexcept {
        std::uint64_t z = (state += 0x9E3779B97F4A7C15ull);
        z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
        z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
        return z ^ (z >> 31);
    }
    /// Uniform in [0, 1).
    float next_float() noexcept { return float(next_u64() >> 40) * (1.0f / 16777216.0f); }
};

/// Mixes several 64-bit values into a seed (splitmix64 finaliser over a running hash).
inline std::uint64_t hash_seed(std::uint64_t a, std::uint64_t b = 0, std::uint64_t c = 0) noexcept {
    SampleRng r(a * 0xD6E8FEB86659FD93ull ^ b);
    r.state ^= r.next_u64() + c * 0x9E3779B97F4A7C15ull;
    return r.next_u64();
}

struct SampleResult {
    vec3 color{0.0f};
    float alpha = 0.0f;  ///< 1 when the camera ray hit geometry
    float cost = 0.0f;   ///< debug_cost: traversal steps of the camera ray
};

/// The surface at a hit, as the shaders see it.
struct SurfacePoint {
    vec3 p{0.0f};       ///< position (barycentric interpolation of the vertices)
    vec3 ng{0.0f};      ///< unit geometric normal, facing the incoming ray
    vec3 ns{0.0f};      ///< unit shading normal, facing the incoming ray
    vec2 uv{0.0f};
    bool entering = true;  ///< the ray arrives from the outside (see "Geometry" above)
    const RenderMaterial* material = nullptr;
    vec3 base{0.0f};    ///< Kd times the map_Kd colour
    vec3 d{0.0f};       ///< unit direction of the incoming ray
};

namespace detail {

inline float max3(const vec3& v) noexcept { return std::max(v.x, std::max(v.y, v.z)); }

/// Texture coordinates of triangle `prim` at barycentrics (u, v).
inline vec2 interpolate_uv(const Mesh& m, std::uint32_t prim, float u, float v) noexcept {
    if (m.texcoords.empty()) return vec2(0.0f);
    const Triangle& t = m.triangles[prim];
    return m.texcoords[t.v[0]] * (1.0f - u - v) + m.texcoords[t.v[1]] * u + m.texcoords[t.v[2]] * v;
}

/// True when the hit (inst, prim, u, v) lies on a cut-out texel of an alpha-tested material.
inline bool cut_out(const ShadeScene& s, TextureFilter f, std::uint32_t inst, std::uint32_t prim, float u,
                    float v) noexcept {
    const RenderMaterial& m = s.material_of(inst, prim);
    if (!m.alpha_tested) return false;
    return m.map_kd->sample_alpha(interpolate_uv(s.mesh_of(inst), prim, u, v), f) < 0.5f;
}

/// The shaders' queries (closest hits of a ray or a batch, any hits of a batch: shadow rays are
/// always batched): Scene queries over the chosen object trees, alpha cut-outs
/// filtered inside the walk when kAlpha.
template <SceneTrees kTrees, bool kAlpha>
struct Tracer {
    const ShadeScene& s;
    TextureFilter filter;

    RAYKIT_INLINE auto keep() const noexcept {
        if constexpr (kAlpha)
            return [this](std::uint32_t inst, std::uint32_t p, float u, float v) {
                return !cut_out(s, filter, inst, p, u, v);
            };
        else
            return AcceptAll{};
    }
    template <class Stats = std::nullptr_t>
    Hit closest(const Ray& ray, Stats stats = nullptr) const {
        return s.scene->template intersect_closest<kTrees>(ray, keep(), stats);
    }
    void closest_batch(std::span<const Ray> rays, std::span<Hit> hits) const {
        s.scene->template intersect_closest<kTrees>(rays, hits, keep());
    }
    void any_batch(std::span<const Ray> rays, std::span<std::uint8_t> blocked) const {
        s.scene->template intersect_any<kTrees>(rays, blocked, keep());
    }
};

/// Times a callable into `ticks` and `bounce_ticks` (stage_ticks units) when `on`.
template <class F>
RAYKIT_INLINE auto timed(bool on, std::uint64_t& ticks, std::uint64_t& bounce_ticks, F&& f) {
    if (!on) return f();
    const std::uint64_t t0 = stage_ticks();
    auto r = f();
    const std::uint64_t dt = stage_ticks() - t0;
    ticks += dt;
    bounce_ticks += dt;
    return r;
}

/// Schlick's approximation with normal-incidence reflectance f0.
inline vec3 schlick(const vec3& f0, float cos_i) noexcept {
    const float m = std::clamp(1.0f - cos_i, 0.0f, 1.0f);
    const float m5 = m * m * m * m * m;
    return f0 + (vec3(1.0f) - f0) * m5;
}

/// Exact Fresnel reflectance of an unpolarised ray at a dielectric boundary; eta = n_from / n_to,
/// cos_i = cosine of the incidence angle (> 0). Writes the cosine of the refraction angle;
/// returns 1 on total internal reflection.
inline float fresnel_dielectric(float cos_i, float eta, float& cos_t) noexcept {
    cos_i = std::clamp(cos_i, 0.0f, 1.0f);
    const float sin2_t = eta * eta * std::max(0.0f, 1.0f - cos_i * cos_i);
    if (sin2_t >= 1.0f) {
        cos_t = 0.0f;
        return 1.0f;
    }
    cos_t = std::sqrt(1.0f - sin2_t);
    const float rs = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float rp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

/// An orthonormal basis (t, b) around unit n (Duff et al. 2017).
inline void basis(const vec3& n, vec3& t, vec3& b) noexcept {
    const float sign = std::copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float bb = n.x * n.y * a;
    t = vec3(1.0f + sign * n.x * n.x * a, sign * bb, -sign * n.x);
    b = vec3(bb, sign + n.y * n.y * a, -n.y);
}

}  // namespace detail

/// The surface seen by `ray` at `hit` (which must be valid, h.inst set); `d` is the unit
/// world ray direction.
inline SurfacePoint surface_point(const ShadeScene& s, const Hit& hit, const vec3& d, TextureFilter filter) {
    const SceneInstance& in = s.scene->instances()[hit.inst];
    const Mesh& m = s.scene->objects()[in.object].mesh;
    const Triangle& t = m.triangles[hit.prim];
    const float w0 = 1.0f - hit.u - hit.v;
    const vec3 &p0 = m.positions[t.v[0]], &p1 = m.positions[t.v[1]], &p2 = m.positions[t.v[2]];
    // object space -> world: points by the transform, normals by its inverse transpose
    const auto normal_to_world = [&](const vec3& n) {
        if (in.identity) return n;
        const float* a = in.to_object.m;
        return vec3(a[0] * n.x + a[4] * n.y + a[8] * n.z, a[1] * n.x + a[5] * n.y + a[9] * n.z,
                    a[2] * n.x + a[6] * n.y + a[10] * n.z);
    };
    SurfacePoint sp;
    sp.d = d;
    sp.p = p0 * w0 + p1 * hit.u + p2 * hit.v;
    if (!in.identity) sp.p = in.to_world.point(sp.p);
    vec3 ng = normal_to_world(glm::cross(p1 - p0, p2 - p0));
    const float lg = glm::length(ng);
    ng = lg > 0.0f && std::isfinite(lg) ? ng / lg : -d;
    bool entering = glm::dot(ng, d) < 0.0f;
    vec3 ns = ng;
    if (!m.normals.empty()) {
        const vec3 n = normal_to_world(m.normals[t.v[0]] * w0 + m.normals[t.v[1]] * hit.u + m.normals[t.v[2]] * hit.v);
        const float ln = glm::length(n);
        if (ln > 1e-12f && std::isfinite(ln)) {
            ns = n / ln;
            entering = glm::dot(ns, d) < 0.0f;
        }
    }
    sp.entering = entering;
    sp.ng = glm::dot(ng, d) > 0.0f ? -ng : ng;
    sp.ns = glm::dot(ns, d) > 0.0f ? -ns : ns;
    sp.uv = detail::interpolate_uv(m, hit.prim, hit.u, hit.v);
    sp.material = &s.materials[in.object].for_triangle(m, hit.prim);
    sp.base = sp.material->kd;
    if (sp.material->map_kd) sp.base *= vec3(sp.material->map_kd->sample(sp.uv, filter));
    return sp;
}

/// Closest hit of `ray` as the shaders see it (alpha cut-outs skipped).
inline Hit shade_closest_hit(const ShadeScene& scene, const Ray& ray, TextureFilter filter = TextureFilter::bilinear) {
    if (scene.alpha_testing) return detail::Tracer<SceneTrees::blocks, true>{scene, filter}.closest(ray);
    return detail::Tracer<SceneTrees::blocks, false>{scene, filter}.closest(ray);
}

}  // namespace raykit
