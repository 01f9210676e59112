// Texture decoding: raykit's bounded decoders (render/image_decode.hpp: libpng, libjpeg-turbo,
// header-checked stb for BMP/TGA) against stb_image alone, on the same files in memory.
//
//   BM_DecodeTextures/raykit   decode_image on every PNG/JPEG/BMP/TGA under the shared data
//   BM_DecodeTextures/stb      stbi_load_from_memory (what raykit used before) on the same bytes
// The counter "pixels" is the total decoded per iteration; skipped without the shared data.
#include <benchmark/benchmark.h>

#include <cctype>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "raykit/render/image_decode.hpp"

namespace {

namespace fs = std::filesystem;

struct File {
    std::string name;
    std::vector<std::uint8_t> bytes;
};

const std::vector<File>& files() {
    static const std::vector<File> all = [] {
        std::vector<File> v;
        const fs::path root = RAYKIT_SHARED_DATA_DIR;
        std::error_code ec;
        if (!fs::is_directory(root, ec)) return v;
        for (const auto& e : fs::recursive_directory_iterator(root)) {
            std::string ext = e.path().extension().string();
            for (char& c : ext) c = char(std::tolower(static_cast<unsigned char>(c)));
            if (ext != ".png" && ext != ".jpg" && ext != ".jpeg" && ext != ".bmp" && ext != ".tga") continue;
            std::ifstream in(e.path(), std::ios::binary);
            v.push_back({e.path().string(), {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()}});
        }
        return v;
    }();
    return all;
}

void BM_DecodeTextures(benchmark::State& state) {
    const bool stb = state.range(0) == 1;
    if (files().empty()) {
        state.SkipWithError("no shared data");
        return;
    }
    std::uint64_t pixels = 0;
    for (auto _ : state) {
        pixels = 0;
        for (const File& f : files()) {
            if (stb) {
                int w = 0, h = 0, c = 0;
                stbi_uc* p = stbi_load_from_memory(f.bytes.data(), int(f.bytes.size()), &w, &h, &c, 4);
                benchmark::DoNotOptimize(p);
                pixels += std::uint64_t(w) * std::uint64_t(h);
                stbi_image_free(p);
            } else {
                const raykit::DecodedImage d = raykit::decode_image(f.bytes.data(), f.bytes.size(), f.name);
                benchmark::DoNotOptimize(d.rgba.data());
                pixels += std::uint64_t(d.width) * d.height;
            }
        }
    }
    state.SetLabel(stb ? "stb" : "raykit");
    state.counters["pixels"] = double(pixels);
    state.counters["files"] = double(files().size());
}
BENCHMARK(BM_DecodeTextures)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->Repetitions(5)->ReportAggregatesOnly(true);

}  // namespace
