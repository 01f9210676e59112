// The device renderer (raykit/cl/render.hpp) against the CPU renderer as the oracle: the same
// camera, lights and RenderSettings; per-channel difference <= 2/255 on >= 99.9 % of the pixels
// for every built-in shader (whitted, normals, depth, ao, debug-cost) at 1 and 4 jittered
// samples per pixel (and at the pixel centres), on a hand-made scene, on generated scenes and
// on the thesis scene when the shared data is there. debug-cost must agree exactly (the same
// traversal steps), camera rays bit for bit (PixelSampler). Plus ray hooks: a build error names
// the hook's line, a hook that emits nothing ends after one bounce, the depth limit, empty
// scenes and no lights, queue memory independent of spp. Scenes of several objects and
// instances (rotations past pi, non-uniform scales; a DeviceScene held by the caller), and a
// dynamic scene moved by a vertex hook on the device and rendered there (no read-back) against
// the CPU Scene moved by the hook's CPU twin.
//
// Every test skips (GTEST_SKIP) only when there is no OpenCL device.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#ifndef RAYKIT_CLI_HAVE_CL
#define RAYKIT_CLI_HAVE_CL 1  // the --device cl branch of `raykit render`
#endif
#include "../examples/cli_render.hpp"
#include "../examples/fog_hook.hpp"
#include "raykit.hpp"
#include "test_support.hpp"
#include "test_device_support.hpp"
#include "raykit/cl.hpp"
#include "raykit/cl/render.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/scene/generate.hpp"

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

using namespace raykit;
namespace rcl = raykit::cl;

namespace {

using raykit::test::test_device;

#define RAYKIT_REQUIRE_DEVICE(dev)                                                       \
    std::string no_device_reason_;                                                       \
    rcl::Device* dev##_ptr_ = test_device(&no_device_reason_);                          \
    if (!dev##_ptr_) GTEST_SKIP() << "no OpenCL device, skipping: " << no_device_reason_; \
    rcl::Device& dev = *dev##_ptr_

struct SceneBuilder {
    Mesh m;
    std::uint32_t material(const Material& mat) {
        m.materials.push_back(mat);
        return std::uint32_t(m.materials.size() - 1);
    }
    std::uint32_t vertex(vec3 p, vec2 uv) {
        m.positions.push_back(p);
        m.texcoords.push_back(uv);
        return std::uint32_t(m.positions.size() - 1);
    }
    void quad(vec3 a, vec3 b, vec3 c, vec3 d, std::uint32_t mat, float uv_scale = 1.0f) {
        const std::uint32_t i = vertex(a, vec2(0, 0) * uv_scale), j = vertex(b, vec2(1, 0) * uv_scale),
                            k = vertex(c, vec2(1, 1) * uv_scale), l = vertex(d, vec2(0, 1) * uv_scale);
        m.triangles.push_back({{i, j, k}});
        m.triangles.push_back({{i, k, l}});
        m.material_ids.push_back(mat);
        m.material_ids.push_back(mat);
    }
    /// Appends `other` (no texcoords: gets (0.3, 0.7)) with material `mat`, scaled and moved.
    void add(const Mesh& other, std::uint32_t mat, float scale, vec3 offset) {
        const auto base = std::uint32_t(m.positions.size());
        for (const vec3& p : other.positions) {
            m.positions.push_back(p * scale + offset);
            m.texcoords.push_back(vec2(0.3f, 0.7f));
        }
        for (const Triangle& t : other.triangles) {
            m.triangles.push_back({{t.v[0] + base, t.v[1] + base, t.v[2] + base}});
            m.material_ids.push_back(mat);
        }
    }
};

Material make_material(vec3 kd, vec3 ks = vec3(0.0f), float ns = 0.0f, int illum = 2) {
    Material m;
    m.kd = kd;
    m.ks = ks;
    m.ns = ns;
    m.illum = illum;
    return m;
}

/// A checker texture with sRGB colours (and no cut-outs).
Texture checker(std::uint32_t w, std::uint32_t h) {
    std::vector<std::uint8_t> px(std::size_t(w) * h * 4);
    for (std::uint32_t y = 0; y < h; ++y)
        for (std::uint32_t x = 0; x < w; ++x) {
            std::uint8_t* p = &px[(std::size_t(y) * w + x) * 4];
            const bool on = ((x + y) & 1) == 0;
            p[0] = on ? 230 : 20;
            p[1] = std::uint8_t(40 + 25 * x % 200);
            p[2] = on ? 60 : 200;
            p[3] = 255;
        }
    return make_texture(w, h, std::move(px), true);
}

/// A scene, its camera and the texture its tables point to (which must live as long).
struct TexturedScene {
    Texture tex;
    RenderScene rs;
    Camera cam;
    explicit TexturedScene(Texture t) : tex(std::move(t)) {}
};

/// A test scene: a textured floor (uv 0..3: wraps), a diffuse-specular sphere, a mirror
/// sphere, a glass box, an emissive panel; two lights (point and directional).
struct TestScene : TexturedScene {
    TestScene() : TexturedScene(checker(7, 5)) {
        SceneBuilder b;
        const auto floor = b.material(make_material(vec3(0.9f)));
        const auto shiny = b.material(make_material(vec3(0.6f, 0.3f, 0.2f), vec3(0.4f), 30.0f));
        const auto mirror = b.material(make_material(vec3(0.1f), vec3(0.8f), 50.0f, 3));
        Material glass = make_material(vec3(0.0f), vec3(0.1f), 80.0f, 7);
        glass.ni = 1.5f;
        const auto glassm = b.material(glass);
        Material lamp = make_material(vec3(0.0f));
        lamp.ke = vec3(2.0f, 1.8f, 1.2f);
        const auto lampm = b.material(lamp);
        b.quad({-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4}, floor, 3.0f);
        Mesh s = make_icosphere(3);
        s.normals.clear();
        b.add(s, shiny, 0.8f, {-1.2f, 0.8f, 0.0f});
        b.add(s, mirror, 0.7f, {1.0f, 0.7f, -0.5f});
        // glass box
        const vec3 lo(-0.3f, 0.0f, 1.0f), hi(0.5f, 0.9f, 1.8f);
        b.quad({lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}, glassm);
        b.quad({hi.x, lo.y, lo.z}, {lo.x, lo.y, lo.z}, {lo.x, hi.y, lo.z}, {hi.x, hi.y, lo.z}, glassm);
        b.quad({hi.x, lo.y, hi.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {hi.x, hi.y, hi.z}, glassm);
        b.quad({lo.x, lo.y, lo.z}, {lo.x, lo.y, hi.z}, {lo.x, hi.y, hi.z}, {lo.x, hi.y, lo.z}, glassm);
        b.quad({lo.x, hi.y, hi.z}, {hi.x, hi.y, hi.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z}, glassm);
        b.quad({-3, 1, -3.5f}, {-1, 1, -3.5f}, {-1, 2.5f, -3.5f}, {-3, 2.5f, -3.5f}, lampm);
        // vertex normals for everything (radial on the spheres, face normals elsewhere)
        b.m.normals.assign(b.m.positions.size(), vec3(0.0f));
        for (const Triangle& t : b.m.triangles) {
            const vec3 n = glm::cross(b.m.positions[t.v[1]] - b.m.positions[t.v[0]],
                                      b.m.positions[t.v[2]] - b.m.positions[t.v[0]]);
            for (int c = 0; c < 3; ++c) b.m.normals[t.v[c]] += n;
        }
        rs = prepare_render_scene(std::move(b.m));
        rs.materials[0].materials[floor].map_kd = &tex;
        rs.materials[0].materials[floor].update_derived();
        rs.lights.push_back(Light::point({2.0f, 4.0f, 3.0f}, vec3(0.8f, 0.8f, 0.7f)));
        rs.lights.push_back(Light::directional({-0.3f, -1.0f, -0.4f}, vec3(0.3f, 0.3f, 0.4f)));
        cam.position = {0.5f, 2.5f, 6.0f};
        cam.target = {0.0f, 0.5f, 0.0f};
        cam.width = 96;
        cam.height = 72;
        cam.vfov_degrees = 50.0f;
    }
};

struct Diff {
    std::size_t bad = 0, total = 0;
    float worst = 0.0f;
    double fraction_ok() const { return total ? 1.0 - double(bad) / double(total) : 1.0; }
};

/// Pixels where some channel (RGB and alpha) differs by more than 2/255.
Diff compare(const Image& a, const Image& b) {
    Diff d;
    d.total = a.pixels.size();
    if (a.pixels.size() != b.pixels.size()) {
        d.bad = d.total;
        return d;
    }
    for (std::size_t i = 0; i < a.pixels.size(); ++i) {
        float w = 0.0f;
        for (int c = 0; c < 4; ++c) w = std::max(w, std::fabs(a.pixels[i][c] - b.pixels[i][c]));
        if (!(w <= 2.0f / 255.0f)) ++d.bad;
        d.worst = std::max(d.worst, w);
    }
    return d;
}

/// The CPU twin of the device renderer: the same scene walking the 8-wide block trees, the
/// shape the device walks (cl/device_tree.hpp: the same hits and the same node counts for
/// debug-cost).
ShadeScene twin_view(const RenderScene& rs) {
    ShadeScene v = rs.view();
    v.trees = SceneTrees::blocks;
    return v;
}

Image cpu_render(const RenderScene& rs, const Camera& cam, const ShadeSettings& s, RenderStats* st = nullptr) {
    RenderSettings set;
    set.spp = 1;
    set.jitter = false;
    set.threads = 2;
    set.shade = s;
    return render_cpu(twin_view(rs), cam, set, st);
}

/// Distinct RGB colours of an image (up to `enough`): a test image must not be all one colour.
std::size_t distinct_colours(const Image& img, std::size_t enough = 8) {
    std::vector<vec3> seen;
    for (const vec4& p : img.pixels) {
        const vec3 c(p);
        if (std::find(seen.begin(), seen.end(), c) == seen.end()) {
            seen.push_back(c);
            if (seen.size() >= enough) break;
        }
    }
    return seen.size();
}

/// Renders `rs` with every built-in shader at 1 and 4 jittered spp (and 1 spp at the pixel
/// centre) on the device and on the CPU, and checks the images agree: <= 2/255 per channel on
/// >= 99.9 % of the pixels, debug-cost exactly; both images non-trivial.
void expect_every_shader_matches(rcl::DeviceRenderer& r, const RenderScene& rs, const Camera& cam,
                                 const std::string& what, unsigned max_depth = 3) {
    for (ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::depth, ShaderKind::ao,
                         ShaderKind::debug_cost})
        for (unsigned spp : {1u, 4u})
            for (bool jitter : {true, false}) {
                if (!jitter && spp != 1) continue;
                RenderSettings set;
                set.spp = spp;
                set.jitter = jitter;
                set.seed = 7;
                set.threads = 2;
                set.shade.shader = k;
                set.shade.max_depth = max_depth;
                set.shade.ao_samples = 8;
                set.shade.background = vec3(0.05f, 0.1f, 0.2f);
                const std::string label = what + " " + shader_name(k) + " spp " + std::to_string(spp) +
                                          (jitter ? " jittered" : " centred");
                RenderStats cs;
                const Image cpu = render_cpu(twin_view(rs), cam, set, &cs);
                rcl::DeviceRenderStats ds;
                const Image gpu = r.render(cam, set, &ds);
                const Diff d = compare(cpu, gpu);
                EXPECT_GE(d.fraction_ok(), 0.999) << label << ": " << d.bad << " of " << d.total
                                                  << " pixels differ by more than 2/255, max diff " << d.worst;
                if (k == ShaderKind::debug_cost) {  // the same traversal steps give the same colours
                    EXPECT_EQ(d.worst, 0.0f) << label << ": " << d.bad << " pixels differ, max diff " << d.worst;
                }
                EXPECT_GE(distinct_colours(cpu), 4u) << label << ": the CPU image is (nearly) one colour";
                EXPECT_GE(distinct_colours(gpu), 4u) << label << ": the device image is (nearly) one colour";
                // the same rays, as far as last-bit differences in shading let them be
                EXPECT_EQ(ds.primary, cs.rays.primary) << label;
                EXPECT_EQ(ds.passes, spp);
                const double cpu_any = double(cs.rays.shadow + cs.rays.ao);
                EXPECT_NEAR(double(ds.shadow), cpu_any, 1e-3 * cpu_any + 1.0) << label;
                const double cpu_cont = double(cs.rays.reflection + cs.rays.refraction);
                EXPECT_NEAR(double(ds.continuation), cpu_cont, 1e-3 * cpu_cont + 1.0) << label;
            }
}
/// The same through the renderer's ShadeScene constructor (its own DeviceScene).
void expect_every_shader_matches(rcl::Device& dev, const RenderScene& rs, const Camera& cam, const std::string& what,
                                 unsigned max_depth = 3) {
    rcl::DeviceRenderer r(dev, rs.view());
    expect_every_shader_matches(r, rs, cam, what, max_depth);
}

/// A sphere with vertex normals, texture coordinates from the direction and two materials
/// (upper and lower half).
Mesh textured_sphere() {
    Mesh s = make_icosphere(3);
    s.normals = s.positions;
    s.texcoords.resize(s.positions.size());
    for (std::size_t i = 0; i < s.positions.size(); ++i) {
        const vec3 p = s.positions[i];
        s.texcoords[i] = vec2(std::atan2(p.z, p.x) * 0.15915494f + 0.5f, 0.5f * p.y + 0.5f);
    }
    s.materials = {make_material(vec3(0.9f, 0.85f, 0.8f), vec3(0.3f), 20.0f), make_material(vec3(0.2f, 0.5f, 0.8f))};
    for (const Triangle& t : s.triangles)
        s.material_ids.push_back(s.positions[t.v[0]].y + s.positions[t.v[1]].y + s.positions[t.v[2]].y > 0.0f ? 0u : 1u);
    return s;
}

/// An affine transform: translate · rotate(degrees about axis) · scale.
mat4 place(vec3 shift, float degrees, vec3 axis, vec3 scale) {
    mat4 t = glm::translate(mat4(1.0f), shift);
    t = glm::rotate(t, glm::radians(degrees), glm::normalize(axis));
    return glm::scale(t, scale);
}

/// Several objects, several instances: a textured floor (identity), a textured sphere with
/// vertex normals (object 1: translated; rotated past pi and scaled), a torus without normals
/// in mirror and glass (object 2: rotated past pi with a non-uniform scale; rotated and
/// scaled again). Each object has its own material table.
struct InstancedScene : TexturedScene {
    InstancedScene() : TexturedScene(checker(9, 6)) {
        SceneBuilder f;
        const auto fm = f.material(make_material(vec3(0.8f)));
        f.quad({-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4}, fm, 2.0f);
        Mesh torus = make_bumpy_torus(2000, 0.1f);
        torus.normals.clear();
        torus.texcoords.clear();
        Material glass = make_material(vec3(0.0f), vec3(0.1f), 60.0f, 7);
        glass.ni = 1.4f;
        torus.materials = {make_material(vec3(0.1f), vec3(0.7f), 40.0f, 3), glass};
        torus.material_ids.clear();
        for (std::size_t t = 0; t < torus.triangles.size(); ++t) torus.material_ids.push_back((t / 64) % 2 ? 1u : 0u);
        const auto floor = rs.add_object(std::move(f.m));
        const auto sphere = rs.add_object(textured_sphere());
        const auto ring = rs.add_object(std::move(torus));
        rs.materials[floor].materials[fm].map_kd = &tex;
        rs.materials[floor].materials[fm].update_derived();
        rs.materials[sphere].materials[0].map_kd = &tex;
        rs.materials[sphere].materials[0].update_derived();
        rs.scene.add_instance(floor);
        rs.scene.add_instance(sphere, place({-1.6f, 1.0f, 0.0f}, 0.0f, {0, 1, 0}, vec3(1.0f)));
        rs.scene.add_instance(sphere, place({1.5f, 1.1f, -1.0f}, 200.0f, {0.3f, 1.0f, 0.2f}, vec3(0.8f, 1.1f, 0.9f)));
        rs.scene.add_instance(ring, place({0.3f, 0.6f, 1.6f}, 250.0f, {0, 1, 0}, vec3(1.6f, 0.5f, 1.0f)));
        rs.scene.add_instance(ring, place({-0.5f, 2.3f, -2.0f}, -120.0f, {1, 0.2f, 0}, vec3(0.7f, 1.3f, 0.9f)));
        rs.scene.update_top_level();
        cam.position = {0.5f, 3.0f, 6.0f};
        cam.target = {0.0f, 1.0f, 0.0f};
        cam.width = 96;
        cam.height = 72;
        cam.vfov_degrees = 55.0f;
        rs.lights.push_back(default_key_light(cam));
        rs.lights.push_back(Light::point({-2.0f, 5.0f, 2.0f}, vec3(0.5f, 0.45f, 0.4f)));
    }
};

/// A vertex hook with the same roundings on both sides (fma, no transcendental functions):
/// bends the object along z by amount · x², tilts the normals to match and shifts the uvs.
struct BendHook {
    static constexpr const char* name = "bend";
    struct Params {
        float amount = 0.0f;
        float uv_shift = 0.0f;
    };
    static constexpr const char* source = R"CLC(typedef struct {
    float amount;
    float uv_shift;
} bend_params;

rk_vertex bend(rk_vertex v, uint index, bend_params p) {
    v.normal[0] = fma(-2.0f * p.amount, v.position[0], v.normal[0]);
    v.position[2] = fma(p.amount * v.position[0], v.position[0], v.position[2]);
    v.uv[0] = v.uv[0] + p.uv_shift;
    return v;
}
)CLC";
    static Vertex apply(const Vertex& v, std::uint32_t, const Params& p) {
        Vertex o = v;
        o.normal.x = std::fma(-2.0f * p.amount, v.position.x, v.normal.x);
        o.position.z = std::fma(p.amount * v.position.x, v.position.x, v.position.z);
        o.uv.x = v.uv.x + p.uv_shift;
        return o;
    }
};
static_assert(rcl::VertexHook<BendHook>);

/// A generated scene: a bumpy torus, an icosphere and a triangle soup (scene/generate.hpp) on a
/// floor, with diffuse, shiny, mirror and glass materials and lights placed from `seed`.
struct GeneratedScene {
    RenderScene rs;
    Camera cam;

    explicit GeneratedScene(std::uint64_t seed, std::uint32_t w = 96, std::uint32_t h = 72) {
        SampleRng rng(seed);
        auto uni = [&](float lo, float hi) { return lo + (hi - lo) * rng.next_float(); };
        SceneBuilder b;
        const auto floor = b.material(make_material(vec3(uni(0.4f, 0.9f), uni(0.4f, 0.9f), uni(0.4f, 0.9f))));
        const auto shiny = b.material(make_material(vec3(uni(0.2f, 0.8f), 0.3f, 0.2f), vec3(0.3f), uni(5.0f, 60.0f)));
        const auto mirror = b.material(make_material(vec3(0.1f), vec3(0.7f), 40.0f, 3));
        Material glass = make_material(vec3(0.0f), vec3(0.1f), 60.0f, 7);
        glass.ni = uni(1.2f, 1.7f);
        const auto glassm = b.material(glass);
        b.quad({-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}, floor, 2.0f);
        b.add(make_bumpy_torus(3000 + 1000 * (seed % 3), uni(0.05f, 0.25f)), shiny, 1.2f,
              {uni(-1.5f, -0.5f), 0.9f, uni(-1.0f, 0.0f)});
        b.add(make_icosphere(2), mirror, 0.6f, {uni(0.8f, 1.6f), 0.6f, uni(-0.5f, 0.5f)});
        b.add(make_random_soup(400, seed, 0.25f), glassm, 1.5f, {uni(-1.0f, 0.0f), 0.0f, uni(0.8f, 1.5f)});
        rs = prepare_render_scene(std::move(b.m));
        cam = frame_scene(rs.bounds(), w, h, 45.0f, vec3(uni(-1.0f, 1.0f), uni(0.4f, 0.9f), 1.0f));
        rs.lights.push_back(default_key_light(cam));
        rs.lights.push_back(Light::point({uni(-3, 3), uni(3, 6), uni(-3, 3)}, vec3(0.5f, 0.45f, 0.4f)));
        rs.lights.push_back(Light::directional({uni(-1, 1), -1.0f, uni(-1, 1)}, vec3(0.2f, 0.2f, 0.3f)));
    }
};

/// A hook that adds a constant colour and emits nothing.
struct ConstantHook {
    static constexpr const char* name = "const_color";
    struct Params {
        float r, g, b;
    };
    static constexpr unsigned max_rays = 0;
    static constexpr unsigned max_shadow_rays = 0;
    static constexpr const char* source = R"CLC(typedef struct {
    float r, g, b;
} const_color_params;

void const_color(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s,
                 const_color_params p) {
    rk_add_color(ctx, (float3)(p.r, p.g, p.b));
    rk_set_alpha(ctx, hit->prim == RK_INVALID ? 0.0f : 1.0f);
}
)CLC";
};

/// A hook that always continues straight on (emits one ray per hit or miss) and adds 1/8 per
/// ray traced: the pixel counts the bounces.
struct ForeverHook {
    static constexpr const char* name = "forever";
    struct Params {
        float pad;
    };
    static constexpr unsigned max_rays = 1;
    static constexpr unsigned max_shadow_rays = 0;
    static constexpr const char* source = R"CLC(typedef struct {
    float pad;
} forever_params;

void forever(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, forever_params p) {
    rk_add_color(ctx, (float3)(0.125f));
    rk_emit_ray(ctx, rk_f3(path->ray.org), rk_f3(path->ray.dir), (float3)(1.0f), 7u);
    rk_emit_ray(ctx, rk_f3(path->ray.org), rk_f3(path->ray.dir), (float3)(1.0f), 7u); /* over budget: refused */
}
)CLC";
};

/// A hook with a syntax error on its line 4.
struct BrokenHook {
    static constexpr const char* name = "broken";
    struct Params {
        float pad;
    };
    static constexpr unsigned max_rays = 0;
    static constexpr unsigned max_shadow_rays = 0;
    static constexpr const char* source = R"CLC(typedef struct { float pad; } broken_params;

void broken(rk_ctx* ctx, const rk_path_ray* path, const rk_hit* hit, const rk_surface* s, broken_params p) {
    rk_add_color(ctx, (float3)(1.0f)) this is not C;
}
)CLC";
};

}  // namespace

/// The renderer's packet walk (kernels/raykit/kernels/trace_packet.hpp) against its single-ray
/// walk: normals and depth give the same image bit for bit, whitted with shadows (max depth 0)
/// the same within 1e-6 (with several lights a pixel's shadow colours add by atomics, in any
/// order), all three the same ray counts. (tests/test_cl.cpp compares the walks' hits word by
/// word.)
void expect_packets_change_nothing(rcl::DeviceRenderer& r, const Camera& cam, const std::string& what) {
    const bool was = r.packet_walk();
    for (ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::depth}) {
        ShadeSettings s;
        s.shader = k;
        s.max_depth = 0;
        rcl::DeviceRenderStats a, b;
        r.set_packet_walk(false);
        const Image single = r.render(cam, s, &a);
        r.set_packet_walk(true);
        const Image packet = r.render(cam, s, &b);
        ASSERT_EQ(single.pixels.size(), packet.pixels.size());
        const float tolerance = k == ShaderKind::whitted ? 1e-6f : 0.0f;
        std::size_t differ = 0;
        for (std::size_t i = 0; i < single.pixels.size(); ++i)
            for (int c = 0; c < 4; ++c) differ += !(std::abs(single.pixels[i][c] - packet.pixels[i][c]) <= tolerance);
        EXPECT_EQ(differ, 0u) << what << " " << shader_name(k) << ": pixels differ between packet and single-ray walks";
        EXPECT_EQ(a.shadow, b.shadow) << what;
        EXPECT_EQ(a.primary, b.primary) << what;
        EXPECT_GE(distinct_colours(packet), 2u) << what;  // not one flat colour
    }
    r.set_packet_walk(was);
}

TEST(DeviceRender, BuiltInShadersMatchTheCpuRenderer) {
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    rcl::DeviceRenderer r(dev, ts.rs.view());
    for (ShaderKind k : {ShaderKind::normals, ShaderKind::depth, ShaderKind::whitted}) {
        for (TextureFilter f : {TextureFilter::bilinear, TextureFilter::nearest}) {
            if (k != ShaderKind::whitted && f == TextureFilter::nearest) continue;
            ShadeSettings s;
            s.shader = k;
            s.max_depth = 4;
            s.filter = f;
            s.background = vec3(0.05f, 0.1f, 0.2f);
            const Image cpu = cpu_render(ts.rs, ts.cam, s);
            rcl::DeviceRenderStats st;
            const Image gpu = r.render(ts.cam, s, &st);
            const Diff d = compare(cpu, gpu);
            EXPECT_GE(d.fraction_ok(), 0.999) << shader_name(k) << ": " << d.bad << " of " << d.total
                                              << " pixels differ, worst " << d.worst;
            EXPECT_EQ(st.primary, 96u * 72u);
            if (k == ShaderKind::whitted) {
                EXPECT_GT(st.continuation, 0u);
                EXPECT_GT(st.shadow, 0u);
                EXPECT_LE(st.bounces, 5u);
            } else {
                EXPECT_EQ(st.bounces, 1u);
                EXPECT_EQ(st.total(), 96u * 72u);
            }
        }
    }
    expect_packets_change_nothing(r, ts.cam, "test scene");
    // without shadow rays and with no lights
    ShadeSettings s;
    s.shadows = false;
    s.max_depth = 2;
    Diff d = compare(cpu_render(ts.rs, ts.cam, s), r.render(ts.cam, s));
    EXPECT_GE(d.fraction_ok(), 0.999) << "no shadows: " << d.bad << " differ, worst " << d.worst;
    ts.rs.lights.clear();
    r.set_lights(ts.rs.lights);
    d = compare(cpu_render(ts.rs, ts.cam, s), r.render(ts.cam, s));
    EXPECT_GE(d.fraction_ok(), 0.999) << "no lights: " << d.bad << " differ, worst " << d.worst;
}

TEST(DeviceRender, EveryShaderMatchesTheCpuAtOneAndFourSpp) {
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    expect_every_shader_matches(dev, ts.rs, ts.cam, "test scene", 4);
}

TEST(DeviceRender, EveryShaderMatchesTheCpuOnGeneratedScenes) {
    RAYKIT_REQUIRE_DEVICE(dev);
    for (std::uint64_t seed : {1u, 2u, 3u}) {
        GeneratedScene g(seed);
        expect_every_shader_matches(dev, g.rs, g.cam, "generated scene " + std::to_string(seed));
    }
}

TEST(DeviceRender, CameraRaysEqualTheCpuSamples) {
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    Camera cam = ts.cam;
    cam.width = 37;  // not a multiple of the work-group size
    cam.height = 23;
    const CameraFrame frame = cam.frame();
    rcl::DeviceRenderer r(dev, ts.rs.view());
    std::size_t checked = 0;
    for (unsigned spp : {1u, 2u, 3u, 4u, 5u, 9u})
        for (bool jitter : {true, false})
            for (std::uint64_t seed : {std::uint64_t(0), std::uint64_t(0x123456789abcdefull)}) {
                RenderSettings set;
                set.spp = spp;
                set.jitter = jitter;
                set.seed = seed;
                PixelSampler sampler(spp, seed, jitter);
                std::vector<std::vector<Ray>> device_rays;
                for (unsigned s = 0; s < spp; ++s) device_rays.push_back(r.camera_rays(cam, set, s));
                std::size_t mismatches = 0;
                for (std::uint32_t y = 0; y < cam.height; ++y)
                    for (std::uint32_t x = 0; x < cam.width; ++x) {
                        sampler.begin_pixel(std::uint64_t(y) * cam.width + x);
                        for (unsigned s = 0; s < spp; ++s) {
                            SampleRng rng;
                            const vec2 j = sampler.sample(s, rng);
                            const Ray a = frame.ray(x, y, j.x, j.y);
                            const Ray& b = device_rays[s][std::size_t(y) * cam.width + x];
                            if (std::memcmp(&a, &b, sizeof(Ray)) != 0) ++mismatches;
                            ++checked;
                        }
                    }
                EXPECT_EQ(mismatches, 0u) << "spp " << spp << (jitter ? " jittered" : " centred") << " seed " << seed;
            }
    EXPECT_EQ(checked, 37u * 23u * 2u * 2u * (1 + 2 + 3 + 4 + 5 + 9));
    EXPECT_THROW(r.camera_rays(cam, RenderSettings{}, 1), std::invalid_argument);
}

TEST(DeviceRender, QueueMemoryDoesNotGrowWithSpp) {
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    RenderSettings set;
    set.shade.max_depth = 2;
    std::size_t bytes[2] = {0, 0};
    for (int i = 0; i < 2; ++i) {
        rcl::DeviceRenderer r(dev, ts.rs.view());  // fresh buffers
        set.spp = i == 0 ? 1u : 8u;
        rcl::DeviceRenderStats st;
        r.render(ts.cam, set, &st);
        bytes[i] = st.queue_bytes;
        EXPECT_EQ(st.passes, set.spp);
        EXPECT_EQ(st.primary, std::uint64_t(set.spp) * 96u * 72u);
        EXPECT_LE(st.peak_queue, std::size_t(96u * 72u * 2u));
    }
    EXPECT_GT(bytes[0], 0u);
    EXPECT_LE(double(bytes[1]), 1.05 * double(bytes[0])) << "8 spp held " << bytes[1] << " bytes, 1 spp " << bytes[0];
}

TEST(DeviceRender, DepthLimitIsHonoured) {
    RAYKIT_REQUIRE_DEVICE(dev);
    SceneBuilder b;
    const std::uint32_t mirror = b.material(make_material(vec3(0.0f), vec3(1.0f), 0.0f, 3));
    b.quad({-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}, mirror);
    b.quad({-50, -50, 2}, {50, -50, 2}, {50, 50, 2}, {-50, 50, 2}, mirror);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    Camera cam;
    cam.position = {0, 0, 1};
    cam.target = {0.1f, 0, 2};
    cam.width = cam.height = 4;
    cam.vfov_degrees = 10;
    rcl::DeviceRenderer r(dev, rs.view());
    for (unsigned depth : {0u, 1u, 3u, 7u}) {
        ShadeSettings s;
        s.max_depth = depth;
        rcl::DeviceRenderStats st;
        r.render(cam, s, &st);
        EXPECT_EQ(st.primary, 16u);
        EXPECT_EQ(st.continuation, 16u * depth) << "max_depth " << depth;
        EXPECT_EQ(st.bounces, depth + 1);
    }
    // a hook that always wants to go on stops at max_depth too; its second ray per hit is refused
    ShadeSettings s;
    s.max_depth = 5;
    rcl::DeviceRenderStats st;
    const Image img = r.render_hook<ForeverHook>(cam, s, {}, &st);
    EXPECT_EQ(st.bounces, 6u);
    EXPECT_EQ(st.continuation, 16u * 5u);
    EXPECT_FLOAT_EQ(img.at(1, 2).x, 6 * 0.125f);
}

TEST(DeviceRender, HookThatEmitsNothingEndsAfterOneBounce) {
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    rcl::DeviceRenderer r(dev, ts.rs.view());
    rcl::DeviceRenderStats st;
    const Image img = r.render_hook<ConstantHook>(ts.cam, ShadeSettings{}, {0.25f, 0.5f, 0.75f}, &st);
    EXPECT_EQ(st.bounces, 1u);
    EXPECT_EQ(st.continuation, 0u);
    EXPECT_EQ(st.shadow, 0u);
    const Image cpu = cpu_render(ts.rs, ts.cam, ShadeSettings{});
    for (std::size_t i = 0; i < img.pixels.size(); ++i) {
        ASSERT_EQ(vec3(img.pixels[i]), vec3(0.25f, 0.5f, 0.75f));
        ASSERT_EQ(img.pixels[i].w, cpu.pixels[i].w) << "coverage of pixel " << i;
    }
}

TEST(DeviceRender, UserFogHookMatchesItsCpuTwin) {
    // examples/fog_hook.hpp: one hook type, its OpenCL source on the device, its C++ twin on the
    // CPU (render_hook_cpu); the images agree as the built-in shaders' do.
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    rcl::DeviceRenderer r(dev, ts.rs.view());
    for (unsigned spp : {1u, 4u})
        for (const bool shadows : {true, false}) {
            RenderSettings set;
            set.spp = spp;
            set.seed = 3;
            set.shade.shadows = shadows;
            set.shade.ambient = vec3(0.15f);
            const FogHook::Params fog{0.12f, 0.6f, 0.65f, 0.7f};
            rcl::DeviceRenderStats ds;
            RenderStats cs;
            const Image gpu = r.render_hook<FogHook>(ts.cam, set, fog, &ds);
            const Image cpu = render_hook_cpu<FogHook>(ts.rs.view(), ts.cam, set, fog, &cs);
            const Diff d = compare(cpu, gpu);
            std::printf("[ info ] fog spp %u shadows %d: %zu of %zu pixels differ by more than 2/255, max %g\n", spp,
                        int(shadows), d.bad, d.total, double(d.worst));
            EXPECT_GE(d.fraction_ok(), 0.999) << "spp " << spp;
            EXPECT_GE(distinct_colours(cpu), 4u);
            EXPECT_EQ(ds.primary, cs.rays.primary);
            EXPECT_EQ(ds.shadow, cs.rays.shadow);
        }
}

TEST(DeviceRender, HookBuildErrorCarriesTheHooksLine) {
    RAYKIT_REQUIRE_DEVICE(dev);
    TestScene ts;
    rcl::DeviceRenderer r(dev, ts.rs.view());
    try {
        r.render_hook<BrokenHook>(ts.cam, ShadeSettings{});
        FAIL() << "a broken hook built";
    } catch (const rcl::BuildError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("<hook broken>:4"), std::string::npos) << msg;
    }
    // the renderer still works afterwards
    EXPECT_NO_THROW(r.render(ts.cam, ShadeSettings{}));
    RenderSettings none;
    none.spp = 0;
    EXPECT_THROW(r.render(ts.cam, none), std::invalid_argument);
}

TEST(DeviceRender, EmptySceneAndNoLightsRenderWithoutError) {
    RAYKIT_REQUIRE_DEVICE(dev);
    RenderScene empty = prepare_render_scene(Mesh{});
    Camera cam;
    cam.width = 16;
    cam.height = 8;
    rcl::DeviceRenderer r(dev, empty.view());
    for (ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::depth, ShaderKind::ao,
                         ShaderKind::debug_cost}) {
        RenderSettings s;
        s.spp = 4;
        s.shade.shader = k;
        s.shade.background = vec3(0.25f);
        rcl::DeviceRenderStats st;
        const Image img = r.render(cam, s, &st);
        ASSERT_EQ(img.pixels.size(), 128u);
        EXPECT_EQ(st.primary, 4u * 128u);
        EXPECT_EQ(st.bounces, 1u);
        const Diff d = compare(render_cpu(empty.view(), cam, s), img);
        EXPECT_EQ(d.bad, 0u) << shader_name(k) << ": worst " << d.worst;
        if (k != ShaderKind::debug_cost) {
            EXPECT_EQ(img.at(3, 3), vec4(0.25f, 0.25f, 0.25f, 0.0f)) << shader_name(k);
        }
    }
    // a lit material with no lights: ambient only, as on the CPU
    Mesh sphere = make_icosphere(3);
    sphere.normals = sphere.positions;
    sphere.materials = {make_material(vec3(0.2f, 0.4f, 0.6f), vec3(0.5f), 10.0f)};
    sphere.material_ids.assign(sphere.triangles.size(), 0);
    RenderScene rs = prepare_render_scene(std::move(sphere));
    cam.width = cam.height = 16;
    ShadeSettings s;
    s.ambient = vec3(0.5f);
    rcl::DeviceRenderer rsph(dev, rs.view());
    const Image img = rsph.render(cam, s);
    EXPECT_NEAR(img.at(8, 8).x, 0.1f, 1e-6f);
    EXPECT_NEAR(img.at(8, 8).z, 0.3f, 1e-6f);
    EXPECT_EQ(img.at(8, 8).w, 1.0f);
    const Diff d = compare(cpu_render(rs, cam, s), img);
    EXPECT_EQ(d.bad, 0u) << "worst " << d.worst;
}

TEST(DeviceRender, ThesisSceneMatchesTheCpuRenderer) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const std::filesystem::path file = std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / "obj/thesis_scene/Scene.obj";
    if (!std::filesystem::exists(file)) GTEST_SKIP() << "no " << file;
    RenderScene rs = prepare_render_scene(load_obj(file));
    const Camera cam = frame_scene(rs.bounds(), 160, 120);
    rs.lights.push_back(default_key_light(cam));
    expect_every_shader_matches(dev, rs, cam, "thesis scene", 2);
}

TEST(DeviceRender, AlphaCutoutsMatchTheCpuRenderer) {
    RAYKIT_REQUIRE_DEVICE(dev);
    SceneBuilder b;
    const auto floor = b.material(make_material(vec3(0.7f, 0.6f, 0.5f)));
    const auto leaf = b.material(make_material(vec3(0.2f, 0.8f, 0.3f)));
    b.quad({-4, 0, -4}, {4, 0, -4}, {4, 0, 4}, {-4, 0, 4}, floor);
    b.quad({-2, 0.2f, 0.5f}, {2, 0.2f, 0.5f}, {2, 2.5f, -0.5f}, {-2, 2.5f, -0.5f}, leaf, 2.0f);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    std::vector<std::uint8_t> px(8 * 8 * 4);
    for (int y = 0; y < 8; ++y)
        for (int x = 0; x < 8; ++x) {
            std::uint8_t* p = &px[std::size_t(y * 8 + x) * 4];
            p[0] = std::uint8_t(30 * x), p[1] = 200, p[2] = std::uint8_t(25 * y);
            p[3] = ((x / 2 + y / 2) & 1) ? 255 : 0;
        }
    const Texture cut = make_texture(8, 8, std::move(px), true);
    ASSERT_TRUE(cut.has_cutout);
    rs.materials[0].materials[leaf].map_kd = &cut;
    rs.materials[0].materials[leaf].update_derived();
    ASSERT_TRUE(rs.view().alpha_testing);
    rs.lights.push_back(Light::point({0.5f, 5.0f, -2.0f}));
    Camera cam;
    cam.position = {0.3f, 2.0f, 5.0f};
    cam.target = {0.0f, 0.6f, 0.0f};
    cam.width = 80;
    cam.height = 60;
    rcl::DeviceRenderer r(dev, rs.view());
    expect_packets_change_nothing(r, cam, "alpha cut-outs");
    for (TextureFilter f : {TextureFilter::bilinear, TextureFilter::nearest}) {
        ShadeSettings s;
        s.filter = f;
        s.max_depth = 1;
        const Diff d = compare(cpu_render(rs, cam, s), r.render(cam, s));
        EXPECT_GE(d.fraction_ok(), 0.999) << texture_filter_name(f) << ": " << d.bad << " of " << d.total
                                          << " differ, worst " << d.worst;
    }
    // the comparison is sensitive: without the cut-outs the image differs a lot
    ShadeSettings s;
    s.max_depth = 1;
    const Image with = r.render(cam, s);
    rs.materials[0].materials[leaf].alpha_tested = false;
    rcl::DeviceRenderer solid(dev, rs.view());
    EXPECT_LT(compare(with, solid.render(cam, s)).fraction_ok(), 0.9);
}

TEST(DeviceRender, CliRendersOnTheDeviceLikeOnTheCpu) {
    RAYKIT_REQUIRE_DEVICE(dev);
    (void)dev;
    const auto dir = std::filesystem::temp_directory_path() / "raykit_test_devrender_cli";
    std::filesystem::create_directories(dir);
    {
        std::ofstream obj(dir / "scene.obj");
        obj << "v -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nv -3 -3 -1\nv 3 -3 -1\nv 3 3 -1\nv -3 3 -1\n"
               "f 1 2 3 4\nf 5 6 7 8\n";
    }
    auto run_cli = [](std::vector<std::string> args) {
        args.insert(args.begin(), {"raykit", "render"});
        std::vector<char*> argv;
        for (auto& a : args) argv.push_back(a.data());
        return raykit_cli_render(int(argv.size()), argv.data(), 2);
    };
    const std::string obj = (dir / "scene.obj").string();
    const std::string cpu = (dir / "cpu.pfm").string(), gpu = (dir / "cl.pfm").string();
    const std::vector<std::string> common = {"--width", "40", "--height", "30", "--quiet", "--max-depth", "2",
                                             "--light", "1", "2", "5", "1", "1", "1"};
    std::vector<std::string> a = {obj, cpu, "--no-jitter", "--threads", "2"};
    a.insert(a.end(), common.begin(), common.end());
    EXPECT_EQ(run_cli(a), 0);
    std::vector<std::string> b = {obj, gpu, "--no-jitter", "--device", "cl"};
    b.insert(b.end(), common.begin(), common.end());
    EXPECT_EQ(run_cli(b), 0);
    const Diff d = compare(read_pfm(cpu), read_pfm(gpu));
    EXPECT_EQ(d.bad, 0u) << "worst " << d.worst;
    // every shader, 4 jittered samples per pixel
    for (const char* shader : {"whitted", "normals", "depth", "ao", "debug-cost"}) {
        std::vector<std::string> c = {obj, cpu, "--threads", "2", "--spp", "4", "--shader", shader, "--seed", "3"};
        c.insert(c.end(), common.begin(), common.end());
        EXPECT_EQ(run_cli(c), 0);
        std::vector<std::string> g = {obj, gpu, "--device", "cl", "--spp", "4", "--shader", shader, "--seed", "3"};
        g.insert(g.end(), common.begin(), common.end());
        EXPECT_EQ(run_cli(g), 0);
        const Image ci = read_pfm(cpu), gi = read_pfm(gpu);
        const Diff e = compare(ci, gi);
        EXPECT_GE(e.fraction_ok(), 0.999) << shader << ": " << e.bad << " of " << e.total << " differ, max diff "
                                          << e.worst;
        EXPECT_GE(distinct_colours(gi), 2u) << shader;
    }
    // --nodes quantized: the same image, bit for bit
    const std::string quant = (dir / "cl_q.pfm").string();
    for (const char* nodes : {"full", "quantized"}) {
        std::vector<std::string> q = {obj, nodes == std::string("full") ? gpu : quant, "--device", "cl", "--nodes",
                                      nodes, "--spp", "4", "--seed", "3"};
        q.insert(q.end(), common.begin(), common.end());
        EXPECT_EQ(run_cli(q), 0) << nodes;
    }
    const Diff qd = compare(read_pfm(gpu), read_pfm(quant));
    EXPECT_EQ(qd.worst, 0.0f) << "--nodes quantized changed the image";
    EXPECT_GE(distinct_colours(read_pfm(quant)), 2u);
    EXPECT_THROW(run_cli({obj, gpu, "--device", "cl", "--spp", "0", "--quiet"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, gpu, "--device", "gpu", "--quiet"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, gpu, "--nodes", "quantized", "--quiet"}), RaykitCliRenderUsageError) << "without --device cl";
    EXPECT_THROW(run_cli({obj, gpu, "--device", "cl", "--nodes", "small", "--quiet"}), RaykitCliRenderUsageError);
}

TEST(DeviceRender, InstancedMultiObjectSceneMatchesTheCpuRenderer) {
    RAYKIT_REQUIRE_DEVICE(dev);
    InstancedScene sc;
    ASSERT_EQ(sc.rs.scene.objects().size(), 3u);
    ASSERT_EQ(sc.rs.scene.instances().size(), 5u);
    expect_every_shader_matches(dev, sc.rs, sc.cam, "instanced (own DeviceScene)");
    // the same scene through a DeviceScene the caller holds
    rcl::DeviceScene<> ds(dev, sc.rs.scene);
    ds.update();
    rcl::DeviceRenderer r(ds, sc.rs.materials, sc.rs.lights);
    expect_every_shader_matches(r, sc.rs, sc.cam, "instanced (DeviceScene)");
    expect_packets_change_nothing(r, sc.cam, "instanced");
    // the comparison sees the instances: moving one changes the image
    ShadeSettings s;
    s.shader = ShaderKind::normals;
    const Image before = r.render(sc.cam, s);
    sc.rs.scene.set_transform(2, place({0.0f, 1.4f, 0.2f}, 20.0f, {0.3f, 1.0f, 0.2f}, vec3(1.3f, 1.1f, 0.9f)));
    sc.rs.scene.update_top_level();
    ds.update();
    const Image after = r.render(sc.cam, s);
    EXPECT_LT(compare(before, after).fraction_ok(), 0.95);
    EXPECT_EQ(compare(cpu_render(sc.rs, sc.cam, s), after).bad, 0u);
    // one table per object
    EXPECT_THROW(rcl::DeviceRenderer(ds, std::span<const MaterialTable>(sc.rs.materials).first(2), sc.rs.lights),
                 std::invalid_argument);
}

TEST(DeviceRender, MovedInstanceNeedsDeviceUpdateThenRendersTheNewPlacement) {
    RAYKIT_REQUIRE_DEVICE(dev);
    InstancedScene sc;
    rcl::DeviceScene<> ds(dev, sc.rs.scene);
    ds.update();
    rcl::DeviceRenderer r(ds, sc.rs.materials, sc.rs.lights);
    ShadeSettings s;
    s.shader = ShaderKind::normals;
    const Image before = r.render(sc.cam, s);
    const std::vector<Ray> rays = {sc.cam.frame().ray(48, 36)};
    // the CPU scene's own rule (update_top_level) does not refresh the device's copy of the instances
    sc.rs.scene.set_transform(2, place({0.0f, 1.4f, 0.2f}, 20.0f, {0.3f, 1.0f, 0.2f}, vec3(1.3f, 1.1f, 0.9f)));
    sc.rs.scene.update_top_level();
    try {
        (void)r.render(sc.cam, s);
        ADD_FAILURE() << "rendered the placement of the last update() after set_transform";
    } catch (const std::logic_error& e) {
        EXPECT_NE(std::string(e.what()).find("update()"), std::string::npos) << e.what();
    }
    EXPECT_THROW((void)ds.closest(rays), std::logic_error) << "traced a stale DeviceScene";
    EXPECT_THROW((void)ds.any(rays), std::logic_error) << "traced a stale DeviceScene";
    ds.update();
    const Image after = r.render(sc.cam, s);
    EXPECT_LT(compare(before, after).fraction_ok(), 0.95) << "the move is visible";
    const Diff d = compare(cpu_render(sc.rs, sc.cam, s), after);
    EXPECT_GE(d.fraction_ok(), 0.999) << d.bad << " of " << d.total << " differ, worst " << d.worst;
    const Hit dh = ds.closest(rays)[0], ch = sc.rs.scene.intersect_closest(rays[0]);
    EXPECT_EQ(dh.inst, ch.inst);
    EXPECT_EQ(dh.t, ch.t);
    // a second move, then update(): fresh again (the check is per move, not once)
    sc.rs.scene.set_transform(1, place({-1.2f, 0.9f, 0.4f}, 35.0f, {0, 1, 0}, vec3(1.1f)));
    EXPECT_THROW((void)r.render(sc.cam, s), std::logic_error);
    ds.update();
    sc.rs.scene.update_top_level();
    EXPECT_GE(compare(cpu_render(sc.rs, sc.cam, s), r.render(sc.cam, s)).fraction_ok(), 0.999);
}

namespace {

/// A floor and a textured dynamic sphere instanced twice (as it is: an identity instance, not
/// mapped; and rotated past pi and scaled), a point light and an 80 x 60 camera: the scene the
/// dynamic render tests bend with BendHook.
struct BendScene {
    Texture tex = checker(8, 8);
    RenderScene rs;
    std::uint32_t body = 0;
    Camera cam;
    BendScene() {
        SceneBuilder f;
        const auto fm = f.material(make_material(vec3(0.7f, 0.7f, 0.6f)));
        f.quad({-5, 0, -5}, {5, 0, -5}, {5, 0, 5}, {-5, 0, 5}, fm);
        const auto floor = rs.add_object(std::move(f.m));
        body = rs.add_object(textured_sphere(), ObjectKind::dynamic);
        rs.materials[body].materials[0].map_kd = &tex;
        rs.materials[body].materials[0].update_derived();
        rs.scene.add_instance(floor);
        rs.scene.add_instance(body, mat4(1.0f));
        rs.scene.add_instance(body, place({2.0f, 1.2f, -1.0f}, 190.0f, {0.2f, 1.0f, 0.1f}, vec3(0.9f, 0.6f, 1.1f)));
        rs.scene.update_top_level();
        cam.position = {0.8f, 3.0f, 6.0f};
        cam.target = {0.6f, 0.8f, 0.0f};
        cam.width = 80;
        cam.height = 60;
        rs.lights.push_back(Light::point({2.0f, 5.0f, 3.0f}, vec3(0.9f)));
    }
    BendScene(const BendScene&) = delete;
    BendScene& operator=(const BendScene&) = delete;
};

}  // namespace

TEST(DeviceRender, DynamicSceneMovedAndRenderedOnTheDeviceMatchesTheCpu) {
    RAYKIT_REQUIRE_DEVICE(dev);
    BendScene b;
    RenderScene& rs = b.rs;
    const std::uint32_t body = b.body;
    const Camera& cam = b.cam;
    rcl::DeviceScene<BendHook> ds(dev, rs.scene);
    rcl::DeviceRenderer r(ds, rs.materials, rs.lights);
    EXPECT_THROW(r.render(cam, ShadeSettings{}), std::logic_error) << "rendered before update()";
    Image first;
    for (int frame = 0; frame < 3; ++frame) {
        const BendHook::Params p{.amount = 0.35f * float(frame), .uv_shift = 0.3f * float(frame)};
        // the device: vertex stage, refit, top level, render — no vertex read back
        ds.set_hook<BendHook>(body, p);
        ds.update();
        // the CPU twin
        rs.scene.move_vertices(body, [&](const Vertex& v, std::uint32_t i) { return BendHook::apply(v, i, p); });
        rs.scene.update_top_level();
        for (ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::depth, ShaderKind::ao,
                             ShaderKind::debug_cost}) {
            RenderSettings set;
            set.spp = 2;
            set.seed = 5;
            set.threads = 2;
            set.shade.shader = k;
            set.shade.max_depth = 2;
            set.shade.ao_samples = 8;
            const std::string label = "frame " + std::to_string(frame) + " " + shader_name(k);
            const Image cpu = render_cpu(twin_view(rs), cam, set);
            const Image gpu = r.render(cam, set);
            const Diff d = compare(cpu, gpu);
            EXPECT_GE(d.fraction_ok(), 0.999) << label << ": " << d.bad << " of " << d.total
                                              << " pixels differ by more than 2/255, max diff " << d.worst;
            if (k == ShaderKind::debug_cost) {
                EXPECT_EQ(d.worst, 0.0f) << label;
            }
            EXPECT_GE(distinct_colours(gpu), 4u) << label;
            if (k == ShaderKind::whitted && frame == 0) first = gpu;
            if (k == ShaderKind::whitted && frame == 2) {  // the comparison sees the motion
                EXPECT_LT(compare(first, gpu).fraction_ok(), 0.95);
            }
        }
    }
    EXPECT_EQ(ds.launches().vertex, 3u);
    EXPECT_EQ(ds.dynamic_object_count(), 1u);
}

// The renderer over a DeviceScene walking quantized nodes (NodeForm::quantized): the same images
// as over full nodes, every channel of every pixel, while a dynamic object bends over three
// frames (its nodes quantized again on the device after each refit), Whitted with reflections
// and shadows, AO and normals, 2 spp.
TEST(DeviceRender, QuantizedNodesRenderTheFullNodesImages) {
    RAYKIT_REQUIRE_DEVICE(dev);
    BendScene b;
    RenderScene& rs = b.rs;
    const std::uint32_t body = b.body;
    const Camera& cam = b.cam;
    rcl::DeviceScene<BendHook> full(dev, rs.scene);
    rcl::DeviceScene<BendHook> quant(dev, rs.scene, {}, rcl::NodeForm::quantized);
    ASSERT_EQ(quant.node_form(), rcl::NodeForm::quantized);
    rcl::DeviceRenderer rf(full, rs.materials, rs.lights);
    rcl::DeviceRenderer rq(quant, rs.materials, rs.lights);
    for (int frame = 0; frame < 3; ++frame) {
        const BendHook::Params p{.amount = 0.35f * float(frame), .uv_shift = 0.3f * float(frame)};
        for (auto* ds : {&full, &quant}) {
            ds->set_hook<BendHook>(body, p);
            ds->update();
        }
        for (ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::ao}) {
            RenderSettings set;
            set.spp = 2;
            set.seed = 5;
            set.shade.shader = k;
            set.shade.max_depth = 2;
            set.shade.ao_samples = 8;
            const Image a = rf.render(cam, set), b = rq.render(cam, set);
            const Diff d = compare(a, b);
            std::printf("[ info ] frame %d %s: %zu of %zu pixels differ, worst %g\n", frame, shader_name(k), d.bad,
                        d.total, double(d.worst));
            EXPECT_EQ(d.worst, 0.0f) << "frame " << frame << " " << shader_name(k);
            EXPECT_GE(distinct_colours(b), 4u);
        }
    }
    EXPECT_EQ(quant.launches().quantize, 3u);
}
