// Benchmarks for raykit/anim/ (and the SMD loader).
//
//   BM_SkinGoblinTiled/T        skin_vertices (positions + normals) on the goblin's
//                               1,679 vertices tiled 600x (1,007,400 vertices, one
//                               link each), T threads (0 = all). Counter Mverts/s.
//   BM_SkinSynthetic/K/T        1,048,576 synthetic vertices with K links each over
//                               64 bones (positions + normals), T threads. Mverts/s.
//   BM_SkinPositionsOnly/K/T    the same, positions only.
//   BM_InterpolatePose/M        interpolate_pose on 4,096 random pose pairs at
//                               t = 0.37; M = 0 slerp, 1 euler. Counter Mposes/s.
//   BM_SampleGoblin/M           sample_frame of the goblin's 800-frame animation
//                               (35 bones) at a fractional frame + skinning
//                               matrices; M = 0 slerp, 1 euler. Counter frames/s.
//   BM_LoadGoblin/F             load_smd_reference (F = 0) / load_smd_animation
//                               (F = 1) of the goblin files, file read included.
//
// Build: `raykit_benchmark(bench_anim)` in benchmarks/CMakeLists.txt. The goblin
// is looked up in RAYKIT_SHARED_DATA_DIR (compile definition), then in
// $RAYKIT_SHARED_DATA, then in <repo>/../shared/data; cases that need it skip
// themselves when it is absent.
#include <benchmark/benchmark.h>

#include <cstdlib>
#include <filesystem>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/io/smd.hpp"

namespace {

namespace fs = std::filesystem;

fs::path goblin_dir() {
    std::vector<fs::path> dirs;
#ifdef RAYKIT_SHARED_DATA_DIR
    dirs.emplace_back(RAYKIT_SHARED_DATA_DIR);
#endif
    if (const char* env = std::getenv("RAYKIT_SHARED_DATA")) dirs.emplace_back(env);
    dirs.push_back(fs::path(__FILE__).parent_path().parent_path().parent_path() / "shared" / "data");
    for (const fs::path& d : dirs) {
        const fs::path p = d / "smd" / "hl2_goblin";
        std::error_code ec;
        if (fs::is_regular_file(p / "Goblin_Reference.smd", ec)) return p;
    }
    return {};
}

struct Goblin {
    raykit::SmdModel model;
    raykit::SmdSkeletonAnim anim;
    raykit::Skeleton skeleton;
};

/// The goblin, loaded once; nullptr when the data is absent.
const Goblin* goblin() {
    static const std::unique_ptr<Goblin> g = []() -> std::unique_ptr<Goblin> {
        const fs::path dir = goblin_dir();
        if (dir.empty()) return nullptr;
        auto p = std::make_unique<Goblin>();
        p->model = raykit::load_smd_reference(dir / "Goblin_Reference.smd");
        p->anim = raykit::load_smd_animation(dir / "Goblin_Anim.smd", p->model);
        p->skeleton = raykit::Skeleton(p->model);
        return p;
    }();
    return g.get();
}

/// A skinning workload: packed weights, rest vertices and bone matrices.
struct Workload {
    raykit::PackedSkin skin;
    std::vector<raykit::vec3> positions, normals;
    std::vector<raykit::SkinMatrix> matrices;
};

void set_rate(benchmark::State& state, std::size_t vertices) {
    state.counters["Mverts/s"] = benchmark::Counter(static_cast<double>(vertices) * 1e-6,
                                                    benchmark::Counter::kIsIterationInvariantRate);
}

void BM_SkinGoblinTiled(benchmark::State& state) {
    const Goblin* g = goblin();
    if (!g) {
        state.SkipWithError("goblin data not found");
        return;
    }
    static const Workload w = [&] {
        Workload w;
        constexpr int kTiles = 600;
        std::vector<raykit::VertexWeights> weights;
        for (int t = 0; t < kTiles; ++t) {
            weights.insert(weights.end(), g->model.weights.begin(), g->model.weights.end());
            w.positions.insert(w.positions.end(), g->model.mesh.positions.begin(), g->model.mesh.positions.end());
            w.normals.insert(w.normals.end(), g->model.mesh.normals.begin(), g->model.mesh.normals.end());
        }
        w.skin = raykit::pack_skin(weights, g->model.bones.size());
        w.matrices = raykit::skin_matrices(g->skeleton, raykit::sample_frame(g->anim, 123.5));
        return w;
    }();
    const auto threads = static_cast<unsigned>(state.range(0));
    std::vector<raykit::vec3> p(w.positions.size()), n(w.normals.size());
    for (auto _ : state) {
        raykit::skin_vertices(w.skin, w.matrices, w.positions, w.normals, p, n, threads);
        benchmark::DoNotOptimize(p.data());
        benchmark::DoNotOptimize(n.data());
        benchmark::ClobberMemory();
    }
    set_rate(state, w.positions.size());
    state.counters["bytes/vert"] = static_cast<double>(w.skin.bytes()) / static_cast<double>(w.positions.size());
}
BENCHMARK(BM_SkinGoblinTiled)->Arg(1)->Arg(2)->Arg(0)->Unit(benchmark::kMillisecond)->UseRealTime();

const Workload& synthetic(int links) {
    static std::vector<std::unique_ptr<Workload>> cache(9);
    auto& slot = cache.at(static_cast<std::size_t>(links));
    if (!slot) {
        slot = std::make_unique<Workload>();
        Workload& w = *slot;
        constexpr std::size_t kVerts = std::size_t{1} << 20, kBones = 64;
        std::mt19937 rng(1234 + static_cast<unsigned>(links));
        std::uniform_real_distribution<float> U(-1.0f, 1.0f);
        std::uniform_int_distribution<std::uint32_t> B(0, kBones - 1);
        std::vector<raykit::VertexWeights> weights(kVerts);
        w.positions.resize(kVerts);
        w.normals.resize(kVerts);
        for (std::size_t v = 0; v < kVerts; ++v) {
            float sum = 0.0f;
            for (int k = 0; k < links; ++k) {
                const float x = 0.1f + std::abs(U(rng));
                weights[v].links.push_back({static_cast<std::uint32_t>((B(rng) + static_cast<std::uint32_t>(k)) % kBones), x});
                sum += x;
            }
            for (auto& l : weights[v].links) l.weight /= sum;
            w.positions[v] = raykit::vec3(U(rng), U(rng), U(rng)) * 10.0f;
            w.normals[v] = glm::normalize(raykit::vec3(U(rng), U(rng), U(rng)) + raykit::vec3(1e-3f));
        }
        w.skin = raykit::pack_skin(weights, kBones);
        for (std::size_t b = 0; b < kBones; ++b) {
            const raykit::BoneTransform t{raykit::euler_xyz_quat({U(rng), U(rng), U(rng)}),
                                          glm::dvec3(U(rng), U(rng), U(rng))};
            w.matrices.push_back(raykit::to_skin_matrix(raykit::transform_matrix(t)));
        }
    }
    return *slot;
}

void BM_SkinSynthetic(benchmark::State& state) {
    const Workload& w = synthetic(static_cast<int>(state.range(0)));
    const auto threads = static_cast<unsigned>(state.range(1));
    std::vector<raykit::vec3> p(w.positions.size()), n(w.normals.size());
    for (auto _ : state) {
        raykit::skin_vertices(w.skin, w.matrices, w.positions, w.normals, p, n, threads);
        benchmark::DoNotOptimize(p.data());
        benchmark::DoNotOptimize(n.data());
        benchmark::ClobberMemory();
    }
    set_rate(state, w.positions.size());
    state.counters["bytes/vert"] = static_cast<double>(w.skin.bytes()) / static_cast<double>(w.positions.size());
}
BENCHMARK(BM_SkinSynthetic)
    ->ArgsProduct({{1, 2, 4}, {1, 2}})
    ->ArgNames({"links", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_SkinPositionsOnly(benchmark::State& state) {
    const Workload& w = synthetic(static_cast<int>(state.range(0)));
    const auto threads = static_cast<unsigned>(state.range(1));
    std::vector<raykit::vec3> p(w.positions.size());
    for (auto _ : state) {
        raykit::skin_vertices(w.skin, w.matrices, w.positions, {}, p, {}, threads);
        benchmark::DoNotOptimize(p.data());
        benchmark::ClobberMemory();
    }
    set_rate(state, w.positions.size());
    state.counters["bytes/vert"] = static_cast<double>(w.skin.bytes()) / static_cast<double>(w.positions.size());
}
BENCHMARK(BM_SkinPositionsOnly)
    ->ArgsProduct({{1, 4}, {1, 2}})
    ->ArgNames({"links", "threads"})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

void BM_InterpolatePose(benchmark::State& state) {
    const auto mode = state.range(0) == 0 ? raykit::Interpolation::slerp : raykit::Interpolation::euler;
    constexpr std::size_t kPairs = 4096;
    std::mt19937 rng(99);
    std::uniform_real_distribution<float> U(-3.1f, 3.1f);
    std::vector<raykit::BonePose> a(kPairs), b(kPairs);
    for (std::size_t i = 0; i < kPairs; ++i) {
        a[i] = {raykit::vec3(U(rng), U(rng), U(rng)), raykit::vec3(U(rng), U(rng), U(rng))};
        b[i] = {raykit::vec3(U(rng), U(rng), U(rng)), raykit::vec3(U(rng), U(rng), U(rng))};
    }
    std::vector<raykit::BoneTransform> out(kPairs);
    for (auto _ : state) {
        raykit::interpolate_poses(a, b, 0.37, mode, out);
        benchmark::DoNotOptimize(out.data());
        benchmark::ClobberMemory();
    }
    state.counters["Mposes/s"] =
        benchmark::Counter(static_cast<double>(kPairs) * 1e-6, benchmark::Counter::kIsIterationInvariantRate);
    state.SetLabel(mode == raykit::Interpolation::slerp ? "slerp" : "euler");
}
BENCHMARK(BM_InterpolatePose)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_SampleGoblin(benchmark::State& state) {
    const Goblin* g = goblin();
    if (!g) {
        state.SkipWithError("goblin data not found");
        return;
    }
    const auto mode = state.range(0) == 0 ? raykit::Interpolation::slerp : raykit::Interpolation::euler;
    double frame = 0.25;
    for (auto _ : state) {
        const auto local = raykit::sample_frame(g->anim, frame, mode, raykit::WrapMode::loop);
        const auto mats = raykit::skin_matrices(g->skeleton, local);
        benchmark::DoNotOptimize(mats.data());
        frame += 1.37;
    }
    state.counters["frames/s"] = benchmark::Counter(1.0, benchmark::Counter::kIsIterationInvariantRate);
    state.SetLabel(mode == raykit::Interpolation::slerp ? "slerp" : "euler");
}
BENCHMARK(BM_SampleGoblin)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond);

void BM_LoadGoblin(benchmark::State& state) {
    const Goblin* g = goblin();
    if (!g) {
        state.SkipWithError("goblin data not found");
        return;
    }
    const fs::path dir = goblin_dir();
    const bool anim = state.range(0) == 1;
    const fs::path file = dir / (anim ? "Goblin_Anim.smd" : "Goblin_Reference.smd");
    for (auto _ : state) {
        if (anim) {
            benchmark::DoNotOptimize(raykit::load_smd_animation(file, g->model).frames.data());
        } else {
            benchmark::DoNotOptimize(raykit::load_smd_reference(file).mesh.positions.data());
        }
    }
    std::error_code ec;
    state.SetBytesProcessed(static_cast<std::int64_t>(state.iterations()) *
                            static_cast<std::int64_t>(fs::file_size(file, ec)));
    state.SetLabel(anim ? "Goblin_Anim.smd" : "Goblin_Reference.smd");
}
BENCHMARK(BM_LoadGoblin)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond);

}  // namespace
