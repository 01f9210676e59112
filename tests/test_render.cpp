// The CPU renderer against analytic answers: Blinn-Phong on a sphere, shadows, a mirror, Snell's
// law through a glass slab, texture filtering and wrapping, sRGB, missing textures, depth limit,
// empty scenes, thread-count independence; plus the `raykit render` command function.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include <glm/gtc/matrix_transform.hpp>

#include "../examples/cli_render.hpp"
#include "../examples/fog_hook.hpp"
#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/render/render_cpu.hpp"
#include "raykit/scene/generate.hpp"

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

using namespace raykit;

namespace {

constexpr double kPi = 3.14159265358979323846;

/// Builds small test scenes: quads and boxes with per-vertex texture coordinates.
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
    /// Quad a b c d (counter-clockwise seen from the front), uv (0,0) (1,0) (1,1) (0,1).
    void quad(vec3 a, vec3 b, vec3 c, vec3 d, std::uint32_t mat) {
        const std::uint32_t i = vertex(a, {0, 0}), j = vertex(b, {1, 0}), k = vertex(c, {1, 1}), l = vertex(d, {0, 1});
        m.triangles.push_back({{i, j, k}});
        m.triangles.push_back({{i, k, l}});
        m.material_ids.push_back(mat);
        m.material_ids.push_back(mat);
    }
    /// Closed box with outward-facing winding.
    void box(vec3 lo, vec3 hi, std::uint32_t mat) {
        const vec3 c = (lo + hi) * 0.5f;
        auto face = [&](vec3 a, vec3 b, vec3 cc, vec3 d) {
            const vec3 n = glm::cross(b - a, cc - a);
            if (glm::dot(n, (a + cc) * 0.5f - c) < 0.0f) quad(d, cc, b, a, mat);
            else quad(a, b, cc, d, mat);
        };
        const vec3 p[8] = {{lo.x, lo.y, lo.z}, {hi.x, lo.y, lo.z}, {hi.x, hi.y, lo.z}, {lo.x, hi.y, lo.z},
                           {lo.x, lo.y, hi.z}, {hi.x, lo.y, hi.z}, {hi.x, hi.y, hi.z}, {lo.x, hi.y, hi.z}};
        face(p[0], p[1], p[2], p[3]);
        face(p[4], p[5], p[6], p[7]);
        face(p[0], p[1], p[5], p[4]);
        face(p[3], p[2], p[6], p[7]);
        face(p[0], p[3], p[7], p[4]);
        face(p[1], p[2], p[6], p[5]);
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
Material emissive(vec3 ke) {
    Material m = make_material(vec3(0.0f));
    m.ke = ke;
    return m;
}

SampleResult shade_one(const RenderScene& rs, const ShadeSettings& s, const Ray& r, ShadeCounters* out = nullptr) {
    SampleRng rng(7);
    ShadeCounters c;
    PathScratch scratch;
    const SampleResult res = shade_ray(rs.view(), s, r, rng, c, scratch);
    if (out) *out = c;
    return res;
}

Ray ray_from(vec3 o, vec3 d) { return Ray{o, 0.0f, d, kInf}; }

/// Unit sphere (icosphere, 5 subdivisions = 20480 triangles) with radial vertex normals.
Mesh smooth_sphere(int levels, const Material& mat) {
    Mesh m = make_icosphere(levels);
    m.normals = m.positions;
    m.materials = {mat};
    m.material_ids.assign(m.triangles.size(), 0);
    return m;
}

std::filesystem::path temp_dir(const std::string& name) {
    const auto d = std::filesystem::temp_directory_path() / ("raykit_test_render_" + name);
    std::filesystem::create_directories(d);
    return d;
}

}  // namespace

// ---------------------------------------------------------------- colour, images

TEST(Srgb, KnownValues) {
    EXPECT_EQ(srgb_to_linear(0.0f), 0.0f);
    EXPECT_FLOAT_EQ(srgb_to_linear(1.0f), 1.0f);
    EXPECT_NEAR(srgb_to_linear(0.5f), 0.2140411f, 1e-6f);
    EXPECT_NEAR(srgb_to_linear(0.04045f), 0.04045f / 12.92f, 1e-7f);  // end of the linear segment
    EXPECT_NEAR(srgb_to_linear(128.0f / 255.0f), 0.2158605f, 1e-6f);
    EXPECT_NEAR(linear_to_srgb(0.2140411f), 0.5f, 1e-6f);
    EXPECT_NEAR(linear_to_srgb(0.0031308f), 0.04045f, 1e-6f);
    EXPECT_EQ(linear_to_srgb8(0.2158605f), 128);
    EXPECT_EQ(linear_to_srgb8(-1.0f), 0);
    EXPECT_EQ(linear_to_srgb8(2.0f), 255);
    for (int i = 0; i < 256; ++i) {
        EXPECT_NEAR(detail::srgb8_lut[i], srgb_to_linear(float(i) / 255.0f), 1e-6f * detail::srgb8_lut[i]) << i;
        EXPECT_EQ(linear_to_srgb8(detail::srgb8_lut[i]), i) << "8-bit round trip of code " << i;
    }
}

TEST(Image, PfmRoundTripAndPngWrite) {
    Image img(3, 2);
    for (std::uint32_t y = 0; y < 2; ++y)
        for (std::uint32_t x = 0; x < 3; ++x) img.at(x, y) = vec4(float(x) + 0.25f, float(y) * 3.5f, -1.5f, 1.0f);
    const auto dir = temp_dir("image");
    write_pfm(img, dir / "a.pfm");
    const Image back = read_pfm(dir / "a.pfm");
    ASSERT_EQ(back.width, 3u);
    ASSERT_EQ(back.height, 2u);
    EXPECT_EQ(rmse(img, back), 0.0);
    EXPECT_EQ(back.at(2, 1).x, 2.25f);  // top-left origin survives the bottom-up file order
    write_png(img, dir / "a.png");
    EXPECT_GT(std::filesystem::file_size(dir / "a.png"), 8u);
    EXPECT_THROW(write_png(img, dir / "no_such_dir" / "a.png"), std::runtime_error);
    EXPECT_THROW(read_pfm(dir / "missing.pfm"), std::runtime_error);
    EXPECT_THROW(rmse(img, Image(2, 2)), std::invalid_argument);
}

// ---------------------------------------------------------------- textures

namespace {
/// W x H linear (non-sRGB) texture whose texel (x, y) is (x, y, x * 10 + y, alpha) / 255.
Texture ramp_texture(std::uint32_t w, std::uint32_t h, std::uint8_t alpha = 255) {
    std::vector<std::uint8_t> px;
    for (std::uint32_t y = 0; y < h; ++y)
        for (std::uint32_t x = 0; x < w; ++x)
            px.insert(px.end(), {std::uint8_t(x), std::uint8_t(y), std::uint8_t(x * 10 + y), alpha});
    return make_texture(w, h, std::move(px), false);
}
}  // namespace

TEST(Texture, BilinearEqualsHandComputationAtTexelCentresAndCorners) {
    const Texture t = ramp_texture(4, 2);
    // texel centres: u = (x + 0.5) / 4, v = (H - y - 0.5) / 2 (v up, row 0 at the top)
    for (int y = 0; y < 2; ++y)
        for (int x = 0; x < 4; ++x) {
            const vec2 uv((x + 0.5f) / 4.0f, (2 - y - 0.5f) / 2.0f);
            const vec4 s = t.sample(uv);
            EXPECT_NEAR(s.x * 255.0f, float(x), 1e-4f);
            EXPECT_NEAR(s.y * 255.0f, float(y), 1e-4f);
            EXPECT_EQ(t.sample(uv, TextureFilter::nearest), t.texel(x, y));
        }
    // texel corner shared by (1,0) (2,0) (1,1) (2,1): the mean of the four
    const vec4 c = t.sample(vec2(0.5f, 0.5f));
    EXPECT_NEAR(c.x * 255.0f, 1.5f, 1e-4f);
    EXPECT_NEAR(c.y * 255.0f, 0.5f, 1e-4f);
    EXPECT_NEAR(c.z * 255.0f, (10 + 11 + 20 + 21) / 4.0f, 1e-4f);
    // an arbitrary point: u = 0.3 -> fx = 0.7 (x0 = 0, ax = 0.7); v = 0.6 -> bottom-up fy = 0.7
    // (rows j = 0, 1 bottom-up = top-down rows 1, 0; ay = 0.7 towards top-down row 0)
    const vec4 a = t.sample(vec2(0.3f, 0.6f));
    const float row1 = (1 - 0.7f) * (0 * 10 + 1) + 0.7f * (1 * 10 + 1);  // top-down row 1: texels (0,1), (1,1)
    const float row0 = (1 - 0.7f) * (0 * 10 + 0) + 0.7f * (1 * 10 + 0);  // top-down row 0: texels (0,0), (1,0)
    EXPECT_NEAR(a.z * 255.0f, (1 - 0.7f) * row1 + 0.7f * row0, 1e-3f);
    EXPECT_NEAR(a.x * 255.0f, 0.7f, 1e-4f);
    EXPECT_NEAR(a.y * 255.0f, 0.3f, 1e-4f);  // 0.3 of row 1 + 0.7 of row 0
    // the corner uv = (0, 0) of the texture: wrap blends the four corner texels
    const vec4 o = t.sample(vec2(0.0f, 0.0f));
    EXPECT_NEAR(o.z * 255.0f, (0 + 1 + 30 + 31) / 4.0f, 1e-4f);
}

TEST(Texture, WrapsAtUOneAndVOne) {
    const Texture t = ramp_texture(8, 4);
    const float eps = 1e-4f;
    for (float v : {0.1f, 0.5f, 0.9f}) {
        // bilinear: continuous across the seam, periodic
        const vec4 below = t.sample(vec2(1.0f - eps, v)), above = t.sample(vec2(1.0f + eps, v));
        EXPECT_NEAR(below.z, above.z, 2e-3f);
        EXPECT_NEAR(below.x * 255.0f, 3.5f, 0.01f);  // halfway between columns 7 and 0
        const vec4 p = t.sample(vec2(0.3f, v)), q = t.sample(vec2(2.3f, v)), r = t.sample(vec2(-0.7f, v));
        EXPECT_NEAR(p.z, q.z, 1e-5f);
        EXPECT_NEAR(p.z, r.z, 1e-5f);
        // nearest: the last column just below u = 1, the first just above
        EXPECT_NEAR(t.sample(vec2(1.0f - eps, v), TextureFilter::nearest).x * 255.0f, 7.0f, 1e-4f);
        EXPECT_NEAR(t.sample(vec2(1.0f + eps, v), TextureFilter::nearest).x * 255.0f, 0.0f, 1e-4f);
    }
    // v: just below 1 is the top row (y = 0), just above 1 the bottom row (y = 3)
    EXPECT_NEAR(t.sample(vec2(0.1f, 1.0f - eps), TextureFilter::nearest).y * 255.0f, 0.0f, 1e-4f);
    EXPECT_NEAR(t.sample(vec2(0.1f, 1.0f + eps), TextureFilter::nearest).y * 255.0f, 3.0f, 1e-4f);
    // non-finite coordinates do not crash
    (void)t.sample(vec2(std::nanf(""), kInf));
}

TEST(Texture, SrgbMapsAreDecodedBeforeFiltering) {
    Texture t = make_texture(2, 1, {128, 0, 255, 255, 0, 0, 0, 255}, true);
    EXPECT_NEAR(t.texel(0, 0).x, 0.2158605f, 1e-6f);
    EXPECT_NEAR(t.texel(0, 0).z, 1.0f, 1e-6f);
    // the midpoint between the two texels is the mean of the *linear* values
    EXPECT_NEAR(t.sample(vec2(0.5f, 0.5f)).x, 0.5f * 0.2158605f, 1e-6f);
    t.srgb = false;
    EXPECT_NEAR(t.texel(0, 0).x, 128.0f / 255.0f, 1e-6f);
}

TEST(Texture, PngRoundTripKeepsBytesAndAlpha) {
    Image img(2, 2);
    img.at(0, 0) = {1, 0, 0, 1};
    img.at(1, 0) = {0, 1, 0, 0};
    img.at(0, 1) = {0, 0, 1, 0.5f};
    img.at(1, 1) = {0.2158605f, 0.2158605f, 0.2158605f, 1};
    const auto dir = temp_dir("png");
    PngOptions o;
    o.alpha = true;
    write_png(img, dir / "rt.png", o);
    std::vector<std::string> warnings;
    const Texture t = load_texture(dir / "rt.png", true, &warnings);
    EXPECT_TRUE(warnings.empty());
    ASSERT_FALSE(t.placeholder);
    ASSERT_EQ(t.width, 2u);
    EXPECT_EQ(t.rgba[4 * 3 + 0], 128);  // 0.2158605 linear -> sRGB code 128
    EXPECT_EQ(t.rgba[4 * 1 + 3], 0);
    EXPECT_TRUE(t.has_alpha);
    EXPECT_TRUE(t.has_cutout);
    EXPECT_NEAR(t.texel(1, 1).x, 0.2158605f, 1e-6f);
}

TEST(Texture, MissingFileGivesPlaceholderAndWarning) {
    std::vector<std::string> warnings;
    const Texture t = load_texture("/nonexistent/raykit/missing.png", true, &warnings);
    EXPECT_TRUE(t.placeholder);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("missing.png"), std::string::npos);
    const vec4 a = t.texel(0, 0), b = t.texel(1, 0);
    EXPECT_EQ(a, vec4(1, 0, 1, 1));  // magenta
    EXPECT_EQ(b, vec4(0, 0, 0, 1));  // black
    // a file that is not an image: placeholder too
    const auto dir = temp_dir("bad");
    std::ofstream(dir / "bad.png") << "not a png";
    warnings.clear();
    EXPECT_TRUE(load_texture(dir / "bad.png", true, &warnings).placeholder);
    EXPECT_EQ(warnings.size(), 1u);
}

TEST(Material, MissingTextureRendersPlaceholderWithOneWarning) {
    SceneBuilder b;
    Material m = make_material(vec3(1.0f));
    m.map_kd = "/nonexistent/raykit/wall.png";
    const std::uint32_t id = b.material(m);
    const std::uint32_t id2 = b.material(m);  // same path: one texture, one warning
    b.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, id);
    b.quad({-1, -1, -1}, {1, -1, -1}, {1, 1, -1}, {-1, 1, -1}, id2);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    ASSERT_EQ(rs.materials[0].warnings.size(), 1u);
    EXPECT_EQ(rs.materials[0].textures.size(), 1u);
    EXPECT_EQ(rs.materials[0].materials[0].map_kd, rs.materials[0].materials[1].map_kd);
    Camera cam;
    cam.position = {0, 0, 2};
    cam.width = cam.height = 32;
    cam.vfov_degrees = 40;
    RenderSettings set;
    set.shade.ambient = vec3(1.0f);
    set.shade.filter = TextureFilter::nearest;
    const Image img = render_cpu(rs.view(), cam, set);
    int magenta = 0, black = 0;
    for (const vec4& p : img.pixels) {
        magenta += p.x > 0.5f && p.y == 0.0f && p.z > 0.5f;
        black += p.x == 0.0f && p.y == 0.0f && p.z == 0.0f;
    }
    EXPECT_GT(magenta, 100);
    EXPECT_GT(black, 100);
    // the cache shares textures between tables
    TextureCache cache;
    Mesh mesh2;
    mesh2.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
    mesh2.triangles = {{{0, 1, 2}}};
    mesh2.material_ids = {1};
    mesh2.materials = {m, m};
    mesh2.materials[0].map_kd = "/nonexistent/raykit/unused.png";  // no triangle uses it: not loaded
    const MaterialTable t1 = make_material_table(mesh2, &cache), t2 = make_material_table(mesh2, &cache);
    EXPECT_EQ(cache.size(), 1u);
    EXPECT_EQ(t1.materials[1].map_kd, t2.materials[1].map_kd);
    EXPECT_NE(t1.materials[1].map_kd, nullptr);
    EXPECT_EQ(t1.materials[0].map_kd, nullptr);
    EXPECT_EQ(t2.warnings.size(), 1u);
}

// ---------------------------------------------------------------- shading

TEST(Shade, BlinnPhongOnASphereMatchesTheFormula) {
    const vec3 kd(0.6f, 0.3f, 0.2f), ks(0.4f, 0.4f, 0.4f);
    const float ns = 20.0f;
    RenderScene rs = prepare_render_scene(smooth_sphere(6, make_material(kd, ks, ns)));
    const vec3 Ldir = glm::normalize(vec3(1.0f, 1.0f, 1.0f));  // towards the light
    rs.lights.push_back(Light::directional(-Ldir, vec3(0.9f, 0.8f, 1.0f)));
    Camera cam;
    cam.position = {0, 0, 4};
    cam.vfov_degrees = 35;
    cam.width = cam.height = 96;
    RenderSettings set;
    set.jitter = false;
    set.shade.ambient = vec3(0.1f);
    const Image img = render_cpu(rs.view(), cam, set);
    const CameraFrame f = cam.frame();
    int checked = 0;
    double worst = 0.0;
    for (std::uint32_t y = 0; y < 96; y += 3)
        for (std::uint32_t x = 0; x < 96; x += 3) {
            const Ray r = f.ray(x, y);
            const dvec3 o(r.org), d = glm::normalize(dvec3(r.dir));
            const double bq = glm::dot(o, d), cq = glm::dot(o, o) - 1.0, disc = bq * bq - cq;
            if (disc <= 0.0) {
                EXPECT_EQ(img.at(x, y), vec4(0.0f)) << x << "," << y;
                continue;
            }
            const dvec3 p = o + d * (-bq - std::sqrt(disc)), n = glm::normalize(p), L(Ldir);
            const double nl = glm::dot(n, L), nv = -glm::dot(n, d);
            if (nl < 0.25 || nv < 0.25) continue;  // away from the terminator and the silhouette (faceting)
            const dvec3 h = glm::normalize(L - d);
            const dvec3 lc(0.9, 0.8, 1.0);
            const double lh = std::max(0.0, glm::dot(L, h)), f5 = std::pow(1.0 - lh, 5.0);
            const dvec3 fresnel = dvec3(ks) + (dvec3(1.0) - dvec3(ks)) * f5;  // Schlick, F0 = Ks
            const dvec3 expect = dvec3(0.1) * dvec3(kd) + dvec3(kd) * nl * lc +
                                 fresnel * ((double(ns) + 8.0) / 8.0 * std::pow(std::max(0.0, glm::dot(n, h)), double(ns)) * nl) * lc;
            for (int c = 0; c < 3; ++c) {
                const double e = std::fabs(double(img.at(x, y)[c]) - expect[c]);
                worst = std::max(worst, e);
                // level 6: 81920 facets, edges ~0.03 rad; the hit lies up to ~1e-4 inside the
                // sphere and interpolated normals deviate from radial by O(1e-4) rad, which the
                // normalised Ns = 20 lobe amplifies; observed worst error 2e-4, allowed 1e-3
                EXPECT_NEAR(img.at(x, y)[c], expect[c], 1e-3) << "pixel " << x << "," << y << " channel " << c;
            }
            EXPECT_EQ(img.at(x, y).w, 1.0f);
            ++checked;
        }
    EXPECT_GT(checked, 150);
    RecordProperty("worst_abs_error", std::to_string(worst));
}

TEST(Shade, PointInShadowIsAmbientOnly) {
    SceneBuilder b;
    const vec3 kd(0.5f, 0.7f, 0.9f);
    const std::uint32_t ground = b.material(make_material(kd));
    const std::uint32_t blocker = b.material(make_material(vec3(0.3f)));
    b.quad({-10, 0, 10}, {10, 0, 10}, {10, 0, -10}, {-10, 0, -10}, ground);         // y = 0, facing +y
    b.quad({0.75f, 5, 0.25f}, {1.25f, 5, 0.25f}, {1.25f, 5, -0.25f}, {0.75f, 5, -0.25f}, blocker);  // y = 5
    RenderScene rs = prepare_render_scene(std::move(b.m));
    rs.lights.push_back(Light::point({0, 10, 0}, vec3(1.0f)));
    ShadeSettings s;
    s.ambient = vec3(0.2f);
    // (2, 0, 0) is behind the blocker's centre (1, 5, 0) seen from the light
    ShadeCounters c;
    const SampleResult shadowed = shade_one(rs, s, ray_from({6, 2, 0}, vec3(2, 0, 0) - vec3(6, 2, 0)), &c);
    EXPECT_EQ(c.rays.shadow, 1u);
    for (int k = 0; k < 3; ++k) EXPECT_FLOAT_EQ(shadowed.color[k], 0.2f * kd[k]);
    // (-2, 0, 0) is lit: ambient + Kd (N.L)
    const SampleResult lit = shade_one(rs, s, ray_from({-6, 2, 0}, vec3(-2, 0, 0) - vec3(-6, 2, 0)));
    const float nl = 10.0f / std::sqrt(4.0f + 100.0f);
    for (int k = 0; k < 3; ++k) EXPECT_NEAR(lit.color[k], 0.2f * kd[k] + kd[k] * nl, 1e-5f);
    // without shadow rays the shadowed point is lit too
    s.shadows = false;
    const SampleResult noshadow = shade_one(rs, s, ray_from({6, 2, 0}, vec3(2, 0, 0) - vec3(6, 2, 0)));
    EXPECT_GT(noshadow.color.x, 0.2f * kd.x + 0.4f);
}

TEST(Shade, MirrorShowsTheReflectedObjectAtThePredictedPixel) {
    SceneBuilder b;
    const std::uint32_t mirror = b.material(make_material(vec3(0.0f), vec3(1.0f), 0.0f, 3));
    const std::uint32_t red = b.material(emissive({1, 0, 0}));
    b.quad({-20, 0, 20}, {20, 0, 20}, {20, 0, -20}, {-20, 0, -20}, mirror);
    const vec3 P(0.5f, 1.0f, -3.0f);
    b.box(P - vec3(0.3f), P + vec3(0.3f), red);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    Camera cam;
    cam.position = {0, 1.5f, 4};
    cam.target = {0, 0, -3};
    cam.vfov_degrees = 50;
    cam.width = cam.height = 101;
    RenderSettings set;
    set.jitter = false;
    set.shade.ambient = vec3(0.0f);
    set.shade.max_depth = 1;
    const Image img = render_cpu(rs.view(), cam, set);
    const CameraFrame f = cam.frame();
    auto pixel_towards = [&](vec3 q) {
        std::uint32_t bx = 0, by = 0;
        float best = -2.0f;
        for (std::uint32_t y = 0; y < f.height; ++y)
            for (std::uint32_t x = 0; x < f.width; ++x) {
                const float c = glm::dot(glm::normalize(f.ray(x, y).dir), glm::normalize(q - f.origin));
                if (c > best) best = c, bx = x, by = y;
            }
        return std::pair{bx, by};
    };
    const auto [dx, dy] = pixel_towards(P);
    const auto [rx, ry] = pixel_towards(vec3(P.x, -P.y, P.z));  // mirror image below the plane y = 0
    EXPECT_GT(ry, dy + 10);
    EXPECT_EQ(img.at(dx, dy), vec4(1, 0, 0, 1));
    EXPECT_EQ(img.at(rx, ry), vec4(1, 0, 0, 1));
    // mirror elsewhere reflects the black sky; with max_depth 0 the reflection disappears
    EXPECT_EQ(img.at(5, f.height - 3), vec4(0, 0, 0, 1));
    set.shade.max_depth = 0;
    const Image flat = render_cpu(rs.view(), cam, set);
    EXPECT_EQ(flat.at(rx, ry), vec4(0, 0, 0, 1));
    EXPECT_EQ(flat.at(dx, dy), vec4(1, 0, 0, 1));
}

TEST(Shade, GlassSlabShiftsTheRayBySnellsLaw) {
    // slab z in [-h, 0] (n = 1.5), backdrop z = -3: red for x < 0, green for x > 0 (emissive)
    const float h = 1.0f, n = 1.5f;
    SceneBuilder b;
    Material glass = make_material(vec3(0.0f));
    glass.ni = n;
    glass.illum = 4;
    const std::uint32_t g = b.material(glass);
    const std::uint32_t red = b.material(emissive({1, 0, 0})), green = b.material(emissive({0, 1, 0}));
    b.box({-20, -20, -h}, {20, 20, 0}, g);
    b.quad({-40, -40, -3}, {0, -40, -3}, {0, 40, -3}, {-40, 40, -3}, red);
    b.quad({0, -40, -3}, {40, -40, -3}, {40, 40, -3}, {0, 40, -3}, green);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    ShadeSettings s;
    s.ambient = vec3(0.0f);
    s.max_depth = 8;
    const double theta = 30.0 * kPi / 180.0, theta_t = std::asin(std::sin(theta) / n);
    const vec3 dir(float(std::sin(theta)), 0.0f, float(-std::cos(theta)));
    auto is_green = [&](double x0) {
        const SampleResult r = shade_one(rs, s, ray_from(vec3(float(x0), 0.0f, 1.0f), dir));
        return r.color.y > r.color.x;
    };
    // the ray from (x0, 0, 1) meets the backdrop at x0 + 3 tan(theta) + h tan(theta_t)
    const double predicted = -(3.0 * std::tan(theta) + h * std::tan(theta_t));
    const double unrefracted = -4.0 * std::tan(theta);
    double lo = -5.0, hi = 2.0;
    ASSERT_FALSE(is_green(lo));
    ASSERT_TRUE(is_green(hi));
    for (int i = 0; i < 40; ++i) {
        const double mid = 0.5 * (lo + hi);
        (is_green(mid) ? hi : lo) = mid;
    }
    EXPECT_NEAR(lo, predicted, 1e-4);
    EXPECT_GT(std::fabs(predicted - unrefracted), 0.2);
    // transmitted colour: (1 - F)^2 of the emission at both interfaces (plus tiny internal reflections)
    float ct = 0.0f;
    const float Fin = detail::fresnel_dielectric(float(std::cos(theta)), 1.0f / n, ct);
    const SampleResult r = shade_one(rs, s, ray_from(vec3(float(predicted) - 0.5f, 0, 1), dir));
    EXPECT_NEAR(r.color.x, (1 - Fin) * (1 - Fin), 2e-3f);
    // Fresnel at normal incidence: ((n - 1) / (n + 1))^2 = 0.04
    EXPECT_NEAR(detail::fresnel_dielectric(1.0f, 1.0f / n, ct), 0.04f, 1e-6f);
    // total internal reflection beyond the critical angle
    EXPECT_EQ(detail::fresnel_dielectric(std::cos(float(0.8)), n, ct), 1.0f);
}

TEST(Shade, AlphaCutoutsLetCameraAndShadowRaysThrough) {
    // a 2 x 1 texture: left texel transparent, right opaque white
    const auto dir = temp_dir("alpha");
    Image tex(2, 1);
    tex.at(0, 0) = {1, 1, 1, 0};
    tex.at(1, 0) = {1, 1, 1, 1};
    PngOptions o;
    o.alpha = true;
    write_png(tex, dir / "leaf.png", o);
    SceneBuilder b;
    Material leaf = make_material(vec3(1.0f));
    leaf.map_kd = (dir / "leaf.png").string();
    const std::uint32_t lm = b.material(leaf);
    const std::uint32_t back = b.material(emissive({0, 0, 1}));
    b.quad({-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}, lm);  // u from 0 (x = -1) to 1 (x = 1)
    b.quad({-5, -5, -2}, {5, -5, -2}, {5, 5, -2}, {-5, 5, -2}, back);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    ASSERT_TRUE(rs.materials[0].any_alpha_tested());
    ShadeSettings s;
    s.ambient = vec3(0.0f);
    s.filter = TextureFilter::nearest;
    EXPECT_EQ(shade_one(rs, s, ray_from({-0.5f, 0, 3}, {0, 0, -1})).color, vec3(0, 0, 1));  // through the cut-out
    EXPECT_EQ(shade_one(rs, s, ray_from({0.5f, 0, 3}, {0, 0, -1})).color, vec3(0, 0, 0));   // opaque, unlit
    // shadow rays: light behind the leaf quad at z = 3, lit floor point seen through the cut-out
    SceneBuilder b2;
    const std::uint32_t lm2 = b2.material(leaf), fl2 = b2.material(make_material(vec3(1.0f)));
    b2.quad({-1, 2, 1}, {1, 2, 1}, {1, 2, -1}, {-1, 2, -1}, lm2);     // horizontal leaf at y = 2
    b2.quad({-5, 0, 5}, {5, 0, 5}, {5, 0, -5}, {-5, 0, -5}, fl2);     // floor y = 0
    RenderScene rs2 = prepare_render_scene(std::move(b2.m));
    rs2.lights.push_back(Light::point({0, 10, 0}));
    const float under_cut = shade_one(rs2, s, ray_from({-0.5f, 1, 3}, vec3(-0.5f, 0, 0) - vec3(-0.5f, 1, 3))).color.x;
    const float under_leaf = shade_one(rs2, s, ray_from({0.5f, 1, 3}, vec3(0.5f, 0, 0) - vec3(0.5f, 1, 3))).color.x;
    EXPECT_GT(under_cut, 0.9f);
    EXPECT_EQ(under_leaf, 0.0f);
}

// ---------------------------------------------------------------- renderer

TEST(Render, DepthLimitIsHonoured) {
    SceneBuilder b;
    const std::uint32_t mirror = b.material(make_material(vec3(0.0f), vec3(1.0f), 0.0f, 3));
    b.quad({-50, -50, 0}, {50, -50, 0}, {50, 50, 0}, {-50, 50, 0}, mirror);
    b.quad({-50, -50, 2}, {50, -50, 2}, {50, 50, 2}, {-50, 50, 2}, mirror);
    RenderScene rs = prepare_render_scene(std::move(b.m));
    for (unsigned depth : {0u, 1u, 2u, 3u, 7u, 20u}) {
        ShadeSettings s;
        s.max_depth = depth;
        ShadeCounters c;
        shade_one(rs, s, ray_from({0, 0, 1}, {0.05f, 0.0f, 1.0f}), &c);
        EXPECT_EQ(c.rays.primary, 1u);
        EXPECT_EQ(c.rays.reflection, depth) << "max_depth " << depth;
        EXPECT_EQ(c.deepest, depth);
    }
    // the renderer passes the limit through: one camera ray per pixel, 3 bounces each
    Camera cam;
    cam.position = {0, 0, 1};
    cam.target = {0.1f, 0, 2};
    cam.width = cam.height = 4;
    cam.vfov_degrees = 10;
    RenderSettings set;
    set.shade.max_depth = 3;
    RenderStats st;
    render_cpu(rs.view(), cam, set, &st);
    EXPECT_EQ(st.rays.primary, 16u);
    EXPECT_EQ(st.rays.reflection, 48u);
    EXPECT_EQ(st.deepest, 3u);
}

TEST(Render, EmptySceneAndNoLightsRenderWithoutError) {
    RenderScene empty = prepare_render_scene(Mesh{});
    Camera cam;
    cam.width = 16;
    cam.height = 8;
    for (ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::depth, ShaderKind::ao,
                         ShaderKind::debug_cost}) {
        RenderSettings set;
        set.shade.shader = k;
        set.shade.background = vec3(0.25f);
        RenderStats st;
        const Image img = render_cpu(empty.view(), cam, set, &st);
        ASSERT_EQ(img.pixels.size(), 128u);
        EXPECT_EQ(st.rays.primary, 128u);
        if (k != ShaderKind::debug_cost) {
            EXPECT_EQ(img.at(3, 3), vec4(0.25f, 0.25f, 0.25f, 0.0f));
        }
    }
    // a lit material with no lights: ambient only
    const vec3 kd(0.2f, 0.4f, 0.6f);
    RenderScene sphere = prepare_render_scene(smooth_sphere(3, make_material(kd, vec3(0.5f), 10.0f)));
    ASSERT_TRUE(sphere.lights.empty());
    RenderSettings set;
    set.shade.ambient = vec3(0.5f);
    cam.width = cam.height = 16;
    const Image img = render_cpu(sphere.view(), cam, set);
    EXPECT_EQ(img.at(8, 8), vec4(0.5f * kd, 1.0f));
    set.spp = 0;
    EXPECT_THROW(render_cpu(sphere.view(), cam, set), std::invalid_argument);
}

TEST(Render, OtherShaders) {
    RenderScene rs = prepare_render_scene(smooth_sphere(4, make_material(vec3(0.5f))));
    Camera cam;
    cam.position = {0, 0, 4};
    cam.width = cam.height = 33;
    cam.vfov_degrees = 40;
    RenderSettings set;
    set.jitter = false;
    set.shade.shader = ShaderKind::normals;
    Image img = render_cpu(rs.view(), cam, set);
    EXPECT_NEAR(img.at(16, 16).x, 0.5f, 0.02f);
    EXPECT_NEAR(img.at(16, 16).z, 1.0f, 0.01f);
    set.shade.shader = ShaderKind::depth;
    set.shade.depth_far = 4.0f;
    img = render_cpu(rs.view(), cam, set);
    EXPECT_NEAR(img.at(16, 16).x, 1.0f - 3.0f / 4.0f, 1e-3f);
    EXPECT_GT(img.at(16, 16).x, img.at(16, 10).x);  // the centre is the nearest point
    set.shade.shader = ShaderKind::ao;
    img = render_cpu(rs.view(), cam, set);  // a convex object occludes nothing of itself
    EXPECT_EQ(img.at(16, 16).x, 1.0f);
    set.shade.shader = ShaderKind::debug_cost;
    RenderStats st;
    img = render_cpu(rs.view(), cam, set, &st);
    EXPECT_GT(st.traversal_steps, 0u);
    EXPECT_GT(img.at(16, 16).x + img.at(16, 16).y + img.at(16, 16).z, 0.0f);
    // AO inside a box corner is darker than on an open floor
    SceneBuilder b;
    const std::uint32_t w = b.material(make_material(vec3(1.0f)));
    b.quad({-5, 0, 5}, {5, 0, 5}, {5, 0, -5}, {-5, 0, -5}, w);
    b.quad({-5, 0, -5}, {5, 0, -5}, {5, 5, -5}, {-5, 5, -5}, w);
    RenderScene corner = prepare_render_scene(std::move(b.m));
    ShadeSettings s;
    s.shader = ShaderKind::ao;
    s.ao_samples = 256;
    s.ao_radius = 2.0f;
    const float open = shade_one(corner, s, ray_from({0, 3, 5}, {0, -3, -2})).color.x;
    const float near_wall = shade_one(corner, s, ray_from({0, 3, 0}, {0, -3, -4.9f})).color.x;
    EXPECT_EQ(open, 1.0f);
    EXPECT_LT(near_wall, 0.85f);
}

TEST(Render, OneAndTwoThreadsGiveIdenticalImages) {
    std::vector<std::pair<RenderScene, Camera>> scenes;
    const std::filesystem::path thesis = std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / "obj/thesis_scene/Scene.obj";
    if (std::filesystem::exists(thesis)) {
        RenderScene rs = prepare_render_scene(load_obj(thesis));
        Camera cam;
        cam.position = {20, 8, 24};
        cam.target = {0, 2.5f, 0};
        cam.width = 96;
        cam.height = 72;
        rs.lights.push_back(Light::point({-25, 35, 30}));
        scenes.emplace_back(std::move(rs), cam);
    }
    {
        SceneBuilder b;
        Material glass = make_material(vec3(0.1f), vec3(0.5f), 30.0f, 7);
        glass.ni = 1.4f;
        const std::uint32_t gm = b.material(glass), fm = b.material(make_material(vec3(0.7f, 0.5f, 0.3f)));
        b.box({-1, 0, -1}, {1, 1.5f, 1}, gm);
        b.quad({-9, 0, 9}, {9, 0, 9}, {9, 0, -9}, {-9, 0, -9}, fm);
        RenderScene rs = prepare_render_scene(std::move(b.m));
        rs.lights.push_back(Light::point({3, 6, 2}));
        scenes.emplace_back(std::move(rs), frame_scene(AABB{vec3(-2), vec3(2)}, 80, 60));
    }
    for (auto& [rs, cam] : scenes)
        for (ShaderKind k : {ShaderKind::whitted, ShaderKind::ao})
            for (unsigned spp : {2u, 4u}) {
                RenderSettings set;
                set.spp = spp;
                set.shade.shader = k;
                set.shade.ao_samples = 3;
                set.shade.max_depth = 3;
                set.threads = 1;
                RenderStats s1, s2;
                const Image a = render_cpu(rs.view(), cam, set, &s1);
                set.threads = 2;
                const Image b = render_cpu(rs.view(), cam, set, &s2);
                ASSERT_EQ(a.pixels.size(), b.pixels.size());
                EXPECT_EQ(std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(vec4)), 0)
                    << shader_name(k) << " spp " << spp;
                EXPECT_EQ(s1.rays.total(), s2.rays.total());
                EXPECT_EQ(s2.threads, 2u);
                // and a different seed changes the jitter
                set.seed = 99;
                const Image c = render_cpu(rs.view(), cam, set);
                EXPECT_NE(std::memcmp(a.pixels.data(), c.pixels.data(), a.pixels.size() * sizeof(vec4)), 0);
            }
}

TEST(Render, EveryTreeAndLeafStoreGiveTheSameImage) {
    // The image may not depend on the tree (a plain binned-SAH tree, one built for blocks, a
    // PLOC tree) nor on what the traversals walk (the blocks or the binary tree): ties go to the
    // smaller triangle index everywhere.
    Mesh m = make_bumpy_torus(20000);
    BuildOptions ploc;
    ploc.builder = BuildOptions::Builder::ploc;
    RenderScene a = prepare_render_scene(m), b = prepare_render_scene(m, BuildOptions{}),
                c = prepare_render_scene(m, ploc);
    const Camera cam = frame_scene(a.bounds(), 64, 48);
    a.lights.push_back(default_key_light(cam));
    b.lights = c.lights = a.lights;
    for (const ShaderKind k : {ShaderKind::whitted, ShaderKind::normals, ShaderKind::ao}) {
        RenderSettings set;
        set.spp = 2;
        set.shade.shader = k;
        const Image ia = render_cpu(a.view(), cam, set);
        ShadeScene binary = a.view();
        binary.trees = SceneTrees::binary;
        for (const ShadeScene& v : {b.view(), c.view(), binary}) {
            const Image ib = render_cpu(v, cam, set);
            EXPECT_EQ(std::memcmp(ia.pixels.data(), ib.pixels.data(), ia.pixels.size() * sizeof(vec4)), 0)
                << shader_name(k);
        }
    }
}

TEST(Render, InstancedSceneRendersAsItsWorldMesh) {
    // Two objects placed four times (rotated past pi, scaled unevenly, translated) against the
    // oracle: the same triangles mapped to world space as one mesh at the identity. Hits equal
    // up to the rounding of the transforms, so pixels may differ only along silhouettes.
    RenderScene rs;
    const std::uint32_t torus = rs.add_object(make_bumpy_torus(8000));
    const std::uint32_t ball = rs.add_object(make_icosphere(3));
    rs.scene.add_instance(torus);
    rs.scene.add_instance(torus, glm::rotate(glm::translate(mat4(1.0f), vec3(2.5f, 0.3f, -1.0f)), 4.0f,
                                             glm::normalize(vec3(1.0f, 2.0f, 0.5f))));
    rs.scene.add_instance(ball, glm::scale(glm::translate(mat4(1.0f), vec3(-2.0f, 0.5f, 0.5f)), vec3(0.6f, 1.3f, 0.9f)));
    rs.scene.add_instance(ball, glm::translate(mat4(1.0f), vec3(0.0f, 2.0f, -2.0f)));
    rs.scene.update_top_level();
    RenderScene flat = prepare_render_scene(rs.scene.world_mesh().first);
    const Camera cam = frame_scene(flat.bounds(), 96, 72);
    rs.lights.push_back(default_key_light(cam));
    flat.lights = rs.lights;
    for (const ShaderKind k : {ShaderKind::whitted, ShaderKind::normals}) {
        RenderSettings set;
        set.shade.shader = k;
        set.jitter = false;
        const Image a = render_cpu(rs.view(), cam, set), b = render_cpu(flat.view(), cam, set);
        std::size_t differ = 0, covered = 0;
        for (std::size_t i = 0; i < a.pixels.size(); ++i) {
            covered += b.pixels[i].w > 0.0f;
            const vec4 d = glm::abs(a.pixels[i] - b.pixels[i]);
            differ += std::max(std::max(d.x, d.y), std::max(d.z, d.w)) > 2e-3f;
        }
        std::printf("[ info ] %s: %zu of %zu covered pixels differ from the world-mesh oracle\n", shader_name(k),
                    differ, covered);
        EXPECT_GT(covered, a.pixels.size() / 20);
        EXPECT_LE(differ, covered / 50) << shader_name(k);
    }
}

// ---------------------------------------------------------------- FrameLoop

namespace {

/// A vertex hook: a wave through the object at time t, plus (from `throw_at`) a sector
/// of it thrown away by `throw_by`, which breaks the tree's neighbourhoods.
Vertex wave(const Vertex& v, float t, float throw_by = 0.0f) {
    Vertex o = v;
    o.position.y += 0.15f * std::sin(4.0f * v.position.x + t);
    if (v.position.x > 0.6f) o.position += vec3(throw_by, 0.5f * throw_by, 0.0f);
    o.normal = glm::normalize(v.normal + vec3(0.0f, 0.1f * std::cos(t), 0.0f));
    return o;
}

/// The scene of the FrameLoop tests: a static torus at the identity and a dynamic sphere (with
/// vertex normals) placed by a turned, scaled instance; `sphere` replaces the sphere's mesh.
RenderScene two_object_scene(const Mesh& sphere, ObjectKind kind) {
    RenderScene rs;
    const std::uint32_t torus = rs.add_object(make_bumpy_torus(6000));
    const std::uint32_t ball = rs.add_object(sphere, kind);
    rs.scene.add_instance(torus);
    rs.scene.add_instance(ball, glm::scale(glm::rotate(glm::translate(mat4(1.0f), vec3(0.3f, 0.9f, 0.2f)), 3.5f,
                                                       vec3(0.0f, 1.0f, 0.0f)),
                                           vec3(0.5f)));
    rs.scene.update_top_level();
    return rs;
}

}  // namespace

TEST(FrameLoop, EachFrameEqualsTheSceneBuiltFromScratch) {
    // Oracle: for each frame, a scene built anew from the vertices the hook gives (static
    // objects, fresh trees), rendered by render_cpu. The loop refits in place (or rebuilds)
    // instead; the image must be the same bit for bit, and the static object untouched.
    Mesh sphere = make_icosphere(3);
    sphere.normals = sphere.positions;
    RenderScene rs = two_object_scene(sphere, ObjectKind::dynamic);
    const Camera cam = frame_scene(rs.bounds(), 80, 60);
    rs.lights.push_back(default_key_light(cam));
    const std::vector<vec3> static_before = rs.scene.objects()[0].mesh.positions;
    const auto static_nodes = rs.scene.objects()[0].bvh.nodes;
    RenderSettings set;
    set.jitter = false;
    set.shade.max_depth = 1;
    FrameLoop loop(rs, set);
    std::uint32_t rebuilds = 0;
    for (int f = 0; f < 6; ++f) {
        const float t = 0.7f * float(f), throw_by = f >= 3 ? 1.5f : 0.0f;
        const Image img = loop.render(cam, vertex_hook([&](std::uint32_t object, const Vertex& v, std::uint32_t) {
            EXPECT_EQ(object, 1u);
            return wave(v, t, throw_by);
        }));
        rebuilds += loop.last().rebuilt;
        Mesh moved = sphere;
        for (std::size_t i = 0; i < moved.positions.size(); ++i) {
            const Vertex v = wave(Vertex{sphere.positions[i], sphere.normals[i], vec2(0.0f)}, t, throw_by);
            moved.positions[i] = v.position;
            moved.normals[i] = v.normal;
        }
        RenderScene fresh = two_object_scene(moved, ObjectKind::static_object);
        fresh.lights = rs.lights;
        const Image want = render_cpu(fresh.view(), cam, set);
        ASSERT_EQ(img.pixels.size(), want.pixels.size());
        EXPECT_EQ(std::memcmp(img.pixels.data(), want.pixels.data(), img.pixels.size() * sizeof(vec4)), 0)
            << "frame " << f;
        std::printf("[ info ] frame %d: vertex %.3f refit %.3f top %.3f render %.2f ms, growth %.3f, %s\n", f,
                    loop.last().ms.vertex, loop.last().ms.refit, loop.last().ms.top, loop.last().ms.render,
                    loop.last().worst_growth, loop.last().rebuilt ? "rebuilt" : "refitted");
        EXPECT_GT(loop.last().render.rays.primary, 0u);
    }
    // the thrown sector breaks the neighbourhoods: the policy rebuilds once, then refits again
    EXPECT_EQ(rebuilds, 1u);
    EXPECT_EQ(rs.scene.objects()[0].mesh.positions, static_before);
    ASSERT_EQ(rs.scene.objects()[0].bvh.nodes.size(), static_nodes.size());
    EXPECT_EQ(std::memcmp(rs.scene.objects()[0].bvh.nodes.data(), static_nodes.data(),
                          static_nodes.size() * sizeof(Node)),
              0);
}

TEST(FrameLoop, MovedButNotUpdatedObjectsCannotBeTraced) {
    Mesh sphere = make_icosphere(2);
    RenderScene rs = two_object_scene(sphere, ObjectKind::dynamic);
    rs.scene.write_vertices(1, [](const Vertex& v, std::uint32_t) { return wave(v, 1.0f); });
    EXPECT_THROW(rs.scene.update_top_level(), std::logic_error);
    EXPECT_THROW((void)rs.scene.intersect_closest(Ray{vec3(0.0f, 5.0f, 0.0f), 0.0f, vec3(0.0f, -1.0f, 0.0f), kInf}),
                 std::logic_error);
    EXPECT_THROW(rs.scene.write_vertices(0, [](const Vertex& v, std::uint32_t) { return v; }), std::logic_error);
    rs.scene.update_object(1, TreeUpdate::refit);
    EXPECT_NO_THROW(rs.scene.update_top_level());
    const Ray down{vec3(0.3f, 5.0f, 0.2f), 0.0f, vec3(0.0f, -1.0f, 0.0f), kInf};
    const Hit h = rs.scene.intersect_closest(down);
    EXPECT_EQ(h.inst, 1u);  // the sphere sits above the torus at (0.3, 0.9, 0.2)
    const Hit o = rs.scene.brute_force_closest(down);
    EXPECT_EQ(h.prim, o.prim);
    EXPECT_EQ(h.t, o.t);
}

// ---------------------------------------------------------------- CPU ray hooks

TEST(RayHook, FogAtDensityZeroIsWhittedWithoutBounces) {
    // The user hook of examples/fog_hook.hpp against the built-in Whitted shader: with no fog,
    // no bounces and no specular material the two compute the same sum (in another order).
    RenderScene rs = two_object_scene(make_icosphere(3), ObjectKind::static_object);
    const Camera cam = frame_scene(rs.bounds(), 96, 72);
    rs.lights.push_back(default_key_light(cam));
    rs.lights.push_back(Light::directional(vec3(0.3f, -1.0f, 0.2f), vec3(0.4f)));
    RenderSettings set;
    set.spp = 2;
    set.shade.max_depth = 0;
    set.shade.background = vec3(0.7f, 0.75f, 0.8f);  // = the fog colour: misses agree too
    RenderStats ws, fs;
    const Image want = render_cpu(rs.view(), cam, set, &ws);
    const Image got = render_hook_cpu<FogHook>(rs.view(), cam, set, FogHook::Params{0.0f, 0.7f, 0.75f, 0.8f}, &fs);
    float worst = 0.0f;
    std::size_t lit = 0;
    for (std::size_t i = 0; i < want.pixels.size(); ++i) {
        const vec4 d = glm::abs(want.pixels[i] - got.pixels[i]);
        worst = std::max({worst, d.x, d.y, d.z, d.w});
        lit += want.pixels[i].w > 0.0f;
    }
    std::printf("[ info ] fog(0) vs whitted: worst difference %g over %zu pixels (%zu covered); rays %llu / %llu\n",
                worst, want.pixels.size(), lit, (unsigned long long)fs.rays.total(),
                (unsigned long long)ws.rays.total());
    EXPECT_LT(worst, 1e-5f);
    EXPECT_GT(lit, want.pixels.size() / 20);
    EXPECT_EQ(fs.rays.primary, ws.rays.primary);
    EXPECT_EQ(fs.rays.shadow, ws.rays.shadow);  // the same shadow rays
}

TEST(RayHook, FogThickensWithDistanceAndIgnoresThreads) {
    // Two equal spheres, one four times as far: with fog the far one is nearer the fog colour.
    RenderScene rs;
    const std::uint32_t ball = rs.add_object(make_icosphere(3));
    rs.scene.add_instance(ball, glm::translate(mat4(1.0f), vec3(-1.2f, 0.0f, 0.0f)));
    rs.scene.add_instance(ball, glm::scale(glm::translate(mat4(1.0f), vec3(4.0f, 0.0f, -12.0f)), vec3(4.0f)));
    rs.scene.update_top_level();
    Camera cam;
    cam.position = vec3(0.0f, 0.0f, 6.0f);
    cam.target = vec3(0.0f, 0.0f, 0.0f);
    cam.width = 96;
    cam.height = 48;
    rs.lights.push_back(Light::point(vec3(0.0f, 10.0f, 10.0f)));
    RenderSettings set;
    set.jitter = false;
    set.threads = 1;
    const FogHook::Params fog{0.08f, 0.7f, 0.75f, 0.8f};
    const Image a = render_hook_cpu<FogHook>(rs.view(), cam, set, fog);
    set.threads = 2;
    const Image b = render_hook_cpu<FogHook>(rs.view(), cam, set, fog);
    EXPECT_EQ(std::memcmp(a.pixels.data(), b.pixels.data(), a.pixels.size() * sizeof(vec4)), 0);
    // distance of each sphere's covered pixels' colour from the fog colour
    const vec3 fc(fog.r, fog.g, fog.b);
    double near_sum = 0.0, far_sum = 0.0;
    int near_n = 0, far_n = 0;
    for (std::uint32_t y = 0; y < cam.height; ++y)
        for (std::uint32_t x = 0; x < cam.width; ++x) {
            const vec4 p = a.at(x, y);
            if (p.w == 0.0f) continue;
            const double d = glm::length(vec3(p) - fc);
            if (x < cam.width / 2) near_sum += d, ++near_n;
            else far_sum += d, ++far_n;
        }
    ASSERT_GT(near_n, 50);
    ASSERT_GT(far_n, 50);
    std::printf("[ info ] mean distance from the fog colour: near sphere %.4f, far sphere %.4f\n", near_sum / near_n,
                far_sum / far_n);
    EXPECT_LT(far_sum / far_n, 0.6 * (near_sum / near_n));
}

// ---------------------------------------------------------------- `raykit render`

namespace {
int run_cli(std::vector<std::string> args) {
    args.insert(args.begin(), {"raykit", "render"});
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    return raykit_cli_render(int(argv.size()), argv.data(), 2);
}
}  // namespace

TEST(CliRender, WritesPngAndPfmAndRejectsBadUsage) {
    const auto dir = temp_dir("cli");
    {
        std::ofstream obj(dir / "scene.obj");
        obj << "mtllib scene.mtl\nv -1 -1 0\nv 1 -1 0\nv 1 1 0\nv -1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\n"
               "usemtl a\nf 1/1 2/2 3/3 4/4\n";
        std::ofstream mtl(dir / "scene.mtl");
        mtl << "newmtl a\nKd 0.8 0.6 0.4\nmap_Kd missing_texture.png\n";
    }
    const std::string obj = (dir / "scene.obj").string(), png = (dir / "out.png").string(),
                      pfm = (dir / "out.pfm").string();
    std::filesystem::remove(png);
    EXPECT_EQ(run_cli({obj, png, "--width", "40", "--height", "30", "--spp", "2", "--quiet", "--pfm", pfm,
                       "--light", "0", "0", "5", "1", "1", "1", "--camera", "0", "0", "4", "0", "0", "0", "--threads",
                       "2", "--shader", "whitted", "--max-depth", "2", "--filter", "nearest"}),
              0);
    const Texture t = load_texture(png, true);
    EXPECT_FALSE(t.placeholder);
    EXPECT_EQ(t.width, 40u);
    EXPECT_EQ(t.height, 30u);
    const Image f = read_pfm(pfm);
    EXPECT_EQ(f.width, 40u);
    float brightest = 0.0f;  // the placeholder texture (magenta/black) on the quad
    for (const vec4& p : f.pixels) brightest = std::max(brightest, p.x);
    EXPECT_GT(brightest, 0.3f);
    // default camera and light, other shaders
    for (const char* shader : {"normals", "depth", "ao", "debug-cost"})
        EXPECT_EQ(run_cli({obj, png, "--width", "16", "--height", "12", "--shader", shader, "--quiet"}), 0) << shader;
    EXPECT_THROW(run_cli({obj, png, "--device", "cl", "--quiet"}), std::runtime_error);
    try {
        run_cli({obj, png, "--device", "cl"});
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("not available yet"), std::string::npos);
    }
    EXPECT_THROW(run_cli({obj}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, png, "--spp", "0"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, png, "--shader", "toon"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, png, "--camera", "1", "2"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, png, "--width", "abc"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, png, "--frobnicate"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({obj, png, "--camera", "0", "0", "0", "0", "0", "0", "--quiet"}), RaykitCliRenderUsageError);
    EXPECT_THROW(run_cli({(dir / "missing.obj").string(), png, "--quiet"}), ParseError);
}
