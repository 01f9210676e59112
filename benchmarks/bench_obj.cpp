// Benchmarks for raykit/io/obj.hpp.
//
//   BM_ObjLoadBunny          load_obj on the 2.4 MB, 105k-line Stanford bunny
//                            (file read included); skipped when the data is absent.
//   BM_ObjParseBunnyInMemory parse_obj on the same text, already in memory.
//   BM_ObjParseGenerated     parse_obj on a generated ~100k-line OBJ: a height-field
//                            grid, /0 with `f v v v` corners, /1 with `f v/vt/vn`.
//
// The bunny is looked up in RAYKIT_SHARED_DATA_DIR (compile definition), then
// in $RAYKIT_SHARED_DATA, then in <repo>/../shared/data next to this source.
#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "raykit/io/obj.hpp"

namespace {

namespace fs = std::filesystem;

fs::path bunny_path() {
    std::vector<fs::path> dirs;
#ifdef RAYKIT_SHARED_DATA_DIR
    dirs.emplace_back(RAYKIT_SHARED_DATA_DIR);
#endif
    if (const char* env = std::getenv("RAYKIT_SHARED_DATA")) dirs.emplace_back(env);
    dirs.push_back(fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" / "data");
    for (const fs::path& d : dirs) {
        const fs::path p = d / "obj" / "stanford_bunny" / "stanford-bunny.obj";
        std::error_code ec;
        if (fs::is_regular_file(p, ec)) return p;
    }
    return {};
}

/// A (n x n)-vertex height field as OBJ text: n*n `v` lines (plus as many `vt`
/// and `vn` lines when `full`) and 2 (n-1)^2 triangle lines.
std::string generated_obj(int n, bool full) {
    std::string s;
    s.reserve(static_cast<std::size_t>(n) * n * (full ? 110 : 40) + static_cast<std::size_t>(n) * n * 2 * 40);
    char buf[256];
    s += "# generated height field\no grid\n";
    for (int y = 0; y < n; ++y) {
        for (int x = 0; x < n; ++x) {
            const double h = 0.25 * std::sin(0.37 * x) * std::cos(0.23 * y);
            std::snprintf(buf, sizeof buf, "v %.6f %.6f %.6f\n", x * 0.01, h, y * 0.01);
            s += buf;
            if (full) {
                std::snprintf(buf, sizeof buf, "vt %.6f %.6f\nvn %.6f %.6f %.6f\n", x / double(n - 1),
                              y / double(n - 1), -0.1 * h, 1.0, 0.05 * h);
                s += buf;
            }
        }
    }
    s += "usemtl ground\n";
    for (int y = 0; y + 1 < n; ++y) {
        for (int x = 0; x + 1 < n; ++x) {
            const int a = y * n + x + 1, b = a + 1, c = a + n, d = c + 1;
            if (full) {
                std::snprintf(buf, sizeof buf, "f %d/%d/%d %d/%d/%d %d/%d/%d\nf %d/%d/%d %d/%d/%d %d/%d/%d\n", a, a, a,
                              b, b, b, d, d, d, a, a, a, d, d, d, c, c, c);
            } else {
                std::snprintf(buf, sizeof buf, "f %d %d %d\nf %d %d %d\n", a, b, d, a, d, c);
            }
            s += buf;
        }
    }
    return s;
}

void report(benchmark::State& state, const raykit::Mesh& m, std::size_t bytes) {
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations() * bytes));
    state.counters["triangles"] = static_cast<double>(m.triangles.size());
    state.counters["vertices"] = static_cast<double>(m.positions.size());
}

void BM_ObjLoadBunny(benchmark::State& state) {
    const fs::path p = bunny_path();
    if (p.empty()) {
        state.SkipWithError("stanford-bunny.obj not found (set RAYKIT_SHARED_DATA)");
        return;
    }
    raykit::Mesh m;
    for (auto _ : state) {
        m = raykit::load_obj(p);
        benchmark::DoNotOptimize(m.triangles.data());
    }
    report(state, m, static_cast<std::size_t>(fs::file_size(p)));
}
BENCHMARK(BM_ObjLoadBunny)->Unit(benchmark::kMillisecond);

void BM_ObjParseBunnyInMemory(benchmark::State& state) {
    const fs::path p = bunny_path();
    if (p.empty()) {
        state.SkipWithError("stanford-bunny.obj not found (set RAYKIT_SHARED_DATA)");
        return;
    }
    const std::string text = raykit::detail::read_text_file(p);
    raykit::Mesh m;
    for (auto _ : state) {
        m = raykit::parse_obj(text, p.string(), p.parent_path());
        benchmark::DoNotOptimize(m.triangles.data());
    }
    report(state, m, text.size());
}
BENCHMARK(BM_ObjParseBunnyInMemory)->Unit(benchmark::kMillisecond);

void BM_ObjParseGenerated(benchmark::State& state) {
    const bool full = state.range(0) != 0;
    // ~100k lines either way: 180^2 + 2*179^2 = 96,482; 3*140^2 + 2*139^2 = 97,442.
    const std::string text = generated_obj(full ? 140 : 180, full);
    raykit::Mesh m;
    for (auto _ : state) {
        m = raykit::parse_obj(text, "generated.obj", {});
        benchmark::DoNotOptimize(m.triangles.data());
    }
    report(state, m, text.size());
    state.SetLabel(full ? "v/vt/vn" : "v only");
}
BENCHMARK(BM_ObjParseGenerated)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
