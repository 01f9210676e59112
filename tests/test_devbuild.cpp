// The device builder (cl/device_build.hpp) against its CPU twin (cpu_twin_build: PlocBuilder,
// no post-pass, collapsed to BlockBvh8, device_tree()): the same wide nodes, slot boxes and
// triangle blocks bit for bit, compared by walking both trees from the root (the numbering of
// nodes and blocks differs); the refit tables it writes; and a DeviceScene frame that rebuilds
// on the device when the policy says so, its hits equal to the CPU's bit for bit.
//
// Inputs cover where builders fail: a real mesh, generated tori, one and two triangles, a
// single leaf, coincident centroids (PLOC's chains: the build gives up and says so), NaN and
// degenerate triangles, needles, far-from-origin coordinates, and several objects in one
// buffer (offsets).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <filesystem>

#include <glm/gtc/matrix_transform.hpp>
#include <limits>
#include <random>
#include <optional>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/cl.hpp"
#include "raykit/scene/generate.hpp"
#include "test_device_support.hpp"
#include "test_support.hpp"

using namespace raykit;
namespace rcl = raykit::cl;

namespace {

#define RAYKIT_REQUIRE_DEVICE(dev)                                                       \
    std::string no_device_reason_;                                                       \
    rcl::Device* dev##_ptr_ = raykit::test::test_device(&no_device_reason_);            \
    if (!dev##_ptr_) GTEST_SKIP() << "no OpenCL device, skipping: " << no_device_reason_; \
    rcl::Device& dev = *dev##_ptr_;                                                      \
    if (!dev.info().fp64) GTEST_SKIP() << "the device builder needs cl_khr_fp64"

/// "" when the trees below node ia of a and ib of b are the same (slot boxes, counts and
/// leaf blocks bit for bit), else the first difference. Counts the nodes and blocks reached.
struct TreeCompare {
    const rcl::DeviceTree& a;
    const rcl::DeviceTree& b;
    std::size_t nodes = 0, blocks = 0;

    std::string node(std::uint32_t ia, std::uint32_t ib, int depth = 0) {
        if (depth > RAYKIT_BVH_MAX_DEPTH + 2) return "too deep";
        if (ia >= a.nodes.size() || ib >= b.nodes.size()) return "node index out of range";
        ++nodes;
        const rcl::DeviceNode& x = a.nodes[ia];
        const rcl::DeviceNode& y = b.nodes[ib];
        for (int c = 0; c < rcl::kDeviceWidth; ++c) {
            const std::string at = " (node " + std::to_string(ia) + "/" + std::to_string(ib) + " slot " + std::to_string(c) + ")";
            for (int p = 0; p < 6; ++p)
                if (std::memcmp(&x.planes[p][c], &y.planes[p][c], sizeof(float)) != 0)
                    return "box plane " + std::to_string(p) + " " + std::to_string(x.planes[p][c]) + " vs " +
                           std::to_string(y.planes[p][c]) + at;
            if (x.unused(c) != y.unused(c)) return "used vs unused" + at;
            if (x.unused(c)) continue;
            if (x.count[c] != y.count[c]) return "count " + std::to_string(x.count[c]) + " vs " + std::to_string(y.count[c]) + at;
            if (x.count[c] == 0) {
                const std::string e = node(x.index[c], y.index[c], depth + 1);
                if (!e.empty()) return e;
                continue;
            }
            for (std::uint32_t k = 0; k < x.count[c]; ++k) {
                if (x.index[c] + k >= a.blocks.size() || y.index[c] + k >= b.blocks.size()) return "block out of range" + at;
                ++blocks;
                if (std::memcmp(&a.blocks[x.index[c] + k], &b.blocks[y.index[c] + k], sizeof(TriangleBlock4)) != 0)
                    return "block " + std::to_string(k) + " differs" + at;
            }
        }
        return "";
    }
};

/// A device build of `mesh` alone, read back.
struct DeviceBuilt {
    rcl::DeviceBuildResult result;
    rcl::DeviceTree tree;
    std::vector<std::uint32_t> parents, needs;
    std::vector<cl_uint2> starts;
};

DeviceBuilt device_build(rcl::Device& dev, rcl::DeviceBuilder& builder, const Mesh& mesh, std::uint32_t node_offset = 0,
                         std::uint32_t block_offset = 0) {
    const std::size_t n = mesh.triangles.size();
    const std::size_t ncap = node_offset + rcl::DeviceBuilder::node_capacity(n);
    const std::size_t bcap = block_offset + rcl::DeviceBuilder::block_capacity(n);
    rcl::Buffer<Triangle> tris(dev, mesh.triangles);
    std::vector<float> pos;
    for (const vec3& p : mesh.positions) pos.insert(pos.end(), {p.x, p.y, p.z});
    rcl::Buffer<float> positions(dev, pos);
    rcl::Buffer<rcl::DeviceNode> nodes(dev, ncap);
    rcl::Buffer<TriangleBlock4> blocks(dev, bcap);
    rcl::Buffer<std::uint32_t> parents(dev, ncap), needs(dev, ncap);
    rcl::Buffer<cl_uint2> starts(dev, ncap);
    rcl::ObjectRecord rec{};
    rec.node_offset = node_offset;
    rec.block_offset = block_offset;
    rec.triangle_count = static_cast<std::uint32_t>(n);
    rec.vertex_count = static_cast<std::uint32_t>(mesh.positions.size());
    DeviceBuilt out;
    out.result = builder.build(tris, positions, rec, 7, {&nodes, &blocks, {&parents, &needs, &starts}});
    if (!out.result.built || n == 0) return out;
    std::vector<rcl::DeviceNode> all = nodes.read(dev);
    out.tree.nodes.assign(all.begin() + node_offset, all.begin() + node_offset + out.result.nodes);
    std::vector<TriangleBlock4> allb = blocks.read(dev);
    out.tree.blocks.assign(allb.begin() + block_offset, allb.begin() + block_offset + out.result.blocks);
    // the tree's inner indices are relative to the object, as device_tree()'s
    const auto p = parents.read(dev), nd = needs.read(dev);
    const auto st = starts.read(dev);
    out.parents.assign(p.begin() + node_offset, p.end());
    out.needs.assign(nd.begin() + node_offset, nd.end());
    out.starts.assign(st.begin() + node_offset, st.end());
    return out;
}

/// Builds `mesh` on the device and checks it against the CPU twin; returns the result.
rcl::DeviceBuildResult expect_twin(rcl::Device& dev, rcl::DeviceBuilder& builder, const Mesh& mesh, const char* what,
                                   std::uint32_t node_offset = 0, std::uint32_t block_offset = 0) {
    const DeviceBuilt d = device_build(dev, builder, mesh, node_offset, block_offset);
    if (!d.result.built) return d.result;
    const rcl::DeviceTree cpu = rcl::device_tree(rcl::cpu_twin_build(mesh, builder.config()));
    EXPECT_EQ(d.result.nodes, cpu.nodes.size()) << what;
    EXPECT_EQ(d.result.blocks, cpu.blocks.size()) << what;
    if (cpu.nodes.empty()) return d.result;
    TreeCompare cmp{d.tree, cpu};
    EXPECT_EQ(cmp.node(0, 0), "") << what;
    EXPECT_EQ(cmp.nodes, cpu.nodes.size()) << what << ": nodes reached";
    EXPECT_EQ(cmp.blocks, cpu.blocks.size()) << what << ": blocks reached";
    // refit tables: every inner child's parent, the inner-child counts, starts where none
    for (std::size_t i = 0; i < d.tree.nodes.size(); ++i) {
        std::uint32_t inner = 0;
        for (int c = 0; c < rcl::kDeviceWidth; ++c) {
            const rcl::DeviceNode& nd = d.tree.nodes[i];
            if (nd.count[c] != 0 || nd.unused(c)) continue;
            ++inner;
            EXPECT_GT(nd.index[c], i) << what << ": a child before its parent";
            if (nd.index[c] < d.parents.size()) {
                EXPECT_EQ(d.parents[nd.index[c]], node_offset + i) << what;
            }
        }
        EXPECT_EQ(d.needs[i], inner) << what << " node " << i;
        EXPECT_EQ(d.starts[i].s[0], inner == 0 ? node_offset + i : kInvalidIndex) << what << " node " << i;
        if (inner == 0) {
            EXPECT_EQ(d.starts[i].s[1], 7u) << what;
        }
    }
    EXPECT_EQ(d.parents[0], kInvalidIndex) << what;
    for (std::size_t i = d.tree.nodes.size(); i < d.starts.size(); ++i)
        EXPECT_EQ(d.starts[i].s[0], kInvalidIndex) << what << ": unused node " << i << " is a start";
    return d.result;
}

/// Appends a triangle with its own three vertices.
void add_triangle(Mesh& m, const vec3& a, const vec3& b, const vec3& c) {
    const auto i = static_cast<std::uint32_t>(m.positions.size());
    m.positions.insert(m.positions.end(), {a, b, c});
    m.triangles.push_back({{i, i + 1, i + 2}});
}

/// n copies of one triangle: every centroid coincides.
Mesh coincident(std::size_t n) {
    Mesh m;
    for (std::size_t i = 0; i < n; ++i) add_triangle(m, vec3(0, 0, 0), vec3(1, 0, 0), vec3(0, 1, 0));
    return m;
}

Mesh subset(const Mesh& m, std::size_t count) {
    Mesh s = m;
    s.triangles.resize(std::min(count, m.triangles.size()));
    return s;
}

/// The device's builders, each against its own CPU twin.
class DeviceBuild : public ::testing::TestWithParam<rcl::DeviceBuildMethod> {
protected:
    rcl::DeviceBuildConfig config() const {
        rcl::DeviceBuildConfig c;
        c.method = GetParam();
        return c;
    }
};
INSTANTIATE_TEST_SUITE_P(Methods, DeviceBuild,
                         ::testing::Values(rcl::DeviceBuildMethod::ploc, rcl::DeviceBuildMethod::sortaxis),
                         [](const auto& info) { return info.param == rcl::DeviceBuildMethod::ploc ? "ploc" : "sortaxis"; });

TEST_P(DeviceBuild, EqualsCpuTwinOnTori) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuilder builder(dev, config());
    for (std::size_t n : {3000u, 20000u, 70000u}) {
        const Mesh m = make_bumpy_torus(n);
        const auto r = expect_twin(dev, builder, m, ("torus " + std::to_string(n)).c_str());
        EXPECT_TRUE(r.built);
        std::printf("torus %zu: %u rounds/levels, height %u, %u nodes, %u blocks\n", m.triangles.size(), r.rounds, r.height, r.nodes,
                    r.blocks);
    }
}

TEST_P(DeviceBuild, EqualsCpuTwinOnRealMeshes) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuilder builder(dev, config());
    int ran = 0;
    for (const char* f : {"obj/stanford_bunny/stanford-bunny.obj", "obj/thesis_scene/Scene.obj"}) {
        const std::filesystem::path p = std::filesystem::path(RAYKIT_SHARED_DATA_DIR) / f;
        if (!std::filesystem::exists(p)) continue;
        const Mesh m = load_obj(p);
        const auto r = expect_twin(dev, builder, m, f);
        EXPECT_TRUE(r.built) << f;
        std::printf("%s: %zu triangles, %u rounds, height %u, %u nodes\n", f, m.triangles.size(), r.rounds, r.height, r.nodes);
        ++ran;
    }
    if (ran == 0) GTEST_SKIP() << "shared data absent";
}

TEST_P(DeviceBuild, SmallAndOffsetInputs) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuilder builder(dev, config());
    const Mesh torus = make_bumpy_torus(2000);
    for (std::size_t n : {1u, 2u, 3u, 5u, 12u, 13u, 64u, 513u, 1025u})
        EXPECT_TRUE(expect_twin(dev, builder, subset(torus, n), ("first " + std::to_string(n)).c_str()).built);
    // at offsets in larger arrays, as in a scene
    EXPECT_TRUE(expect_twin(dev, builder, subset(torus, 700), "offset", 37, 101).built);
    // a smaller build after a larger one reuses the scratch arrays
    EXPECT_TRUE(expect_twin(dev, builder, subset(torus, 40), "after a larger one").built);
    const auto empty = device_build(dev, builder, Mesh{});
    EXPECT_TRUE(empty.result.built);
    EXPECT_EQ(empty.result.nodes, 0u);
}

TEST_P(DeviceBuild, HostileGeometry) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuilder builder(dev, config());
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    Mesh m;
    auto tri = [&](vec3 a, vec3 b, vec3 c) { add_triangle(m, a, b, c); };
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int i = 0; i < 3000; ++i) {
        const vec3 o(U(rng) * 10.0f, U(rng) * 10.0f, U(rng) * 10.0f);
        switch (i % 6) {
        case 0: tri(o, o + vec3(1, 0, 0), o + vec3(0, 1, 0)); break;                      // ordinary
        case 1: tri(o, o, o); break;                                                       // a point
        case 2: tri(o, o + vec3(1e-6f, 0, 0), o + vec3(50, 1e-7f, 0)); break;               // needle
        case 3:  // a NaN vertex (all such sit at one sanitized centroid: a chain, so only a few)
            if (i % 60 == 3) tri(o, o + vec3(nan, 0, 0), o + vec3(0, 1, 0));
            else tri(o, o + vec3(0, 1e-3f, 0), o + vec3(1e-3f, 0, 0));
            break;
        case 4: tri(o + vec3(3e7f, -3e7f, 3e7f), o + vec3(3e7f + 1, -3e7f, 3e7f), o + vec3(3e7f, -3e7f + 1, 3e7f)); break;  // far
        default: tri(o, o + vec3(0, 0, 2), o + vec3(0, 2, 0)); break;                     // axis-aligned
        }
    }
    const auto r = expect_twin(dev, builder, m, "hostile mix");
    EXPECT_TRUE(r.built) << r.rounds << " rounds, height " << r.height;
    Mesh all_nan;
    for (int i = 0; i < 50; ++i) add_triangle(all_nan, vec3(nan), vec3(nan), vec3(nan));
    EXPECT_TRUE(expect_twin(dev, builder, all_nan, "every vertex NaN").built);
}

TEST_P(DeviceBuild, SeededRandomMeshes) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuilder builder(dev, config());
    // pbrt-style seeded geometry: sizes from 1 to 5000, uniform, clustered, flat and huge layouts
    for (std::uint32_t seed = 1; seed <= 12; ++seed) {
        std::mt19937 rng(seed);
        std::uniform_real_distribution<float> U(-1.0f, 1.0f);
        const std::size_t n = std::size_t(1) + rng() % 5000;
        const int layout = int(seed % 4);
        const float scale = layout == 3 ? 1e6f : 1.0f;
        Mesh m;
        vec3 cluster(0.0f);
        for (std::size_t i = 0; i < n; ++i) {
            if (layout == 1 && i % 64 == 0) cluster = vec3(U(rng), U(rng), U(rng)) * 20.0f;
            vec3 o = layout == 1 ? cluster + vec3(U(rng), U(rng), U(rng)) * 0.05f : vec3(U(rng), U(rng), U(rng)) * 10.0f;
            if (layout == 2) o.y = 0.0f;  // flat: every triangle in one plane
            const float e = 0.01f + 0.2f * (U(rng) + 1.0f);
            add_triangle(m, o * scale, (o + vec3(e, 0, U(rng) * e)) * scale, (o + vec3(0, layout == 2 ? 0.0f : e, e)) * scale);
        }
        const auto r = expect_twin(dev, builder, m, ("seed " + std::to_string(seed)).c_str());
        EXPECT_TRUE(r.built) << "seed " << seed;
    }
}

TEST(DeviceBuildPloc, CoincidentCentroidsGiveUpAndSaySo) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuilder builder(dev);
    // every triangle the same: PLOC merges one pair per round (a chain), so the device gives
    // up after kMaxRounds and leaves it to the CPU; fifty still finish on the device (a chain
    // of height 49; past RAYKIT_BVH_MAX_DEPTH it gives up too)
    const Mesh m = coincident(2000);
    const auto r = expect_twin(dev, builder, m, "2000 coincident");
    EXPECT_FALSE(r.built);
    EXPECT_GT(r.rounds, rcl::DeviceBuilder::kMaxRounds);
    const auto small = expect_twin(dev, builder, subset(m, 50), "50 coincident");
    EXPECT_TRUE(small.built);
}

TEST(DeviceBuildSortAxis, CoincidentCentroidsPairGreedilyAndStayShallow) {
    RAYKIT_REQUIRE_DEVICE(dev);
    rcl::DeviceBuildConfig cfg;
    cfg.method = rcl::DeviceBuildMethod::sortaxis;
    rcl::DeviceBuilder builder(dev, cfg);
    // equal distances everywhere: mutual pairing takes neighbours two by two (the rank of a pair
    // breaks the ties), so unlike PLOC this stays O(log n) deep and the device builds it
    const auto r = expect_twin(dev, builder, coincident(5000), "5000 coincident");
    EXPECT_TRUE(r.built);
    EXPECT_LE(r.height, 20u);
    // windows of 1 and 16, and the greedy pairing of a level with few mutual pairs
    for (unsigned w : {1u, 16u}) {
        cfg.window = w;
        rcl::DeviceBuilder b2(dev, cfg);
        EXPECT_TRUE(expect_twin(dev, b2, make_bumpy_torus(9000), ("window " + std::to_string(w)).c_str()).built);
    }
    cfg.window = 17;
    EXPECT_THROW(rcl::DeviceBuilder(dev, cfg), std::invalid_argument);
    // a chain: triangles along x with growing gaps, so each one's nearest is the one before and
    // a level has one mutual pair per chunk; levels of more than 256 elements then pair
    // greedily (halving), the last 256 one pair a level: about 100 levels here, not 3000
    cfg.window = 2;
    rcl::DeviceBuilder b3(dev, cfg);
    Mesh chain;
    float x = 0.0f, gap = 0.01f;
    for (std::uint32_t i = 0; i < 3000; ++i, x += gap, gap *= 1.002f) {
        add_triangle(chain, vec3(x, 0, 0), vec3(x + 1e-3f, 0, 0), vec3(x, 1e-3f, 0));
    }
    const auto rc = expect_twin(dev, b3, chain, "growing gaps");
    EXPECT_TRUE(rc.built);
    EXPECT_LE(rc.rounds, 300u) << "levels: the greedy fallback did not run";
    // the same along a spiral: the Morton order is not the chain's, so greedy windows choose
    Mesh spiral;
    float a = 0.0f, step = 0.002f;
    for (std::uint32_t i = 0; i < 3000; ++i, a += step, step *= 1.001f) {
        const vec3 p(std::cos(a) * (1.0f + a), std::sin(a) * (1.0f + a), 0.1f * a);
        add_triangle(spiral, p, p + vec3(1e-3f, 0, 0), p + vec3(0, 1e-3f, 0));
    }
    const auto rs = expect_twin(dev, b3, spiral, "spiral chain");
    EXPECT_TRUE(rs.built);
    std::printf("chain: %u levels, spiral: %u levels\n", rc.rounds, rs.rounds);
}

// ---------------------------------------------------------------- the frame's rebuild stage

/// Closest and any-hit answers of a DeviceScene against the CPU Scene, bit for bit.
std::size_t disagreements(rcl::DeviceScene<>& ds, const Scene& s, const std::vector<Ray>& rays) {
    const std::vector<Hit> dh = ds.closest(rays);
    const std::vector<std::uint32_t> da = ds.any(rays);
    std::size_t bad = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        const Hit c = s.intersect_closest(rays[i]);
        const Hit& d = dh[i];
        const bool same = c.valid() == d.valid() &&
                          (!c.valid() || (c.prim == d.prim && c.inst == d.inst && std::memcmp(&c.t, &d.t, 4) == 0 &&
                                          std::memcmp(&c.u, &d.u, 4) == 0 && std::memcmp(&c.v, &d.v, 4) == 0));
        bad += !same || s.intersect_any(rays[i]) != (da[i] != 0);
    }
    return bad;
}

/// The scene's device tree of object o against the CPU twin built over `positions`.
void expect_scene_tree(rcl::DeviceScene<>& ds, std::uint32_t o, const Mesh& mesh, const char* what) {
    rcl::DeviceTree dev;
    dev.nodes = ds.nodes(o);
    dev.blocks = ds.blocks(o);
    const rcl::DeviceTree cpu = rcl::device_tree(rcl::cpu_twin_build(mesh, ds.rebuild_settings().build));
    TreeCompare cmp{dev, cpu};
    EXPECT_EQ(cmp.node(0, 0), "") << what;
    EXPECT_EQ(cmp.nodes, cpu.nodes.size()) << what;
    EXPECT_EQ(dev.nodes.size(), cpu.nodes.size()) << what;
}

TEST(DeviceRebuild, FrameRebuildsWhenThePolicySaysSoAndAnswersStayExact) {
    RAYKIT_REQUIRE_DEVICE(dev);
    const Mesh torus = make_bumpy_torus(6000);
    Scene cpu;
    const std::uint32_t body = cpu.add_object(torus, ObjectKind::dynamic);
    const std::uint32_t ground = cpu.add_object(make_bumpy_torus(2000, 0.1f, 3.0f, 0.2f));
    cpu.add_instance(body);
    cpu.add_instance(body, glm::rotate(glm::translate(mat4(1.0f), vec3(0.5f, 2.0f, 0.0f)), 3.5f, vec3(0, 0, 1)));
    cpu.add_instance(ground);
    cpu.update_top_level();
    rcl::DeviceRebuild settings;
    settings.enabled = true;
    rcl::DeviceScene<> ds(dev, cpu, settings);
    // the same frames walking quantized nodes: the rebuilt tree's nodes are quantized again on the
    // device, the host's bytes, and the answers stay the CPU's
    rcl::DeviceScene<> dq(dev, cpu, settings, rcl::NodeForm::quantized);
    ASSERT_EQ(dq.node_form(), rcl::NodeForm::quantized);
    const std::vector<Ray> rays = raykit::test::random_rays(torus, 3000, 5);
    auto quantized_differ = [&] {
        std::size_t differ = 0;
        const std::vector<rcl::DeviceNode> fn = dq.nodes(body);
        const std::vector<rcl::QuantizedNode> qn = dq.quantized_nodes(body);
        for (std::size_t i = 0; i < fn.size(); ++i) {
            const std::optional<rcl::QuantizedNode> want = rcl::quantize_node(fn[i]);
            differ += !want || std::memcmp(&*want, &qn[i], sizeof(rcl::QuantizedNode)) != 0;
        }
        return differ;
    };

    auto frame = [&](const std::vector<vec3>& pos) {
        ds.set_positions(body, pos);
        dq.set_positions(body, pos);
        cpu.set_positions(body, pos);
        cpu.update_top_level();
        const rcl::FrameTimes ft = ds.update();
        EXPECT_EQ(dq.update().rebuilt, ft.rebuilt);
        EXPECT_EQ(quantized_differ(), 0u);
        EXPECT_EQ(disagreements(dq, cpu, rays), 0u) << "quantized nodes";
        return ft;
    };
    // a gentle wave keeps the neighbourhoods: refit only
    std::vector<vec3> pos = torus.positions;
    for (vec3& p : pos) p.z += 0.02f * std::sin(4.0f * p.x);
    rcl::FrameTimes ft = frame(pos);
    EXPECT_EQ(ft.rebuilt, 0u);
    EXPECT_LT(ft.worst_growth, settings.policy.threshold);
    EXPECT_EQ(disagreements(ds, cpu, rays), 0u);
    // a sector thrown far away: the refitted boxes stretch across the gap, the policy rebuilds
    for (vec3& p : pos)
        if (p.x > 0.6f) p += vec3(6.0f, 4.0f, -3.0f);
    ft = frame(pos);
    EXPECT_EQ(ft.rebuilt, 1u);
    EXPECT_EQ(ft.rebuilt_on_host, 0u);
    EXPECT_GT(ft.worst_growth, settings.policy.threshold);
    Mesh moved = torus;
    moved.positions = pos;
    expect_scene_tree(ds, body, moved, "rebuilt on the device");
    EXPECT_EQ(disagreements(ds, cpu, rays), 0u);
    // the rebuilt tree refits (one-pass, through the tables the build wrote) like the CPU twin's
    for (vec3& p : pos) p.y += 0.01f * std::cos(3.0f * p.z);
    ft = frame(pos);
    EXPECT_EQ(ft.rebuilt, 0u);
    BlockBvh8 twin = rcl::cpu_twin_build(moved, settings.build);
    moved.positions = pos;
    twin.refit(moved);
    TreeCompare cmp{rcl::DeviceTree{ds.nodes(body), ds.blocks(body)}, rcl::device_tree(twin)};
    EXPECT_EQ(cmp.node(0, 0), "") << "refit after a device rebuild";
    EXPECT_EQ(disagreements(ds, cpu, rays), 0u);
    EXPECT_THROW(ds.update(rcl::RefitMethod::level_wise), std::invalid_argument);
}

TEST(DeviceRebuild, TooDeepForTheDeviceBuildsOnTheHost) {
    RAYKIT_REQUIRE_DEVICE(dev);
    // 300 triangles that collapse onto one spot: a PLOC chain far deeper than RAYKIT_BVH_MAX_DEPTH
    const Mesh torus = make_bumpy_torus(300);
    Scene cpu;
    const std::uint32_t body = cpu.add_object(torus, ObjectKind::dynamic);
    cpu.add_instance(body);
    cpu.update_top_level();
    rcl::DeviceRebuild settings;
    settings.enabled = true;
    rcl::DeviceScene<> ds(dev, cpu, settings);
    std::vector<vec3> pos = torus.positions;
    for (std::size_t i = 0; i < pos.size(); ++i) pos[i] = i % 3 == 0 ? vec3(0) : i % 3 == 1 ? vec3(1, 0, 0) : vec3(0, 1, 0);
    for (vec3& p : pos) p *= 50.0f;  // far bigger than before: growth way past the threshold
    ds.set_positions(body, pos);
    cpu.set_positions(body, pos);
    cpu.update_top_level();
    const rcl::FrameTimes ft = ds.update();
    EXPECT_EQ(ft.rebuilt, 1u) << "growth " << ft.worst_growth;
    EXPECT_EQ(ft.rebuilt_on_host, 1u);
    Mesh moved = torus;
    moved.positions = pos;
    expect_scene_tree(ds, body, moved, "built on the host");
    const std::vector<Ray> rays = raykit::test::random_rays(moved, 500, 9);
    EXPECT_EQ(disagreements(ds, cpu, rays), 0u);
}

}  // namespace
