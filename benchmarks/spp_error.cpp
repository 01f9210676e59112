// benchmarks/spp_error.cpp — image error against samples per pixel and texture filter, with cost.
//
//   spp_error [OUT_DIR] [--threads T] [--ref-spp N]
//
// Prints CSV to stdout (and writes OUT_DIR/render_spp_error.csv when OUT_DIR is given):
//   scene,filter,spp,rmse,ms,mrays_s
// For each scene and texture filter (bilinear, nearest) and spp in {1, 2, 4, 8, 16}: the RMSE
// (linear RGB, raykit::rmse) of the image against a reference rendered with --ref-spp (default
// 256) samples per pixel and bilinear filtering, and the render time (best of 3 frames, wall ms,
// T threads, default 2). The reference uses a different seed than the measured frames, so its
// own noise does not correlate with theirs; its residual error (about RMSE(1 spp) / 16) is the
// floor the curves flatten towards.
// Scenes, 320 x 240, Whitted, max depth 1, one point light with shadows:
//   thesis    RAYKIT_SHARED_DATA_DIR/obj/thesis_scene/Scene.obj from (20, 8, 24) to (0, 2.5, 0)
//             (the view of docs/thesis_scene.png): geometric edges, foliage cut-outs and
//             minified textures
//   closeup   a 2 x 2 quad textured with obj/helix/texturetest/texturetest.png (256 x 256) seen
//             at a grazing angle from (0, -0.45, 0.2): the near part magnified to several pixels
//             per texel, the far part minified — where nearest and bilinear differ most
// A scene whose data file is missing is left out. benchmarks/plot_render.py turns the CSV into
// docs/render_spp_error.png and docs/render_texture_filter.png.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/render/render_cpu.hpp"

#ifndef RAYKIT_SHARED_DATA_DIR
#define RAYKIT_SHARED_DATA_DIR "../shared/data"
#endif

namespace {

using namespace raykit;

struct Case {
    std::string name;
    RenderScene rs;
    Camera cam;
};

std::filesystem::path data(const char* rel) { return std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / rel; }

bool make_thesis(Case& c) {
    const auto file = data("obj/thesis_scene/Scene.obj");
    if (!std::filesystem::exists(file)) return false;
    c.name = "thesis";
    c.rs = prepare_render_scene(load_obj(file));
    c.cam.position = {20.0f, 8.0f, 24.0f};
    c.cam.target = {0.0f, 2.5f, 0.0f};
    c.rs.lights.push_back(Light::point({-25.0f, 35.0f, 30.0f}));
    return true;
}

bool make_closeup(Case& c) {
    const auto tex = data("obj/helix/texturetest/texturetest.png");
    if (!std::filesystem::exists(tex)) return false;
    c.name = "closeup";
    Mesh m;
    m.positions = {{-1, -1, 0}, {1, -1, 0}, {1, 1, 0}, {-1, 1, 0}};
    m.texcoords = {{0, 0}, {1, 0}, {1, 1}, {0, 1}};
    m.triangles = {{{0, 1, 2}}, {{0, 2, 3}}};
    Material mat;
    mat.kd = vec3(1.0f);
    mat.map_kd = tex.string();
    m.materials = {mat};
    m.material_ids = {0, 0};
    c.rs = prepare_render_scene(std::move(m));
    c.cam.position = {0.0f, -0.45f, 0.2f};
    c.cam.target = {0.0f, 0.05f, 0.0f};
    c.cam.up = {0.0f, 0.0f, 1.0f};
    c.cam.vfov_degrees = 50.0f;
    c.rs.lights.push_back(Light::point({0.0f, -1.0f, 3.0f}));
    return true;
}

}  // namespace

int main(int argc, char** argv) {
    std::string out_dir;
    unsigned threads = 2, ref_spp = 256;
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--threads" && i + 1 < argc) threads = unsigned(std::stoul(argv[++i]));
        else if (a == "--ref-spp" && i + 1 < argc) ref_spp = unsigned(std::stoul(argv[++i]));
        else if (!a.empty() && a[0] != '-') out_dir = a;
        else {
            std::fprintf(stderr, "usage: spp_error [OUT_DIR] [--threads T] [--ref-spp N]\n");
            return 2;
        }
    }
    std::vector<Case> cases;
    try {
        for (auto make : {make_thesis, make_closeup}) {
            Case c;
            if (make(c)) {
                c.cam.width = 320;
                c.cam.height = 240;
                cases.push_back(std::move(c));
            } else {
                std::fprintf(stderr, "spp_error: data for a scene missing under %s, left out\n", RAYKIT_SHARED_DATA_DIR);
            }
        }
    } catch (const std::exception& e) {
        std::fprintf(stderr, "spp_error: %s\n", e.what());
        return 1;
    }

    std::ostringstream csv;
    csv << "scene,filter,spp,rmse,ms,mrays_s\n";
    std::cout << csv.str() << std::flush;
    for (Case& c : cases) {
        RenderSettings set;
        set.threads = threads;
        set.shade.max_depth = 1;
        set.spp = ref_spp;
        set.seed = 0xC0FFEE;
        std::fprintf(stderr, "spp_error: %s reference, %u spp ...\n", c.name.c_str(), ref_spp);
        const Image ref = render_cpu(c.rs.view(), c.cam, set);
        set.seed = 0;
        for (TextureFilter f : {TextureFilter::bilinear, TextureFilter::nearest})
            for (unsigned spp : {1u, 2u, 4u, 8u, 16u}) {
                set.spp = spp;
                set.shade.filter = f;
                RenderStats st;
                Image img;
                double best = 1e30, mrays = 0.0;
                for (int rep = 0; rep < 3; ++rep) {
                    img = render_cpu(c.rs.view(), c.cam, set, &st);
                    if (st.render_ms < best) best = st.render_ms, mrays = st.mrays_per_second();
                }
                char line[256];
                std::snprintf(line, sizeof line, "%s,%s,%u,%.6f,%.2f,%.3f\n", c.name.c_str(), texture_filter_name(f),
                              spp, rmse(img, ref), best, mrays);
                csv << line;
                std::cout << line << std::flush;
            }
    }
    if (!out_dir.empty()) {
        const auto file = std::filesystem::path(out_dir) / "render_spp_error.csv";
        std::ofstream out(file);
        out << csv.str();
        if (!out) {
            std::fprintf(stderr, "spp_error: cannot write %s\n", file.string().c_str());
            return 1;
        }
        std::fprintf(stderr, "spp_error: wrote %s\n", file.string().c_str());
    }
    return 0;
}
