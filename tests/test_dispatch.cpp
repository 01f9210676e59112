// The instruction-set levels the traversals dispatch to (raykit/simd/isa.hpp, scene/trace.hpp),
// from a build for baseline x86-64 as a consumer's default build is: every level is compiled in,
// and each one this CPU runs traces the same rays through every tree shape, leaf store, batch
// and scene. Every level must give brute force's answer (the scalar watertight test) and the
// base level's, bit for bit: hits, t, u, v, instance and any-hit flags.
#include <gtest/gtest.h>

#include <bit>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "raykit.hpp"
#include "raykit/scene/generate.hpp"
#include "test_support.hpp"

using namespace raykit;

namespace {

/// Everything one level answered, in one flat record per query.
struct Answers {
    std::vector<std::uint32_t> words;
    void add(const Hit& h) {
        words.insert(words.end(), {h.prim, h.inst, std::bit_cast<std::uint32_t>(h.t), std::bit_cast<std::uint32_t>(h.u),
                                   std::bit_cast<std::uint32_t>(h.v)});
    }
    void add(bool b) { words.push_back(b ? 1u : 0u); }
};

/// Restores the default cap after each test.
class Levels : public ::testing::Test {
  protected:
    void TearDown() override { set_max_isa(Isa::avx512); }
    /// The levels this CPU runs, lowest first.
    static std::vector<Isa> levels() {
        std::vector<Isa> v;
        for (Isa i : {Isa::base, Isa::avx2, Isa::avx512})
            if (int(i) <= int(cpu_isa())) v.push_back(i);
        return v;
    }
};

/// The first word where two levels differ ("" when none).
std::string first_difference(const Answers& a, const Answers& b) {
    if (a.words.size() != b.words.size()) return "different counts";
    for (std::size_t i = 0; i < a.words.size(); ++i)
        if (a.words[i] != b.words[i])
            return "word " + std::to_string(i) + ": " + std::to_string(a.words[i]) + " vs " + std::to_string(b.words[i]);
    return "";
}

}  // namespace

TEST_F(Levels, ActiveLevelFollowsTheCapAndTheCpu) {
    std::printf("[ info ] compiled for %s, CPU runs %s\n", isa_name(compiled_isa()), isa_name(cpu_isa()));
    for (Isa cap : {Isa::base, Isa::avx2, Isa::avx512}) {
        set_max_isa(cap);
        const Isa want = int(cap) < int(cpu_isa()) ? cap : cpu_isa();
        EXPECT_EQ(int(active_isa()), int(int(want) < int(compiled_isa()) ? compiled_isa() : want)) << isa_name(cap);
    }
}

TEST_F(Levels, EveryLevelGivesTheSameAnswersAsBruteForce) {
    const Mesh m = make_bumpy_torus(12000);
    const MeshView mv(m);
    const Bvh bvh = build_bvh(mv, BuildOptions{});
    const WideBvh8 wide = WideBvh8::build(bvh);
    const BlockBvh8 blocks8 = BlockBvh8::build(m);
    const BlockBvh blocks4 = BlockBvh::build(m, bvh);
    const std::vector<Ray> rays = test::packet_test_rays(m, 2001, 5);

    // the oracle: brute force with the scalar test, compiled once (no level)
    std::vector<Hit> oracle(rays.size());
    std::vector<bool> oracle_any(rays.size());
    std::size_t hits = 0;
    for (std::size_t i = 0; i < rays.size(); ++i) {
        oracle[i] = brute_force_closest(m, rays[i]);
        oracle_any[i] = brute_force_any(m, rays[i]);
        hits += oracle[i].valid();
    }
    ASSERT_GT(hits, rays.size() / 4);

    // a scene of instances past pi, with a filter, single rays and batches
    Scene s;
    const std::uint32_t torus = s.add_object(make_bumpy_torus(4000));
    const std::uint32_t ball = s.add_object(make_icosphere(3));
    s.add_instance(torus);
    for (int k = 1; k < 4; ++k) {
        mat4 t = glm::translate(mat4(1.0f), vec3(1.5f * float(k), 0.3f * float(k), -0.5f));
        t = glm::rotate(t, 1.3f * float(k) + 2.0f, vec3(0.0f, 1.0f, 0.0f));
        s.add_instance(k % 2 ? ball : torus, glm::scale(t, vec3(0.5f)));
    }
    s.update_top_level();
    const std::vector<Ray> scene_rays = test::batch_test_rays(s.world_mesh().first, 1500, 6);
    const auto keep = [](std::uint32_t, std::uint32_t p, float u, float) { return p % 5 != 0 || u < 0.5f; };

    std::vector<Answers> per_level;
    for (const Isa level : levels()) {
        set_max_isa(level);
        ASSERT_EQ(int(active_isa()), int(level));
        Answers a;
        std::size_t wrong = 0;
        for (std::size_t i = 0; i < rays.size(); ++i) {
            const Ray& r = rays[i];
            const Hit got[4] = {intersect_closest(blocks8, r), intersect_closest(blocks4, r),
                                intersect_closest(mv, wide, r), intersect_closest(mv, bvh, r)};
            const bool any[4] = {intersect_any(blocks8, r), intersect_any(blocks4, r), intersect_any(mv, wide, r),
                                 intersect_any(mv, bvh, r)};
            for (int k = 0; k < 4; ++k) {
                wrong += got[k].prim != oracle[i].prim || std::bit_cast<std::uint32_t>(got[k].t) !=
                                                              std::bit_cast<std::uint32_t>(oracle[i].t);
                wrong += any[k] != oracle_any[i];
                a.add(got[k]);
                a.add(any[k]);
            }
        }
        EXPECT_EQ(wrong, 0u) << isa_name(level) << ": answers unlike brute force's";
        // the other triangle tests follow the same FMA rule (config.hpp), so they too answer
        // alike inside a level's walk and in brute force outside any
        std::size_t other_wrong = 0;
        for (std::size_t i = 0; i < rays.size(); i += 3) {
            const Hit mt = intersect_closest<MollerTrumbore>(mv, wide, rays[i]);
            const Hit th = intersect_closest<ThesisTest>(mv, bvh, rays[i]);
            const Hit mt_o = brute_force_closest<MollerTrumbore>(m, rays[i]);
            const Hit th_o = brute_force_closest<ThesisTest>(m, rays[i]);
            other_wrong += std::bit_cast<std::uint32_t>(mt.t) != std::bit_cast<std::uint32_t>(mt_o.t) ||
                           mt.prim != mt_o.prim;
            // the thesis test's hits can lie outside the triangle's box, where a tree never looks
            if (th.valid() && th_o.prim == th.prim)
                other_wrong += std::bit_cast<std::uint32_t>(th.t) != std::bit_cast<std::uint32_t>(th_o.t);
            a.add(mt);
            a.add(th);
        }
        EXPECT_EQ(other_wrong, 0u) << isa_name(level) << ": Moller-Trumbore or thesis test unlike brute force";
        for (const BlockBvh8* b : {&blocks8}) {
            std::vector<Hit> batch(rays.size());
            std::vector<std::uint8_t> occluded(rays.size());
            intersect_closest(*b, rays, batch, 1);
            intersect_any(*b, rays, occluded, 1);
            std::size_t batch_wrong = 0;  // packets (frusta at this level's width) against brute force
            for (std::size_t i = 0; i < rays.size(); ++i) {
                batch_wrong += batch[i].prim != oracle[i].prim ||
                               std::bit_cast<std::uint32_t>(batch[i].t) != std::bit_cast<std::uint32_t>(oracle[i].t);
                batch_wrong += (occluded[i] != 0) != oracle_any[i];
                a.add(batch[i]);
                a.add(occluded[i] != 0);
            }
            EXPECT_EQ(batch_wrong, 0u) << isa_name(level) << ": batch answers unlike brute force's";
        }
        std::vector<Hit> sb(scene_rays.size());
        std::vector<std::uint8_t> so(scene_rays.size());
        s.intersect_closest(scene_rays, sb, keep);
        s.intersect_any(scene_rays, so, keep);
        for (std::size_t i = 0; i < scene_rays.size(); ++i) {
            a.add(s.intersect_closest(scene_rays[i], keep));
            a.add(s.intersect_any(scene_rays[i], keep));
            a.add(sb[i]);
            a.add(so[i] != 0);
        }
        per_level.push_back(std::move(a));
    }
    for (std::size_t l = 1; l < per_level.size(); ++l)
        EXPECT_EQ(first_difference(per_level[l], per_level[0]), "") << isa_name(levels()[l]) << " against base";
    std::printf("[ info ] %zu levels (up to %s), %zu rays (%zu hit) x 4 trees + batches + %zu scene rays, %zu words each\n",
                per_level.size(), isa_name(levels().back()), rays.size(), hits, scene_rays.size(),
                per_level[0].words.size());
}
