// Skinning on the OpenCL device (raykit::SkinHook, anim/skin_hook.hpp)
// against the CPU skinning of anim/skinning.hpp: positions (and normals) of
// the goblin (HL2), the dwarf (HL1) and the hand-made fixtures of
// tests/data/smd at whole and half frames, equal to 1e-5 of the model's
// extent; the refit that follows leaves every box enclosing its triangles.
// Also the buffer-hook extension of cl/hook.hpp itself (unset buffers,
// bad slots, re-upload per frame). Skips only when OpenCL has no device;
// shared-data cases skip when /work/shared/data is missing.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "test_support.hpp"
#include "test_device_support.hpp"
#include "raykit/anim/interpolate.hpp"
#include "raykit/anim/skeleton.hpp"
#include "raykit/anim/skin_hook.hpp"
#include "raykit/anim/skinning.hpp"
#include "raykit/bvh/validate.hpp"
#include "raykit/cl.hpp"
#include "raykit/io/smd.hpp"
#include "raykit/scene/scene.hpp"

#ifndef RAYKIT_CLI_HAVE_CL
#define RAYKIT_CLI_HAVE_CL 1
#endif
#include "../examples/cli_skin.hpp"
#include <sstream>

namespace {

namespace fs = std::filesystem;
namespace rcl = raykit::cl;
using namespace raykit;

using raykit::test::test_device;

#define REQUIRE_DEVICE(dev)                                                       \
    std::string why_;                                                             \
    rcl::Device* dev = test_device(&why_);                                        \
    if (!dev) GTEST_SKIP() << "no OpenCL device, skipping: " << why_

fs::path fixture_dir() { return fs::path(RAYKIT_TEST_DATA_DIR) / "smd"; }
fs::path shared_smd_dir() { return fs::path(RAYKIT_SHARED_DATA_DIR) / "smd"; }

float extent_of(const std::vector<vec3>& p) {
    vec3 lo(1e30f), hi(-1e30f);
    for (const vec3& v : p) {
        lo = glm::min(lo, v);
        hi = glm::max(hi, v);
    }
    return std::max({hi.x - lo.x, hi.y - lo.y, hi.z - lo.z});
}

std::vector<AABB> triangle_boxes(const std::vector<vec3>& pos, const Mesh& mesh) {
    std::vector<AABB> boxes(mesh.triangles.size());
    for (std::size_t t = 0; t < boxes.size(); ++t) {
        AABB b;
        for (int c = 0; c < 3; ++c) b.grow(pos[mesh.triangles[t].v[c]]);
        boxes[t] = b;
    }
    return boxes;
}

/// Skins `model` through `frames` on the device and on the CPU and compares.
void check_model(rcl::Device& dev, const SmdModel& model, const SmdSkeletonAnim* anim, const std::vector<double>& frames,
                 Interpolation interp) {
    Scene scene;
    const std::uint32_t body = scene.add_object(model.mesh, ObjectKind::dynamic);
    scene.add_instance(body);
    rcl::DeviceScene<SkinHook> ds(dev, scene);
    const Skeleton skeleton(model);
    const PackedSkin skin = pack_skin(model.weights, model.bones.size());
    upload_skin(ds, scene, body, skin);
    const float extent = extent_of(model.mesh.positions);
    ASSERT_GT(extent, 0.0f);
    const float tol = 1e-5f * extent;
    const std::size_t n = model.mesh.positions.size();
    const bool normals = !model.mesh.normals.empty();
    for (double f : frames) {
        SCOPED_TRACE("frame " + std::to_string(f));
        const std::vector<BoneTransform> local =
            anim ? sample_frame(*anim, f, interp, WrapMode::clamp) : skeleton.bind_transforms();
        const std::vector<SkinMatrix> mats = skin_matrices(skeleton, local);
        upload_skin_matrices(ds, std::span<const SkinMatrix>(mats));
        ds.update();
        std::vector<vec3> cpu_p(n), cpu_n(normals ? n : 0);
        skin_vertices(skin, mats, model.mesh.positions, model.mesh.normals, cpu_p, cpu_n);
        const std::vector<vec3> dev_p = ds.positions(body);
        const std::vector<Vertex> dev_v = ds.moved_vertices(body);
        ASSERT_EQ(dev_p.size(), n);
        float worst = 0.0f, worst_n = 0.0f;
        for (std::size_t i = 0; i < n; ++i) {
            worst = std::max(worst, glm::length(dev_p[i] - cpu_p[i]));
            worst = std::max(worst, glm::length(dev_v[i].position - cpu_p[i]));
            if (normals) worst_n = std::max(worst_n, glm::length(dev_v[i].normal - cpu_n[i]));
        }
        EXPECT_LE(worst, tol) << "largest position difference " << worst << " (extent " << extent << ")";
        EXPECT_LE(worst_n, 1e-5f) << "largest normal difference";
        // The CPU twin of the hook, vertex by vertex, agrees with skin_vertices exactly.
        const SkinHook::Host host{skin.offsets, skin.links, mats};
        for (std::size_t i = 0; i < n; i += std::max<std::size_t>(1, n / 97)) {
            Vertex v;
            v.position = model.mesh.positions[i];
            if (normals) v.normal = model.mesh.normals[i];
            const Vertex w = SkinHook::apply(v, static_cast<std::uint32_t>(i), {}, host);
            EXPECT_EQ(w.position, cpu_p[i]);
        }
        // Refit after skinning: every box encloses its (device-skinned) triangles.
        // (the device tree's nodes 1.. are a BlockBvh8's with inner indices + 1, cl/device_tree.hpp)
        const std::vector<raykit::cl::DeviceNode> dn = ds.nodes(body);
        ASSERT_GE(dn.size(), 2u);
        const std::vector<TriangleBlock4> blocks = ds.blocks(body);
        WideBvhT<raykit::cl::kDeviceWidth> tree;  // leaves back to prim_ids ranges of the blocks' lanes
        for (std::size_t i = 1; i < dn.size(); ++i) {
            auto n = dn[i];
            for (int c = 0; c < raykit::cl::kDeviceWidth; ++c) {
                if (n.count[c] == 0 && !n.unused(c)) --n.index[c];
                if (n.count[c] == 0) continue;
                const auto first = static_cast<std::uint32_t>(tree.prim_ids.size());
                for (std::uint32_t k = n.index[c]; k < n.index[c] + n.count[c]; ++k)
                    for (int l = 0; l < 4; ++l) tree.prim_ids.push_back(blocks.at(k).prim[l]);
                n.index[c] = first;
                n.count[c] = static_cast<std::uint32_t>(tree.prim_ids.size()) - first;
            }
            tree.nodes.push_back(n);
        }
        const std::vector<AABB> boxes = triangle_boxes(dev_p, model.mesh);
        EXPECT_EQ(tree.validate(boxes), "");
        // The top level holds the refitted root.
        const AABB root = ds.root_boxes()[body];
        for (const AABB& b : boxes) {
            ASSERT_TRUE(root.min.x <= b.min.x && root.min.y <= b.min.y && root.min.z <= b.min.z);
            ASSERT_TRUE(root.max.x >= b.max.x && root.max.y >= b.max.y && root.max.z >= b.max.z);
        }
    }
}

TEST(SkinDevice, FixturesMatchCpu) {
    REQUIRE_DEVICE(dev);
    const SmdModel m = load_smd_reference(fixture_dir() / "ref_weights.SMD");
    const SmdSkeletonAnim a = load_smd_animation(fixture_dir() / "anim_weights.smd", m);
    check_model(*dev, m, nullptr, {0.0}, Interpolation::slerp);
    const double last = double(a.frame_count() - 1);
    check_model(*dev, m, &a, {0.0, 0.5, 1.0, std::min(2.5, last), last}, Interpolation::slerp);
    check_model(*dev, m, &a, {0.25, std::min(1.5, last)}, Interpolation::euler);
}

TEST(SkinDevice, GoblinMatchesCpu) {
    REQUIRE_DEVICE(dev);
    const fs::path dir = shared_smd_dir() / "hl2_goblin";
    if (!fs::exists(dir / "Goblin_Reference.smd")) GTEST_SKIP() << "shared SMD data not found";
    const SmdModel m = load_smd_reference(dir / "Goblin_Reference.smd");
    const SmdSkeletonAnim a = load_smd_animation(dir / "Goblin_Anim.smd", m);
    ASSERT_GT(a.frame_count(), 400u);
    check_model(*dev, m, &a, {0.0, 1.5, 100.0, 399.5, double(a.frame_count() - 1)}, Interpolation::slerp);
}

TEST(SkinDevice, DwarfMatchesCpu) {
    REQUIRE_DEVICE(dev);
    const fs::path dir = shared_smd_dir() / "hl1_dwarf";
    if (!fs::exists(dir / "ref.SMD")) GTEST_SKIP() << "shared SMD data not found";
    const SmdModel m = load_smd_reference(dir / "ref.SMD");
    const SmdSkeletonAnim a = load_smd_animation(dir / "run.SMD", m);
    const double last = double(a.frame_count() - 1);
    check_model(*dev, m, &a, {0.0, 0.5, std::min(3.0, last), std::min(7.5, last), last}, Interpolation::slerp);
    check_model(*dev, m, &a, {std::min(2.5, last)}, Interpolation::euler);
}

TEST(SkinDevice, BufferHookErrors) {
    REQUIRE_DEVICE(dev);
    const SmdModel m = load_smd_reference(fixture_dir() / "ref_weights.SMD");
    Scene scene;
    const std::uint32_t body = scene.add_object(m.mesh, ObjectKind::dynamic);
    scene.add_instance(body);
    rcl::DeviceScene<SkinHook, rcl::ScaleHook> ds(*dev, scene);
    const PackedSkin skin = pack_skin(m.weights, m.bones.size());
    upload_skin(ds, scene, body, skin);
    // matrices (slot 2) never uploaded
    EXPECT_THROW(ds.update(), std::logic_error);
    const std::vector<float> none;
    EXPECT_THROW((ds.set_hook_buffer<SkinHook, float>(3, std::span<const float>(none))), std::out_of_range);
    EXPECT_THROW((ds.set_hook_buffer<rcl::ScaleHook, float>(0, std::span<const float>(none))), std::out_of_range);
    PackedSkin wrong = skin;
    wrong.offsets.push_back(wrong.offsets.back());
    EXPECT_THROW(upload_skin(ds, scene, body, wrong), std::invalid_argument);
    // Switching the object to a hook without buffers still works (and back).
    ds.set_hook<rcl::ScaleHook>(body, {2.0f});
    ds.update();
    const std::vector<vec3> p = ds.positions(body);
    for (std::size_t i = 0; i < p.size(); ++i) EXPECT_EQ(p[i], m.mesh.positions[i] * 2.0f);
    const Skeleton sk(m);
    const std::vector<SkinMatrix> mats = skin_matrices(sk, sk.bind_transforms());
    upload_skin_matrices(ds, std::span<const SkinMatrix>(mats));
    ds.set_hook<SkinHook>(body, {});
    ds.update();
    const std::vector<vec3> q = ds.positions(body);
    const std::vector<vec3> cpu = skin_positions(skin, mats, m.mesh.positions);
    for (std::size_t i = 0; i < q.size(); ++i) EXPECT_LE(glm::length(q[i] - cpu[i]), 1e-5f * extent_of(cpu));
    EXPECT_EQ(ds.compiled_hooks(), std::vector<std::string>{"skin"});
}

/// `raykit skin ... --device cl` prints the CPU's lines, numbers within 1e-5 of the extent.
void check_cli(const fs::path& ref, const fs::path& anim, double frame) {
    raykit_cli::SkinArgs a;
    a.reference = ref.string();
    a.animation = anim.string();
    a.frame = frame;
    const std::string cpu = raykit_cli::skin_corners_text(a, nullptr);
    a.device_cl = true;
    const std::string dev = raykit_cli::skin_corners_text(a, nullptr);
    std::istringstream ic(cpu), id(dev);
    std::vector<vec3> pc, pd;
    vec3 p;
    while (ic >> p.x >> p.y >> p.z) pc.push_back(p);
    while (id >> p.x >> p.y >> p.z) pd.push_back(p);
    ASSERT_EQ(pc.size(), pd.size());
    ASSERT_FALSE(pc.empty());
    EXPECT_EQ(std::count(cpu.begin(), cpu.end(), '\n'), std::count(dev.begin(), dev.end(), '\n'));
    const float tol = 1e-5f * extent_of(pc);
    for (std::size_t i = 0; i < pc.size(); ++i) ASSERT_LE(glm::length(pc[i] - pd[i]), tol) << "corner " << i;
}

TEST(SkinDevice, CliDeviceClPrintsTheCpuLines) {
    REQUIRE_DEVICE(dev);
    (void)dev;
    char prog[] = "raykit", cmd[] = "skin", ref[] = "r.smd", opt[] = "--device", cl[] = "cl";
    char* argv[] = {prog, cmd, ref, opt, cl};
    EXPECT_TRUE(raykit_cli::parse_skin_args(5, argv, 2).device_cl);
    check_cli(fixture_dir() / "ref_weights.SMD", fixture_dir() / "anim_weights.smd", 2.5);
    const fs::path dir = shared_smd_dir() / "hl2_goblin";
    if (fs::exists(dir / "Goblin_Reference.smd")) check_cli(dir / "Goblin_Reference.smd", dir / "Goblin_Anim.smd", 123.5);
}

}  // namespace
