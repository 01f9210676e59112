// The raykit command line, driven as a user would: exit codes, messages, and
// trace output checked against brute force over all triangles.
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <random>
#include <set>
#include <sstream>
#include <string>

#include "raykit.hpp"
#include "raykit/io/obj.hpp"
#include "raykit/io/obj_write.hpp"
#include "raykit/render/texture.hpp"
#include "raykit/scene/generate.hpp"

#ifndef RAYKIT_CLI_PATH
#error "RAYKIT_CLI_PATH must name the raykit executable"
#endif

using namespace raykit;
namespace fs = std::filesystem;

namespace {

struct Result {
    int code;
    std::string out, err;
};

/// This process's scratch folder, emptied at first use: process ids come round again, and
/// files an earlier process of the same id left (one.png) made tests that expect a file to
/// be absent fail now and then.
fs::path tmpdir() {
    static const fs::path dir = [] {
        fs::path d = fs::temp_directory_path() / ("raykit_cli_test_" + std::to_string(::getpid()));
        fs::remove_all(d);
        fs::create_directories(d);
        return d;
    }();
    return dir;
}

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

Result run(const std::string& args) {
    const fs::path out = tmpdir() / "stdout.txt", err = tmpdir() / "stderr.txt";
    const std::string cmd =
        std::string(RAYKIT_CLI_PATH) + " " + args + " >" + out.string() + " 2>" + err.string();
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), slurp(out), slurp(err)};
}

void write(const fs::path& p, const std::string& text) {
    std::ofstream(p, std::ios::binary) << text;
}

/// The last line of stderr must be a one-line reason starting "raykit: error:".
void expect_clean_error(const Result& r, int code, const std::string& needle) {
    EXPECT_EQ(r.code, code) << r.err;
    EXPECT_NE(r.err.find("raykit: error: "), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(needle), std::string::npos) << "stderr was: " << r.err;
    EXPECT_LT(r.code, 128) << "crashed";
}

}  // namespace

TEST(Cli, UsageErrorsExitWithTwo) {
    expect_clean_error(run(""), 2, "no command");
    expect_clean_error(run("frobnicate"), 2, "unknown command");
    expect_clean_error(run("info"), 2, "info takes one");
    expect_clean_error(run("info a.obj --nope"), 2, "not expected: --nope");
    expect_clean_error(run("info a.obj --leaf-size"), 2, "--leaf-size: 1 required N missing");
    expect_clean_error(run("info a.obj --leaf-size x"), 2, "--leaf-size: expects a number");
    expect_clean_error(run("info a.obj --builder magic"), 2, "--builder: magic not in {sah,pairwise,sortaxis,ploc}");
    expect_clean_error(run("info a.obj --leaf-block 3"), 2, "--leaf-block: 3 not in {1,2,4,8,16}");
    expect_clean_error(run("info a.obj --builder sortaxis --pairing best"), 2, "--pairing: best not in");
    expect_clean_error(run("info a.obj --builder ploc --optimize maybe"), 2, "--optimize: maybe not in {on,off}");
    expect_clean_error(run("trace a.obj r.txt"), 2, "HITS.txt is required");
    expect_clean_error(run("trace a.obj r.txt h.txt --test fancy"), 2, "--test: fancy not in {watertight,mt,thesis}");
    EXPECT_EQ(run("--help").code, 0);
}

TEST(Cli, MissingAndMalformedFilesExitWithOne) {
    expect_clean_error(run("info /nonexistent/scene.obj"), 1, "/nonexistent/scene.obj");
    const fs::path bad = tmpdir() / "bad.obj";
    write(bad, "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n");
    expect_clean_error(run("info " + bad.string()), 1, "bad.obj:4");
    write(bad, "v 0 0 0\nv 1 nan 0\n");
    expect_clean_error(run("check " + bad.string()), 1, "bad.obj:2");
}

TEST(Cli, MalformedRaysNameTheLine) {
    const fs::path scene = tmpdir() / "sphere.obj", rays = tmpdir() / "rays.txt", hits = tmpdir() / "hits.txt";
    save_obj(make_icosphere(2), scene);
    const std::string good = "0 0 -5 0 0 1 0 inf\n";
    const std::string base = "trace " + scene.string() + " " + rays.string() + " " + hits.string();
    write(rays, good + "0 0 -5 0 0 1 0\n");
    expect_clean_error(run(base), 1, "rays.txt:2");
    write(rays, good + good + "0 0 -5 0 zero 1 0 inf\n");
    expect_clean_error(run(base), 1, "rays.txt:3");
    write(rays, "0 0 nan 0 0 1 0 inf\n");
    expect_clean_error(run(base), 1, "rays.txt:1");
    write(rays, "0 0 -5 0 0 1 0 inf 7\n");
    expect_clean_error(run(base), 1, "rays.txt:1");
    write(rays, "inf 0 -5 0 0 1 0 inf\n");
    expect_clean_error(run(base), 1, "rays.txt:1");
    expect_clean_error(run("trace " + scene.string() + " /nonexistent/rays.txt " + hits.string()), 1, "rays.txt");
}

TEST(Cli, TraceMatchesBruteForce) {
    Mesh m = make_bumpy_torus(5000);
    transform_positions(m, 10.0f, vec3(1e5f, 0.0f, -3.0f));  // away from the origin
    const fs::path scene = tmpdir() / "torus.obj", rays = tmpdir() / "rays2.txt", hits = tmpdir() / "hits2.txt",
                   anyf = tmpdir() / "any2.txt";
    save_obj(m, scene);
    const Mesh loaded = load_obj(scene);  // what the CLI sees (9 significant digits round-trip exactly)
    ASSERT_EQ(loaded.positions, m.positions);
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::ostringstream text;
    std::vector<Ray> rs;
    for (int i = 0; i < 2000; ++i) {
        Ray r;
        r.org = vec3(1e5f, 0.0f, -3.0f) + vec3(U(rng), U(rng), U(rng)) * 20.0f;
        const Triangle& t = m.triangles[std::size_t(rng()) % m.triangles.size()];
        r.dir = (i % 3 == 0 ? m.positions[t.v[0]] : vec3(1e5f, 0.0f, -3.0f) + vec3(U(rng), U(rng), U(rng))) - r.org;
        r.tmax = i % 5 == 0 ? 0.5f : kInf;
        rs.push_back(r);
        char line[256];
        std::snprintf(line, sizeof line, "%.9g %.9g %.9g %.9g %.9g %.9g %.9g %s\n", r.org.x, r.org.y, r.org.z,
                      r.dir.x, r.dir.y, r.dir.z, r.tmin, i % 5 == 0 ? "0.5" : "inf");
        text << line;
    }
    write(rays, text.str());
    Result r = run("trace " + scene.string() + " " + rays.string() + " " + hits.string());
    ASSERT_EQ(r.code, 0) << r.err;
    r = run("trace " + scene.string() + " " + rays.string() + " " + anyf.string() + " --any-hit");
    ASSERT_EQ(r.code, 0) << r.err;
    std::istringstream h(slurp(hits)), a(slurp(anyf));
    std::size_t bad = 0, hitcount = 0;
    for (const Ray& ray : rs) {
        long prim;
        float t, u, v;
        int any;
        ASSERT_TRUE(h >> prim >> t >> u >> v);
        ASSERT_TRUE(a >> any);
        const Hit o = brute_force_closest(m, ray);
        hitcount += o.valid();
        if (o.valid() ? (prim != long(o.prim) || t != o.t) : prim != -1) ++bad;
        if (any != int(o.valid())) ++bad;
    }
    EXPECT_EQ(bad, 0u);
    EXPECT_GT(hitcount, 500u);
    // a tree built for 4-triangle blocks (another tree, same test): the same HITS, byte for byte
    const fs::path hits_blk = tmpdir() / "hits2_blk.txt";
    r = run("trace " + scene.string() + " " + rays.string() + " " + hits_blk.string() + " --leaf-block 4 --leaf-size 12");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(slurp(hits_blk), slurp(hits));
}

TEST(Cli, InfoJsonAndCheck) {
    const fs::path scene = tmpdir() / "soup.obj";
    save_obj(make_random_soup(2000, 3), scene);
    Result r = run("info " + scene.string() + " --json");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("\"triangles\": 2000"), std::string::npos) << r.out;
    EXPECT_NE(r.out.find("\"sah_cost\": "), std::string::npos) << r.out;
    r = run("check " + scene.string() + " --rays 500 --seed 3");
    EXPECT_EQ(r.code, 0) << r.out << r.err;
    EXPECT_NE(r.out.find("0 disagreements"), std::string::npos) << r.out;
    r = run("info " + scene.string() + " --json --leaf-block 4 --leaf-size 12");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("\"leaf_block\": 4"), std::string::npos) << r.out;
    r = run("check " + scene.string() + " --rays 500 --seed 4 --leaf-block 4 --leaf-size 12 --builder ploc");
    EXPECT_EQ(r.code, 0) << r.out << r.err;
    // flags left out take the builder's own defaults (sortaxis: area, mutual, W 2; ploc: post-pass on)
    const auto sah_of = [&](const std::string& flags) {
        const Result x = run("info " + scene.string() + " --json " + flags);
        EXPECT_EQ(x.code, 0) << flags << ": " << x.err;
        const auto at = x.out.find("\"sah_cost\": ");
        return at == std::string::npos ? std::string("?") : x.out.substr(at, x.out.find_first_of(",}", at) - at);
    };
    EXPECT_EQ(sah_of("--builder sortaxis"), sah_of("--builder sortaxis --metric area --pairing mutual --window 2"));
    EXPECT_NE(sah_of("--builder sortaxis"), sah_of("--builder sortaxis --pairing greedy --window 6"));
    EXPECT_EQ(sah_of("--builder ploc"), sah_of("--builder ploc --optimize on"));
    EXPECT_NE(sah_of("--builder ploc"), sah_of("--builder ploc --optimize off"));
    r = run("generate torus " + (tmpdir() / "t.obj").string() + " --tris 1000");
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(load_obj(tmpdir() / "t.obj").triangle_count(), 1024u);  // 2·nu·nv, nv = 16, nu = 32
}

#if RAYKIT_CLI_HAVE_CL
TEST(Cli, DeviceTraceWritesTheSameHitsAsTheCpu) {
    const fs::path scene = tmpdir() / "dev.obj", rays = tmpdir() / "dev_rays.txt";
    save_obj(make_bumpy_torus(8000), scene);
    std::mt19937 rng(9);
    std::uniform_real_distribution<float> U(-2.0f, 2.0f);
    std::ostringstream text;
    for (int i = 0; i < 3000; ++i) {
        char line[256];
        std::snprintf(line, sizeof line, "%.9g %.9g %.9g %.9g %.9g %.9g 0 inf\n", U(rng), U(rng), U(rng), U(rng),
                      U(rng), U(rng));
        text << line;
    }
    write(rays, text.str());
    for (const char* any : {"", " --any-hit"}) {
        const fs::path a = tmpdir() / "dev_cpu.txt", b = tmpdir() / "dev_cl.txt";
        Result r = run("trace " + scene.string() + " " + rays.string() + " " + a.string() + any);
        ASSERT_EQ(r.code, 0) << r.err;
        r = run("trace " + scene.string() + " " + rays.string() + " " + b.string() + any + " --device cl");
        if (r.code != 0 && r.err.find("no OpenCL") != std::string::npos) GTEST_SKIP() << r.err;
        ASSERT_EQ(r.code, 0) << r.err;
        EXPECT_EQ(slurp(a), slurp(b)) << "device and CPU HITS files differ" << any;
    }
    const Result d = run("info --device");
    EXPECT_EQ(d.code, 0) << d.err;
}

TEST(Cli, DeviceRenderTakesEveryShaderAndSpp) {
    const fs::path scene = tmpdir() / "dev_render.obj", png = tmpdir() / "dev_render.png";
    save_obj(make_icosphere(2), scene);
    for (const char* shader : {"whitted", "normals", "depth", "ao", "debug-cost"}) {
        const Result r = run("render " + scene.string() + " " + png.string() +
                             " --device cl --spp 4 --width 32 --height 24 --shader " + shader);
        if (r.code != 0 && r.err.find("no OpenCL") != std::string::npos) GTEST_SKIP() << r.err;
        EXPECT_EQ(r.code, 0) << shader << ": " << r.err;
        EXPECT_NE(r.out.find(std::string("4 spp, ") + shader), std::string::npos) << r.out;
    }
}
#endif

// ------------------------------------------------------------------ issue 12: inputs (OBJ, MTL, RAYS readers)

TEST(CliInputs, TraceRefusesADirectoryAsRaysAndWritesNoHits) {
    const fs::path scene = tmpdir() / "in_sphere.obj", hits = tmpdir() / "in_hits.txt";
    save_obj(make_icosphere(1), scene);
    const fs::path dir = tmpdir() / "rays_dir";
    fs::create_directories(dir);
    fs::remove(hits);
    const Result r = run("trace " + scene.string() + " " + dir.string() + " " + hits.string());
    expect_clean_error(r, 1, dir.string() + ": is a directory");
    EXPECT_FALSE(fs::exists(hits)) << "a HITS file was written";
}

TEST(CliInputs, DeviceFilesAreRefusedNotReadForever) {
    if (!fs::exists("/dev/zero")) GTEST_SKIP() << "no /dev/zero";
    expect_clean_error(run("info /dev/zero"), 1, "/dev/zero: is not a regular file");
    const fs::path scene = tmpdir() / "in_sphere2.obj";
    save_obj(make_icosphere(1), scene);
    expect_clean_error(run("trace " + scene.string() + " /dev/zero " + (tmpdir() / "h.txt").string()), 1,
                       "/dev/zero: is not a regular file");
}

TEST(CliInputs, RaysUseTheObjNumberRule) {
    const fs::path scene = tmpdir() / "in_sphere3.obj", rays = tmpdir() / "in_rays.txt",
                   hits = tmpdir() / "in_hits3.txt";
    save_obj(make_icosphere(2), scene);
    write(rays, "0 0 -5 1e-46 0 1 0 inf\n");  // was "not a number"
    const Result r = run("trace " + scene.string() + " " + rays.string() + " " + hits.string());
    EXPECT_EQ(r.code, 0) << r.err;
    write(rays, "0 0 -5 0 0 1 0 1e39\n");
    expect_clean_error(run("trace " + scene.string() + " " + rays.string() + " " + hits.string()), 1,
                       "in_rays.txt:1: number '1e39' overflows a float in 'tmax'");
}

TEST(CliInputs, ASceneWithoutTrianglesIsReported) {
    const fs::path smd = tmpdir() / "in_walk.smd";
    write(smd, "version 1\nnodes\n0 \"root\" -1\nend\nskeleton\ntime 0\n0 0 0 0 0 0 0\nend\n");
    const Result r = run("info " + smd.string());
    EXPECT_NE(r.err.find("raykit: warning: " + smd.string() + ": no triangles"), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("'.smd'"), std::string::npos) << r.err;
}

// ---- issue 12: every numeric flag bounded, every failure one honest line -------------------------

#if defined(__SANITIZE_ADDRESS__)
#define RAYKIT_CLI_TEST_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RAYKIT_CLI_TEST_ASAN 1
#endif
#endif

namespace {

/// Runs a shell line in which RAYKIT names the CLI; `timeout` turns a hang into exit 124.
Result run_sh(const std::string& line) {
    const fs::path out = tmpdir() / "stdout.txt", err = tmpdir() / "stderr.txt";
    const std::string cmd = "RAYKIT='" + std::string(RAYKIT_CLI_PATH) + "'; (" + line + ") >" + out.string() + " 2>" +
                            err.string();
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : 128 + WTERMSIG(status), slurp(out), slurp(err)};
}

/// The CLI with `args`, stopped after 60 s (a hang fails as exit 124, not as a stuck test).
Result run_bounded(const std::string& args) { return run_sh("timeout 60 \"$RAYKIT\" " + args); }

/// A failure as issue 12 wants it: exit `code`; stderr's one "raykit: error: " line is its last
/// and names `needle`; the usage text comes before it exactly when the exit is 2 (bad flags);
/// other lines are warnings.
void expect_one_error_line(const Result& r, int code, const std::string& needle, const std::string& what) {
    EXPECT_EQ(r.code, code) << what << "\nstderr: " << r.err;
    std::vector<std::string> lines;
    std::istringstream in(r.err);
    for (std::string l; std::getline(in, l);) lines.push_back(l);
    std::size_t errors = 0;
    for (const std::string& l : lines) errors += l.rfind("raykit: error: ", 0) == 0;
    EXPECT_EQ(errors, 1u) << what << "\nstderr: " << r.err;
    ASSERT_FALSE(lines.empty()) << what;
    EXPECT_EQ(lines.back().rfind("raykit: error: ", 0), 0u) << what << "\nstderr: " << r.err;
    EXPECT_NE(lines.back().find(needle), std::string::npos) << what << "\nstderr: " << r.err;
    const bool usage = r.err.rfind("usage:", 0) == 0;
    EXPECT_EQ(usage, code == 2) << what << "\nstderr: " << r.err;
    if (code != 2) {
        for (std::size_t i = 0; i + 1 < lines.size(); ++i)
            EXPECT_EQ(lines[i].rfind("raykit: warning: ", 0), 0u) << what << "\nline: " << lines[i];
    }
}

/// A small closed scene for the bound tests.
fs::path bounds_scene() {
    static const fs::path p = [] {
        const fs::path s = tmpdir() / "bounds_sphere.obj";
        save_obj(make_icosphere(1), s);
        return s;
    }();
    return p;
}

}  // namespace

// ------------------------------------------------------------------ raykit animate
// (examples/cli_animate.hpp; its argument rules are unit-tested in test_anim.cpp)

namespace {

/// An 8 x 8 24-bit BMP: red in the centre 4 x 4 texels, black elsewhere, so
/// uv (0.5, 0.5) samples red and uv (0, 0) (where lost texture coordinates
/// sample: a corner, blended with the other corners by wrap addressing) black.
void write_centre_red_bmp(const fs::path& p) {
    const int w = 8, h = 8;
    std::string px;
    for (int y = h - 1; y >= 0; --y) {  // bottom-up rows
        for (int x = 0; x < w; ++x) {
            const bool red = x >= 2 && x <= 5 && y >= 2 && y <= 5;
            px += std::string{'\0', '\0', red ? '\xC8' : '\0'};  // B G R
        }
    }
    auto u32 = [](std::uint32_t v) { return std::string{char(v), char(v >> 8), char(v >> 16), char(v >> 24)}; };
    auto u16 = [](std::uint16_t v) { return std::string{char(v), char(v >> 8)}; };
    std::string bmp = "BM" + u32(54 + std::uint32_t(px.size())) + u32(0) + u32(54);
    bmp += u32(40) + u32(w) + u32(h) + u16(1) + u16(24) + u32(0) + u32(std::uint32_t(px.size())) + u32(2835) +
           u32(2835) + u32(0) + u32(0);
    write(p, bmp + px);
}

/// A 2-unit cube on one bone (Half-Life 1 vertex lines), every corner at uv (0.5, 0.5).
std::string textured_cube_smd(const std::string& texture) {
    struct Face {
        int n[3];
        int q[4][3];
    };
    const Face faces[6] = {
        {{1, 0, 0}, {{1, -1, -1}, {1, 1, -1}, {1, 1, 1}, {1, -1, 1}}},
        {{-1, 0, 0}, {{-1, -1, -1}, {-1, -1, 1}, {-1, 1, 1}, {-1, 1, -1}}},
        {{0, 1, 0}, {{-1, 1, -1}, {-1, 1, 1}, {1, 1, 1}, {1, 1, -1}}},
        {{0, -1, 0}, {{-1, -1, -1}, {1, -1, -1}, {1, -1, 1}, {-1, -1, 1}}},
        {{0, 0, 1}, {{-1, -1, 1}, {1, -1, 1}, {1, 1, 1}, {-1, 1, 1}}},
        {{0, 0, -1}, {{-1, -1, -1}, {-1, 1, -1}, {1, 1, -1}, {1, -1, -1}}},
    };
    std::ostringstream s;
    s << "version 1\nnodes\n0 \"root\" -1\nend\nskeleton\ntime 0\n0 0 0 0 0 0 0\nend\ntriangles\n";
    for (const Face& f : faces) {
        const int tris[2][3] = {{0, 1, 2}, {0, 2, 3}};
        for (const auto& tri : tris) {
            s << texture << "\n";
            for (int i : tri) {
                const int* p = f.q[i];
                s << "0 " << p[0] << " " << p[1] << " " << p[2] + 1 << " " << f.n[0] << " " << f.n[1] << " " << f.n[2]
                  << " 0.5 0.5\n";
            }
        }
    }
    s << "end\n";
    return s.str();
}

/// Pixels of a PNG: total, not black, and pure red (the texture's colour only).
struct PixelCount {
    std::size_t total = 0, lit = 0, red = 0;
};
PixelCount count_pixels(const fs::path& png) {
    std::vector<std::string> warnings;
    const Texture img = load_texture(png, /*srgb=*/false, &warnings);
    EXPECT_FALSE(img.placeholder) << png << ": " << (warnings.empty() ? "" : warnings[0]);
    PixelCount c;
    for (std::size_t i = 0; i + 3 < img.rgba.size(); i += 4) {
        const int r = img.rgba[i], g = img.rgba[i + 1], b = img.rgba[i + 2];
        ++c.total;
        if (r + g + b > 0) ++c.lit;
        if (r > 20 && g == 0 && b == 0) ++c.red;
    }
    return c;
}

}  // namespace

TEST(CliBounds, ThreadCountsAboveTheLimitAreUsageErrors) {
    const std::string s = bounds_scene().string();
    const fs::path rays = tmpdir() / "bounds_rays.txt", hits = tmpdir() / "bounds_hits.txt";
    write(rays, "0 0 -5 0 0 1 0 inf\n");
    const std::string png = (tmpdir() / "bounds_threads.png").string();
    for (const std::string& cmd : {"info " + s, "check " + s + " --rays 10", "trace " + s + " " + rays.string() + " " +
                                  hits.string(), "render " + s + " " + png + " --width 8 --height 8 --quiet"})
        for (const char* t : {"4294967295", "2147483648", "1025", "-1", "99999999999999999999", "1e400", "2e3"})
            expect_one_error_line(run_bounded(cmd + " --threads " + t), 2, "--threads: must be in 0..1024",
                                  cmd + " --threads " + t);
    EXPECT_EQ(run_bounded("info " + s + " --threads 1024").code, 0);
    EXPECT_EQ(run_bounded("render " + s + " " + png + " --width 8 --height 8 --quiet --threads 1024").code, 0);
}

TEST(CliBounds, GenerateRejectsTriangleCountsItCannotMake) {
    const fs::path out = tmpdir() / "bounds_gen.obj";
    for (const char* kind : {"torus", "icosphere", "soup"})
        for (const char* n : {"0", "18446744073709551615", "4294967296", "1000001", "-3"}) {
            fs::remove(out);
            const std::string cmd = std::string("generate ") + kind + " " + out.string() + " --tris " + n;
            expect_one_error_line(run_bounded(cmd), 2, "--tris: must be in 1..1000000", cmd);
            EXPECT_FALSE(fs::exists(out)) << cmd;
        }
    expect_one_error_line(run_bounded("generate soup " + out.string() + " --seed -1"), 2, "--seed", "seed -1");
    ASSERT_EQ(run_bounded("generate icosphere " + out.string() + " --tris 20").code, 0);
    EXPECT_EQ(load_obj(out).triangle_count(), 20u);
    ASSERT_EQ(run_bounded("generate icosphere " + out.string() + " --tris 5119").code, 0);
    EXPECT_EQ(load_obj(out).triangle_count(), 1280u);  // the largest level that fits: 20·4^3
    ASSERT_EQ(run_bounded("generate soup " + out.string() + " --tris 1").code, 0);
    EXPECT_EQ(load_obj(out).triangle_count(), 1u);
}

TEST(CliBounds, RenderFlagsOutOfRangeAreUsageErrors) {
    const std::string base = "render " + bounds_scene().string() + " " + (tmpdir() / "bounds_flags.png").string() +
                             " --width 8 --height 8 --quiet ";
    const std::pair<const char*, const char*> bad[] = {
        {"--ao-samples 4000000000", "--ao-samples: must be in 1..4096"},
        {"--ao-samples 4097", "--ao-samples: must be in 1..4096"},
        {"--ao-samples 0", "--ao-samples: must be in 1..4096"},
        {"--ao-samples -1", "--ao-samples: must be in 1..4096"},
        {"--ao-radius -1", "--ao-radius: must be a finite number > 0"},
        {"--ao-radius 0", "--ao-radius: must be a finite number > 0"},
        {"--ao-radius nan", "--ao-radius"},
        {"--ao-radius inf", "--ao-radius"},
        {"--light 0 5 0 -1 1 1", "--light colour must be finite and >= 0"},
        {"--sun 0 -1 0 1 -0.5 1", "--sun colour must be finite and >= 0"},
        {"--ambient -0.1 0 0", "--ambient colour must be finite and >= 0"},
        {"--background 0 0 -1", "--background colour must be finite and >= 0"},
        {"--sun 0 0 0 1 1 1", "--sun direction"},
        {"--sun 1e30 1e30 1e30 1 1 1", "--sun direction"},
        {"--fov 0", "--fov: must be in (0, 180)"},
        {"--fov 180", "--fov: must be in (0, 180)"},
        {"--camera 1e20 0 0 0 0 0", "--camera position must lie within"},
        {"--camera 0 0 5 0 -5e9 0", "--camera position must lie within"},
        {"--light 0 0 1e10 1 1 1", "--light position must lie within"},
        {"--fov nan", "--fov"},
        {"--width 0", "--width: must be in 1..65536"},
        {"--height 65537", "--height: must be in 1..65536"},
        {"--width 99999999999", "--width: must be in 1..65536"},
        {"--spp 0", "--spp: must be in 1..65536"},
        {"--spp 65537", "--spp: must be in 1..65536"},
        {"--max-depth 1001", "--max-depth: must be in 0..1000"},
        {"--max-depth 18446744073709551616", "--max-depth: must be in 0..1000"},
        {"--leaf-size 0", "--leaf-size: must be in 1..4294967295"},
        {"--seed -1", "--seed"},
        {"--camera 0 0 5 0 0 5", "--camera"},
        {"--up 0 0 0", "--up"},
    };
    for (const auto& [flags, needle] : bad) expect_one_error_line(run_bounded(base + flags), 2, needle, flags);
    // the edges of each range work
    for (const char* ok : {"--ao-samples 4096 --shader ao", "--ao-samples 1 --shader ao --ao-radius 1e-3",
                           "--max-depth 0", "--max-depth 1000", "--fov 179", "--light 0 5 0 0 0 0",
                           "--seed 18446744073709551615", "--spp 2"})
        EXPECT_EQ(run_bounded(base + ok).code, 0) << ok;
    // the caps are in the help
    const Result u = run_bounded("render --help");
    EXPECT_EQ(u.code, 0) << u.err;
    EXPECT_NE(u.out.find("1..4096"), std::string::npos) << u.out;
    EXPECT_NE(u.out.find("16777216 pixels"), std::string::npos) << u.out;
}

TEST(CliBounds, ImagesRaysAndFramesHaveDocumentedLimits) {
    const std::string s = bounds_scene().string();
    const std::string png = (tmpdir() / "bounds_big.png").string();
    expect_one_error_line(run_bounded("render " + s + " " + png + " --width 65536 --height 65536"), 2,
                          "at most 16777216 pixels", "65536 x 65536");
    expect_one_error_line(run_bounded("render " + s + " " + png + " --width 4097 --height 4096"), 2,
                          "at most 16777216 pixels", "4097 x 4096");
    expect_one_error_line(run_bounded("check " + s + " --rays 1000000000000"), 2, "--rays: must be in 1..1000000",
                          "check --rays 1e12");
    expect_one_error_line(run_bounded("check " + s + " --rays 0"), 2, "--rays: must be in 1..1000000", "--rays 0");
    expect_one_error_line(run_bounded("animate-test " + s + " --frames 1000000000"), 2,
                          "--frames: must be in 1..1000", "animate-test --frames 1e9");
    expect_one_error_line(run_bounded("info " + s + " --builder sortaxis --window 4097"), 2,
                          "--window: must be in 1..4096", "--window 4097");
    expect_one_error_line(run_bounded("info " + s + " --leaf-size 0"), 2, "--leaf-size: must be in 1..4294967295",
                          "--leaf-size 0");
    const Result h = run_bounded("check --help");
    EXPECT_NE(h.out.find("1..1000000 (default 2000)"), std::string::npos) << h.out;
}

TEST(CliBounds, ScenesThatAreNotRegularFilesAreRefused) {
    for (const std::string& bad : {std::string("/dev/zero"), tmpdir().string()}) {
        const std::string why = bad == "/dev/zero" ? ": is not a regular file" : ": is a directory";
        expect_one_error_line(run_bounded("info " + bad), 1, bad + why, "info " + bad);
        expect_one_error_line(run_bounded("render " + bad + " " + (tmpdir() / "x.png").string()), 1, bad + why,
                              "render " + bad);
    }
}

TEST(CliBounds, OutOfMemoryIsOneLine) {
#if defined(RAYKIT_CLI_TEST_ASAN)
    GTEST_SKIP() << "ulimit -v and AddressSanitizer's shadow memory do not mix";
#else
    // 4096 x 4096 float pixels are 256 MiB: under a 200 MiB address-space limit the image cannot
    // be allocated, however little the scene needs
    const Result r = run_sh("ulimit -v 204800; timeout 60 \"$RAYKIT\" render " + bounds_scene().string() + " " +
                            (tmpdir() / "bounds_oom.png").string() + " --width 4096 --height 4096 --quiet");
    expect_one_error_line(r, 1, "raykit: error: out of memory (", "render under ulimit -v");
    EXPECT_EQ(r.err.find("std::bad_alloc"), std::string::npos) << r.err;
#endif
}

TEST(CliBounds, OutputsAreCheckedBeforeAnyWork) {
    const std::string s = bounds_scene().string();
    const fs::path png = tmpdir() / "bounds_first.png";
    fs::remove(png);
    expect_one_error_line(run_bounded("render " + s + " " + png.string() + " --width 8 --height 8 --pfm " +
                                      "/nonexistent_raykit_dir/x.pfm"),
                          1, "/nonexistent_raykit_dir/x.pfm", "--pfm into a missing folder");
    EXPECT_FALSE(fs::exists(png)) << "the PNG was written before the PFM failed";
    expect_one_error_line(run_bounded("render " + s + " /nonexistent_raykit_dir/o.png"), 1,
                          "/nonexistent_raykit_dir/o.png", "OUT.png into a missing folder");
    expect_one_error_line(run_bounded("render " + s + " " + tmpdir().string()), 1, tmpdir().string(),
                          "OUT.png is a folder");
    // the HITS file is checked before the (missing) RAYS file is read
    expect_one_error_line(run_bounded("trace " + s + " /nonexistent_raykit_dir/r.txt /nonexistent_raykit_dir/h.txt"),
                          1, "/nonexistent_raykit_dir/h.txt", "HITS into a missing folder");
    expect_one_error_line(run_bounded("generate torus /nonexistent_raykit_dir/t.obj"), 1,
                          "/nonexistent_raykit_dir/t.obj", "generate into a missing folder");
}

TEST(CliBounds, LibraryErrorsNeverPrintUsage) {
    // a scene around 1e20 once printed the usage text: the camera framed from its bounds was not
    // finite and that library error was taken for a bad flag
    const fs::path far = tmpdir() / "bounds_far.obj";
    write(far, "v 1e20 0 0\nv -1e20 0 0\nv 0 1e20 0\nf 1 2 3\n");
    const std::string png = (tmpdir() / "bounds_far.png").string();
    expect_one_error_line(run_bounded("render " + far.string() + " " + png + " --width 8 --height 8"), 1, "",
                          "render at 1e20");
    const fs::path bad = tmpdir() / "bounds_bad.obj";
    write(bad, "v 0 0 0\nf 1 2 3\n");
    for (const std::string cmd : {"info", "check", "render"})
        expect_one_error_line(run_bounded(cmd + " " + bad.string() + (cmd == "render" ? " " + png : std::string())), 1,
                              "bounds_bad.obj:2", cmd + " with a bad face");
}

TEST(CliAnimate, CharacterWithoutASceneKeepsItsTexture) {
    // Without --scene the render mesh started with no texture coordinates and
    // dropped the character's: every hit sampled uv (0, 0), black here.
    const fs::path dir = tmpdir() / "animate_cube";
    fs::create_directories(dir);
    write_centre_red_bmp(dir / "skin.bmp");
    const fs::path smd = dir / "cube.smd";
    write(smd, textured_cube_smd("skin.bmp"));
    const Result r = run("animate " + smd.string() + " " + smd.string() + " " + (dir / "cube_%d.png").string() +
                         " --width 64 --height 48 --camera 2.5 2.5 2.5 0 0.9 0");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << r.err;
    const PixelCount c = count_pixels(dir / "cube_0.png");
    EXPECT_EQ(c.total, 64u * 48u);
    EXPECT_GT(c.red, c.total / 10) << "the cube should cover a good part of the frame in the texture's red";
    EXPECT_EQ(c.lit, c.red) << "every lit pixel has the texture's colour (red, no green or blue)";
}

TEST(CliAnimate, GoblinFrameIsNotBlack) {
#ifdef RAYKIT_SHARED_DATA_DIR
    const fs::path dir = fs::path(RAYKIT_SHARED_DATA_DIR) / "smd" / "hl2_goblin";
#else
    const fs::path dir;
#endif
    if (dir.empty() || !fs::exists(dir / "Goblin_Reference.smd")) GTEST_SKIP() << "shared SMD data not found";
    const fs::path out = tmpdir() / "goblin_%03d.png";
    const Result r = run("animate " + (dir / "Goblin_Reference.smd").string() + " " +
                         (dir / "Goblin_Anim.smd").string() + " " + out.string() +
                         " --frames 1 --first 100 --width 96 --height 72");
    ASSERT_EQ(r.code, 0) << r.err;
    const PixelCount c = count_pixels(tmpdir() / "goblin_100.png");
    EXPECT_GT(c.lit, c.total / 100) << "the goblin renders black";
}

/// A directory tmpdir()/name holding skin.bmp (write_centre_red_bmp), cube.smd (the textured
/// cube) and anim.smd (`anim_smd`), for animate runs.
static fs::path write_cube_animation(const std::string& name, const std::string& anim_smd) {
    const fs::path dir = tmpdir() / name;
    fs::create_directories(dir);
    write_centre_red_bmp(dir / "skin.bmp");
    write(dir / "cube.smd", textured_cube_smd("skin.bmp"));
    write(dir / "anim.smd", anim_smd);
    return dir;
}

#if RAYKIT_CLI_HAVE_CL
/// Pixels of two PNGs of one size where some channel differs by more than 2/255 (all when the
/// sizes differ), and how many pixels each has.
static std::pair<std::size_t, std::size_t> png_pixels_apart(const fs::path& a, const fs::path& b) {
    const Texture x = load_texture(a, /*srgb=*/false), y = load_texture(b, /*srgb=*/false);
    if (x.rgba.size() != y.rgba.size() || x.placeholder || y.placeholder) return {x.rgba.size() / 4 + 1, x.rgba.size() / 4};
    std::size_t bad = 0;
    for (std::size_t i = 0; i + 3 < x.rgba.size(); i += 4) {
        int worst = 0;
        for (int c = 0; c < 4; ++c) worst = std::max(worst, std::abs(int(x.rgba[i + c]) - int(y.rgba[i + c])));
        bad += worst > 2;
    }
    return {bad, x.rgba.size() / 4};
}

TEST(CliAnimate, DeviceFramesEqualTheCpuFrames) {
    // --device cl runs the whole frame on the device (skinning, refit, top level, render);
    // its frames are the CPU's within the device renderer's tolerance (<= 2/255 on >= 99.9 %),
    // and with --nodes quantized the same files byte for byte
    const fs::path dir = write_cube_animation(
        "animate_device", "nodes\n0 \"root\" -1\nend\nskeleton\ntime 0\n0 0 0 0 0 0 0\ntime 1\n0 0.3 0 0.2 0.4 0.3 0.5\nend\n");
    const fs::path ref = dir / "cube.smd", anim = dir / "anim.smd";
    std::vector<std::string> runs = {"animate " + ref.string() + " " + anim.string() + " " + (dir / "@_%d.png").string() +
                                     " --width 64 --height 48 --camera 2.5 2.5 2.5 0 0.9 0 --fps 2"};
#ifdef RAYKIT_SHARED_DATA_DIR
    const fs::path goblin = fs::path(RAYKIT_SHARED_DATA_DIR) / "smd" / "hl2_goblin";
    const fs::path thesis = fs::path(RAYKIT_SHARED_DATA_DIR) / "obj" / "thesis_scene" / "Scene.obj";
    if (fs::exists(goblin / "Goblin_Reference.smd") && fs::exists(thesis))
        runs.push_back("animate " + (goblin / "Goblin_Reference.smd").string() + " " +
                       (goblin / "Goblin_Anim.smd").string() + " " + (dir / "goblin_@_%d.png").string() +
                       " --scene " + thesis.string() + " --first 100 --frames 2 --width 96 --height 72");
#endif
    for (const std::string& cmd : runs) {
        std::vector<std::string> names;
        for (const std::string device : {"cpu", "cl", "clq"}) {
            std::string c = cmd;
            c.replace(c.find('@'), 1, device);
            const Result r = run(c + (device == "clq" ? " --device cl --nodes quantized" : " --device " + device));
            if (r.code != 0 && r.err.find("no OpenCL") != std::string::npos) GTEST_SKIP() << r.err;
            ASSERT_EQ(r.code, 0) << c << ": " << r.err;
        }
        const std::string prefix = cmd.find("goblin_@") != std::string::npos ? "goblin_" : "";
        const int first = prefix.empty() ? 0 : 100;
        for (int k = first; k < first + 2; ++k) {
            const std::string n = std::to_string(k) + ".png";
            const auto [bad, total] = png_pixels_apart(dir / (prefix + "cpu_" + n), dir / (prefix + "cl_" + n));
            EXPECT_GT(total, 0u) << prefix << n;
            EXPECT_LE(double(bad), 1e-3 * double(total)) << prefix << n << ": " << bad << " of " << total
                                                          << " pixels differ by more than 2/255";
            EXPECT_EQ(slurp(dir / (prefix + "cl_" + n)), slurp(dir / (prefix + "clq_" + n)))
                << prefix << n << ": --nodes quantized changed the frame";
        }
        EXPECT_NE(png_pixels_apart(dir / (prefix + "cl_" + std::to_string(first) + ".png"),
                                   dir / (prefix + "cl_" + std::to_string(first + 1) + ".png")).first, 0u)
            << prefix << ": the frames should differ (the animation moves)";
    }
    std::string cpu_q = runs[0];
    cpu_q.replace(cpu_q.find('@'), 1, "q");
    expect_one_error_line(run(cpu_q + " --nodes quantized"), 2, "--nodes quantized: only with --device cl",
                          "animate --nodes quantized on the CPU");
}
#endif

TEST(CliAnimate, OutputPatternNamesEveryFrame) {
    // Keys at times 4 and 6: three frames (the middle one holds the first key).
    const fs::path dir = write_cube_animation(
        "animate_pattern", "nodes\n0 \"root\" -1\nend\nskeleton\ntime 4\n0 0 0 0 0 0 0\ntime 6\n0 0 0 1 0 0 0.5\nend\n");
    const fs::path ref = dir / "cube.smd", anim = dir / "anim.smd";
    const std::string base = "animate " + ref.string() + " " + anim.string() + " ";
    const std::string small = " --width 16 --height 12";
    expect_clean_error(run(base + (dir / "f_%3000000000d.png").string() + small), 2, "field width 3000000000");
    expect_clean_error(run(base + (dir / "f_%40d.png").string() + small), 2, "field width 40 is too large");
    expect_clean_error(run(base + (dir / "f_%s.png").string() + small), 2, "only an integer conversion");
    expect_clean_error(run(base + (dir / "one.png").string() + small + " --frames 2"), 2, "no %d conversion");
    expect_clean_error(run(base + (dir / "one.png").string() + small), 2, "3 frames would be written");
    EXPECT_FALSE(fs::exists(dir / "one.png"));
    Result r = run(base + (dir / "one.png").string() + small + " --frames 1");
    EXPECT_EQ(r.code, 0) << r.err;
    EXPECT_TRUE(fs::exists(dir / "one.png"));
    r = run(base + (dir / "f_%02d.png").string() + small);
    ASSERT_EQ(r.code, 0) << r.err;
    for (const char* f : {"f_00.png", "f_01.png", "f_02.png"}) EXPECT_TRUE(fs::exists(dir / f)) << f;
    EXPECT_FALSE(fs::exists(dir / "f_03.png"));
}

// ------------------------------------------------------------------ issue 15: one parser, one set of names

namespace {

/// The flags ("--name") a command's --help lists, without --help itself.
std::set<std::string> help_flags(const std::string& command) {
    const Result r = run(command + " --help");
    EXPECT_EQ(r.code, 0) << command << ": " << r.err;
    std::set<std::string> flags;
    std::istringstream in(r.out);
    for (std::string line; std::getline(in, line);) {
        const auto at = line.find_first_not_of(' ');
        if (at == std::string::npos || at == 0 || line[at] != '-') continue;  // option lines are indented
        std::string names = line.substr(at, line.find(' ', at) - at);     // "-h,--help", "--width"
        std::istringstream parts(names);
        for (std::string n; std::getline(parts, n, ',');)
            if (n.rfind("--", 0) == 0 && n != "--help") flags.insert(n);
    }
    return flags;
}

/// The commands `raykit --help` lists.
std::set<std::string> help_commands() {
    const Result r = run("--help");
    EXPECT_EQ(r.code, 0) << r.err;
    std::set<std::string> commands;
    std::istringstream in(r.out.substr(std::min(r.out.size(), r.out.find("Subcommands:"))));
    std::string line;
    std::getline(in, line);  // "Subcommands:"
    while (std::getline(in, line) && line.rfind("  ", 0) == 0) {
        std::istringstream w(line);
        std::string name;
        w >> name;
        commands.insert(name);
    }
    return commands;
}

fs::path readme_path() { return fs::path(RAYKIT_TEST_DATA_DIR) / ".." / ".." / "README.md"; }

/// The lines of README.md's fenced blocks: {in the "## Command line" synopsis?, line}.
std::vector<std::pair<bool, std::string>> readme_block_lines() {
    std::istringstream in(slurp(readme_path()));
    std::vector<std::pair<bool, std::string>> out;
    bool in_block = false, in_section = false, synopsis_done = false, synopsis = false;
    for (std::string line; std::getline(in, line);) {
        if (line.rfind("## ", 0) == 0) in_section = line == "## Command line";
        if (line.rfind("```", 0) == 0) {
            if (!in_block) synopsis = in_section && !synopsis_done;
            else if (synopsis) synopsis_done = true;
            in_block = !in_block;
            continue;
        }
        if (in_block) out.emplace_back(synopsis, line);
    }
    return out;
}

/// README's synopsis: the flags of each command ("raykit CMD ..." lines and their indented
/// continuations; "# ..." comments left out).
std::map<std::string, std::set<std::string>> readme_synopsis() {
    std::map<std::string, std::set<std::string>> flags;
    std::string command;
    for (const auto& [synopsis, raw] : readme_block_lines()) {
        if (!synopsis) continue;
        const std::string line = raw.substr(0, raw.find('#'));
        std::istringstream words(line);
        std::string w;
        if (line.rfind("raykit ", 0) == 0) {
            words >> w >> command;  // "raykit", the command
            flags[command];
        } else if (line.empty() || line[0] != ' ') {
            command.clear();
            continue;
        }
        while (words >> w) {
            // "[--width", "W]", "[--light", "--flag]..."
            const auto at = w.find("--");
            if (at == std::string::npos) continue;
            std::string f = w.substr(at);
            f = f.substr(0, f.find_first_of("]|. "));
            if (!command.empty() && f.size() > 2) flags[command].insert(f);
        }
    }
    return flags;
}

std::string joined(const std::set<std::string>& s) {
    std::string out;
    for (const std::string& x : s) out += x + " ";
    return out;
}

}  // namespace

TEST(CliHelp, EveryCommandHasHelp) {
    const std::set<std::string> commands = help_commands();
    EXPECT_EQ(commands, (std::set<std::string>{"info", "trace", "check", "generate", "skin", "animate", "render",
                                               "animate-test"}));
    for (const std::string& c : commands) {
        const Result r = run(c + " --help");
        EXPECT_EQ(r.code, 0) << c << ": " << r.err;
        EXPECT_NE(r.out.find("Usage: raykit " + c + " [OPTIONS]"), std::string::npos) << r.out;
        EXPECT_TRUE(r.err.empty()) << c << ": " << r.err;
        EXPECT_FALSE(help_flags(c).empty()) << c;
    }
    // a usage error names the command's own usage and where its help is, then one error line
    const Result bad = run("render --width");
    expect_clean_error(bad, 2, "--width");
    EXPECT_EQ(bad.err.rfind("usage: raykit render SCENE.obj OUT.png [OPTIONS]\nrun 'raykit render --help'", 0), 0u)
        << bad.err;
    EXPECT_EQ(run("render --help").out.find("usage:"), std::string::npos) << "help is not a usage error";
}

TEST(CliHelp, LeafSizeIsTheOneNameForTheLargestLeaf) {
    for (const char* c : {"info", "trace", "check", "render"}) {
        const std::set<std::string> f = help_flags(c);
        EXPECT_EQ(f.count("--leaf-size"), 1u) << c << ": " << joined(f);
        EXPECT_EQ(f.count("--leaf"), 0u) << c << ": the deprecated name is not in the help";
    }
    const fs::path scene = tmpdir() / "leaf_soup.obj";
    save_obj(make_random_soup(500, 2), scene);
    const Result now = run("info " + scene.string() + " --json --leaf-size 5");
    ASSERT_EQ(now.code, 0) << now.err;
    EXPECT_NE(now.out.find("\"max_leaf_size\": 5,"), std::string::npos) << now.out;
    EXPECT_TRUE(now.err.empty()) << now.err;
    // the old name still works, says so, and builds the same tree
    const Result old = run("info " + scene.string() + " --json --leaf 5");
    ASSERT_EQ(old.code, 0) << old.err;
    EXPECT_NE(old.out.find("\"max_leaf_size\": 5,"), std::string::npos) << old.out;
    EXPECT_NE(old.err.find("raykit: warning: --leaf is deprecated, use --leaf-size"), std::string::npos) << old.err;
    const auto sah = [](const std::string& out) { return out.substr(out.find("\"sah_cost\"")); };
    EXPECT_EQ(sah(old.out).substr(0, 30), sah(now.out).substr(0, 30));
    // and keeps its range, named as given
    expect_one_error_line(run("info " + scene.string() + " --leaf 0"), 2, "--leaf: must be in 1..4294967295",
                          "--leaf 0");
}

TEST(CliReadme, SynopsisListsExactlyTheFlagsOfEachCommandsHelp) {
    if (!fs::exists(readme_path())) GTEST_SKIP() << readme_path() << " not found";
    const std::map<std::string, std::set<std::string>> readme = readme_synopsis();
    std::set<std::string> readme_commands;
    for (const auto& [c, f] : readme) readme_commands.insert(c);
    EXPECT_EQ(readme_commands, help_commands()) << "README synopsis: " << joined(readme_commands);
    for (const auto& [c, flags] : readme) {
        const std::set<std::string> help = help_flags(c);
        for (const std::string& f : flags) EXPECT_EQ(help.count(f), 1u) << "README lists " << c << " " << f;
        for (const std::string& f : help) EXPECT_EQ(flags.count(f), 1u) << c << " --help lists " << f;
    }
    // the parse above sees what it should
    ASSERT_TRUE(readme.count("render"));
    EXPECT_EQ(readme.at("render").count("--background"), 1u);
    EXPECT_EQ(readme.at("info").count("--device"), 1u);  // from the second "raykit info" line
}

TEST(CliReadme, EveryExampleCommandRuns) {
#ifdef RAYKIT_SHARED_DATA_DIR
    const fs::path shared = fs::path(RAYKIT_SHARED_DATA_DIR);
#else
    const fs::path shared;
#endif
    if (shared.empty() || !fs::exists(shared)) GTEST_SKIP() << "shared data (../shared/data) not found";
    if (!fs::exists(readme_path())) GTEST_SKIP() << readme_path() << " not found";
    std::vector<std::string> examples;
    for (const auto& [synopsis, line] : readme_block_lines())
        if (!synopsis && line.rfind("raykit ", 0) == 0) examples.push_back(line);
    ASSERT_FALSE(examples.empty()) << "README has no raykit example";
    // as from the repository root: ../shared/data beside it, out/ for outputs
    const fs::path root = tmpdir() / "readme" / "repo";
    fs::create_directories(root / "out");
    std::error_code ec;
    fs::create_directory_symlink(fs::absolute(shared).parent_path(), root.parent_path() / "shared", ec);
    ASSERT_TRUE(fs::exists(root / ".." / "shared" / "data")) << ec.message();
    for (const std::string& line : examples) {
        EXPECT_EQ(line.find_first_of("[]<>"), std::string::npos) << "not a runnable command: " << line;
        std::istringstream words(line);
        std::vector<std::string> w;
        for (std::string x; words >> x;) w.push_back(x);
        // the files it writes: arguments under out/, a frame pattern for each frame
        long first = 0, frames = 1;
        for (std::size_t i = 0; i + 1 < w.size(); ++i) {
            if (w[i] == "--first") first = std::stol(w[i + 1]);
            if (w[i] == "--frames") frames = std::stol(w[i + 1]);
        }
        std::vector<fs::path> outputs;
        for (const std::string& x : w) {
            if (x.rfind("out/", 0) != 0) continue;
            const auto pct = x.find('%');
            if (pct == std::string::npos) {
                outputs.push_back(root / x);
                continue;
            }
            for (long k = first; k < first + frames; ++k) {
                char num[32];  // a width of at most 9 digits and a long's 20 characters fit
                const int width = x[pct + 1] == '0' ? std::clamp(x[pct + 2] - '0', 0, 9) : 0;
                std::snprintf(num, sizeof num, "%0*ld", width, k);
                outputs.push_back(root / (x.substr(0, pct) + num + x.substr(x.find('d', pct) + 1)));
            }
        }
        ASSERT_FALSE(outputs.empty()) << "no output under out/: " << line;
        for (const fs::path& o : outputs) fs::remove(o);
        const Result r = run_sh("cd '" + root.string() + "' && \"$RAYKIT\" " + line.substr(7));
        EXPECT_EQ(r.code, 0) << line << "\n" << r.err;
        for (const fs::path& o : outputs) EXPECT_TRUE(fs::exists(o) && fs::file_size(o) > 0) << o << " from " << line;
    }
}

// ------------------------------------------------------------------ issue 15: small items

TEST(CliIssue15, GenerateSaysWhichIcosphereItMade) {
    const fs::path out = tmpdir() / "ico15.obj";
    const Result r = run("generate icosphere " + out.string() + " --tris 5000");
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(load_obj(out).triangle_count(), 1280u);
    EXPECT_NE(r.out.find("1280 triangles (icosphere level 3, the largest within --tris 5000"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("the next 5120"), std::string::npos) << r.out;
    const Result exact = run("generate icosphere " + out.string() + " --tris 1280");
    ASSERT_EQ(exact.code, 0) << exact.err;
    EXPECT_EQ(exact.out.find('('), std::string::npos) << "nothing to explain: " << exact.out;
}

TEST(CliIssue15, SkinRefusesAnAnimationOfAnotherSkeleton) {
    const fs::path dir = write_cube_animation(
        "skin_other", "nodes\n0 \"hip\" -1\n1 \"knee\" 0\nend\nskeleton\ntime 0\n0 0 0 0 0 0 0\n1 0 0 1 0 0 0\nend\n");
    const Result r = run("skin " + (dir / "cube.smd").string() + " " + (dir / "anim.smd").string() + " 0");
    expect_one_error_line(r, 1, "anim.smd: none of its bones is in the skeleton of " + (dir / "cube.smd").string(),
                          "skin with a foreign animation");
    EXPECT_EQ(r.err.find("warning"), std::string::npos) << "one line, not a warning per bone: " << r.err;
    EXPECT_TRUE(r.out.empty()) << "no bind pose printed";
    // an animation of the cube's own bone still works
    write(dir / "own.smd", "nodes\n0 \"root\" -1\nend\nskeleton\ntime 0\n0 0 0 1 0 0 0\nend\n");
    const Result ok = run("skin " + (dir / "cube.smd").string() + " " + (dir / "own.smd").string() + " 0");
    ASSERT_EQ(ok.code, 0) << ok.err;
    EXPECT_EQ(std::count(ok.out.begin(), ok.out.end(), '\n'), 36);
    // and animate refuses the foreign one the same way
    expect_one_error_line(run("animate " + (dir / "cube.smd").string() + " " + (dir / "anim.smd").string() + " " +
                              (dir / "f_%d.png").string() + " --width 8 --height 8"),
                          1, "none of its bones is in the skeleton", "animate with a foreign animation");
}

TEST(CliIssue15, AMissingFileHasNoLineNumber) {
    // "FILE: cannot open file: ...", not "FILE:0: ..." (no line to name)
    const std::string png = (tmpdir() / "m.png").string();
    const std::pair<std::string, std::string> cases[] = {
        {"info /nonexistent_raykit/scene.obj", "/nonexistent_raykit/scene.obj"},
        {"skin /nonexistent_raykit/ref.smd", "/nonexistent_raykit/ref.smd"},
        {"render /nonexistent_raykit/scene.obj " + png, "/nonexistent_raykit/scene.obj"},
    };
    for (const auto& [cmd, file] : cases) {
        const Result r = run(cmd);
        expect_one_error_line(r, 1, file + ": cannot open file", cmd);
        EXPECT_EQ(r.err.find(":0:"), std::string::npos) << r.err;
    }
}
