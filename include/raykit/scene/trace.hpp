// raykit/scene/trace.hpp — the one closest-hit and one any-hit traversal of every tree
// shape × leaf store, and the brute-force oracle they are tested against.
//
//   Hit h = intersect_closest(mesh, bvh, ray);                // a Bvh, WideBvh or WideBvh8 over a mesh
//   Hit h = intersect_closest<MollerTrumbore>(mesh, bvh, ray);
//   bool blocked = intersect_any(mesh, bvh, shadow_ray);
//   Hit b = intersect_closest(blocks, ray);                   // BlockBvh (scene/block_bvh.hpp)
//   Hit g = closest_hit(tree, leaves, ray, keep, &stats);     // the one walk those call
//   closest_hit_packet(tree, leaves, rays, nullptr, n, hits);  // n <= kPacketWidth rays as one packet
//
// The acceleration concept is a tree shape (bvh/node.hpp's binary Bvh, bvh/wide.hpp's 4- and
// 8-wide trees: traverse<Mode> walks each) composed with a leaf store that tests the triangles of
// a leaf's slot range:
//   IndexedLeaves<Test>  slots → prim_ids → the mesh's triangle → its three positions; any
//                        triangle test (Test); no copy of the geometry.
//   BlockLeaves          slots are TriangleBlock4s: four triangles' vertices copied in leaf
//                        order, one 4-lane watertight test per block (the fastest CPU path).
//   Scene's instance store (scene/scene.hpp) is a third: a top-level leaf maps the ray into an
//                        object and runs closest_hit on that object's tree.
// closest_hit / any_hit are the only CPU single-ray traversals: every query of raykit (meshes,
// blocks, scenes, the renderer) goes through them, so a change to the walk or a leaf loop is
// made once. Batches of coherent rays take closest_hit_packet / any_hit_packet: up to
// kPacketWidth rays share one walk of a wide tree (bvh/traverse_packet.hpp) over the same leaf
// stores' per-ray leaf loops, and each ray gets its single-ray answer bit for bit (the batch
// calls intersect_closest(blocks, rays, hits) and Scene::intersect_closest(rays, hits)).
//
// A leaf filter `keep(prim, u, v)` (true = a real hit) runs only on candidate hits: alpha
// cut-outs and user callbacks. AcceptAll, the default, is compiled out. The optional Stats
// policy (TraversalStats*, or nullptr for none) counts inner nodes and leaves visited.
//
// Ties (two triangles at the same t) go to the smaller triangle index, so the answer does not
// depend on the tree, the shape or the leaf store.
//
// Instruction-set levels (raykit/simd/isa.hpp says why): the walks, the box and block tests and
// BlockLeaves' leaf loop are compiled once per level the compiler's flags do not already give —
// base, avx2, avx512 — each copy in namespace raykit::isa_<level> under a target pragma (GCC's
// `target`, clang's attribute push). The copy is scene/trace_level.inc, which includes the
// per-level parts of intersect/slab.hpp, intersect/triangle4.hpp and the three bvh/traverse
// headers (what stands below RAYKIT_ISA_PASS there) with RAYKIT_ISA_SSE2 / SSE41 / AVX / FMA /
// AVX512 saying what the level has. raykit::closest_hit & co. (declared below, defined at the
// end) switch on active_isa() and call their level's copy: one load and a predictable branch
// per call. Only those parts are compiled under a target pragma (every other header is
// included before), so no inline function of the standard library or of GLM is ever emitted
// with instructions the CPU may lack. Not Highway: its dynamic dispatch (HWY_EXPORT) takes
// plain functions, and these walks are templates over the caller's leaf filter; and the box
// tests rely on MAXPS/MINPS returning their second operand on NaN (intersect/slab.hpp), which
// the hand-written intrinsics keep.
#ifndef RAYKIT_SCENE_TRACE_HPP
#define RAYKIT_SCENE_TRACE_HPP

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <new>
#include <type_traits>

#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/traverse_packet.hpp"
#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/simd/isa.hpp"

namespace raykit {

/// The leaf filter that keeps every hit; traversals compile its calls out.
struct AcceptAll {
    constexpr bool operator()(std::uint32_t, float, float) const noexcept { return true; }
};
/// True when `F` is a real filter (anything but AcceptAll).
template <class F>
inline constexpr bool kFilters = !std::is_same_v<std::remove_cvref_t<F>, AcceptAll>;

namespace detail {

/// The closest-hit rule of every leaf store: candidate (t, u, v) of triangle p (already within
/// tm) replaces `hit` when it is nearer, or as near with a smaller index, and `keep` accepts
/// it; then tm shrinks to t. Returns whether it did.
template <class Keep>
RAYKIT_INLINE bool take_closer(Hit& hit, float& tm, float t, float u, float v, std::uint32_t p, const Keep& keep) {
    if (!(t < hit.t || p < hit.prim)) return false;
    if constexpr (kFilters<Keep>)
        if (!keep(p, u, v)) return false;
    hit = {t, u, v, p, 0};
    tm = t;
    return true;
}

}  // namespace detail

/// Leaf store over an indexed mesh: slot k is triangle ids[k], tested with `Test`.
template <class Test = DefaultTriangleTest>
struct IndexedLeaves {
    const vec3* RAYKIT_RESTRICT pos;
    const Triangle* RAYKIT_RESTRICT tris;
    const std::uint32_t* RAYKIT_RESTRICT ids;

    using RayData = typename Test::RayData;
    RAYKIT_INLINE static RayData prepare(const Ray& r) noexcept { return Test::prepare(r); }

    /// Closest accepted hit among slots [first, first + count) within [tmin, tm]; shrinks tm.
    template <class Keep, class Stats>
    RAYKIT_INLINE bool closest(const RayData& rd, const Ray& ray, std::uint32_t first, std::uint32_t count,
                               float& tm, Hit& hit, const Keep& keep, Stats) const {
        bool found = false;
        for (std::uint32_t k = first; k < first + count; ++k) {
            const std::uint32_t p = ids[k];
            const Triangle& t = tris[p];
            TriHit th;
            if (Test::intersect(rd, pos[t.v[0]], pos[t.v[1]], pos[t.v[2]], ray.tmin, tm, th))
                found |= detail::take_closer(hit, tm, th.t, th.u, th.v, p, keep);
        }
        return found;
    }
    /// True when some slot in [first, first + count) has an accepted hit in [tmin, tmax].
    template <class Keep, class Stats>
    RAYKIT_INLINE bool any(const RayData& rd, const Ray& ray, std::uint32_t first, std::uint32_t count,
                           const Keep& keep, Stats) const {
        for (std::uint32_t k = first; k < first + count; ++k) {
            const std::uint32_t p = ids[k];
            const Triangle& t = tris[p];
            TriHit th;
            if (Test::intersect(rd, pos[t.v[0]], pos[t.v[1]], pos[t.v[2]], ray.tmin, ray.tmax, th)) {
                if constexpr (kFilters<Keep>)
                    if (!keep(p, th.u, th.v)) continue;
                return true;
            }
        }
        return false;
    }
};

/// Leaf store of 4-triangle blocks: slot k is blocks[k] (watertight test only). The walks test
/// them with their level's Watertight4 (the per-level BlockLeaves below RAYKIT_ISA_PASS).
struct BlockLeaves {
    const TriangleBlock4* RAYKIT_RESTRICT blocks;
};

/// A tree a packet can walk (bvh/traverse_packet.hpp): the 4- and 8-wide trees.
template <class T>
inline constexpr bool kPacketTree = false;
template <int W>
inline constexpr bool kPacketTree<WideBvhT<W>> = true;

/// Closest accepted hit of `ray` in `tree` (a Bvh or WideBvhT) over `leaves`, within
/// [ray.tmin, tmax] (tmax replaces ray.tmax: callers that narrow the interval pass the ray
/// itself, not a copy, whose piecewise stores stall the vector loads of the ray setup).
template <class Tree, class Leaves, class Keep = AcceptAll, class Stats = std::nullptr_t>
Hit closest_hit_within(const Tree& tree, const Leaves& leaves, const Ray& ray, float tmax, const Keep& keep = {},
                       Stats stats = nullptr);
/// Closest accepted hit of `ray` in `tree` (a Bvh or WideBvhT) over `leaves`.
template <class Tree, class Leaves, class Keep = AcceptAll, class Stats = std::nullptr_t>
Hit closest_hit(const Tree& tree, const Leaves& leaves, const Ray& ray, const Keep& keep = {}, Stats stats = nullptr);
/// True when `ray` has an accepted hit in [ray.tmin, ray.tmax].
template <class Tree, class Leaves, class Keep = AcceptAll, class Stats = std::nullptr_t>
bool any_hit(const Tree& tree, const Leaves& leaves, const Ray& ray, const Keep& keep = {}, Stats stats = nullptr);
/// Closest accepted hits of rays[0, n) (n ≤ kPacketWidth) walked as packets: hits[k] is
/// closest_hit_within(tree, leaves, rays[k], tmax[k], keep) bit for bit (tmax null: each
/// ray's own tmax). Trees a packet cannot walk (the binary Bvh) and rays into several
/// octants (one_octant) are walked ray by ray.
template <class Tree, class Leaves, class Keep = AcceptAll>
void closest_hit_packet(const Tree& tree, const Leaves& leaves, const Ray* rays, const float* tmax, unsigned n,
                        Hit* hits, const Keep& keep = {});
/// Any-hit of rays[0, n) (n ≤ kPacketWidth) walked as packets (ray by ray where
/// closest_hit_packet walks them so): bit k set when rays[k] has an accepted hit in
/// [tmin, tmax] (any_hit's answer, lane by lane).
template <class Tree, class Leaves, class Keep = AcceptAll>
unsigned any_hit_packet(const Tree& tree, const Leaves& leaves, const Ray* rays, unsigned n, const Keep& keep = {});

/// The index store of `tree` (built over `mesh`) for triangle test `Test`.
template <class Test = DefaultTriangleTest, class Tree>
IndexedLeaves<Test> indexed_leaves(const MeshView& mesh, const Tree& tree) noexcept {
    return {mesh.positions.data(), mesh.triangles.data(), tree.prim_ids.data()};
}

/// A tree whose leaves index prim_ids: Bvh, WideBvh, WideBvh8.
template <class T>
concept IndexedTree = requires(const T& t) {
    t.nodes;
    t.prim_ids;
};

/// Closest hit over an indexed mesh (ties to the smaller triangle index).
template <class Test = DefaultTriangleTest, IndexedTree Tree, class Stats = std::nullptr_t, class Keep = AcceptAll>
Hit intersect_closest(const MeshView& mesh, const Tree& tree, const Ray& ray, Stats stats = nullptr,
                      const Keep& keep = {}) {
    return closest_hit(tree, indexed_leaves<Test>(mesh, tree), ray, keep, stats);
}

/// Any hit over an indexed mesh.
template <class Test = DefaultTriangleTest, IndexedTree Tree, class Stats = std::nullptr_t, class Keep = AcceptAll>
bool intersect_any(const MeshView& mesh, const Tree& tree, const Ray& ray, Stats stats = nullptr,
                   const Keep& keep = {}) {
    return any_hit(tree, indexed_leaves<Test>(mesh, tree), ray, keep, stats);
}

/// Tests every triangle: the oracle for traversal tests.
template <class Test = DefaultTriangleTest>
Hit brute_force_closest(const MeshView& mesh, const Ray& ray) {
    const typename Test::RayData rd = Test::prepare(ray);
    Hit hit;
    float tmax = ray.tmax;
    for (std::uint32_t p = 0; p < mesh.size(); ++p) {
        TriHit th;
        if (Test::intersect(rd, mesh.vertex(p, 0), mesh.vertex(p, 1), mesh.vertex(p, 2), ray.tmin, tmax, th) &&
            (th.t < hit.t || p < hit.prim)) {
            hit = {th.t, th.u, th.v, p, 0};
            tmax = th.t;
        }
    }
    return hit;
}

template <class Test = DefaultTriangleTest>
bool brute_force_any(const MeshView& mesh, const Ray& ray) {
    const typename Test::RayData rd = Test::prepare(ray);
    for (std::uint32_t p = 0; p < mesh.size(); ++p) {
        TriHit th;
        if (Test::intersect(rd, mesh.vertex(p, 0), mesh.vertex(p, 1), mesh.vertex(p, 2), ray.tmin, ray.tmax, th))
            return true;
    }
    return false;
}

}  // namespace raykit

// ---- the per-level copies (scene/trace_level.inc) and the public walks that pick one ----

#define RAYKIT_ISA_PASS 1

#define RAYKIT_ISA_PRAGMA(...) _Pragma(#__VA_ARGS__)
#if defined(__clang__)
#define RAYKIT_ISA_BEGIN(features) RAYKIT_ISA_PRAGMA(clang attribute push(__attribute__((target(features))), apply_to = function))
#define RAYKIT_ISA_END RAYKIT_ISA_PRAGMA(clang attribute pop)
#else
#define RAYKIT_ISA_BEGIN(features) RAYKIT_ISA_PRAGMA(GCC push_options) RAYKIT_ISA_PRAGMA(GCC target(features))
#define RAYKIT_ISA_END RAYKIT_ISA_PRAGMA(GCC pop_options)
#endif
// base: what the compiler's flags give; avx2 (x86-64-v3) and avx512 (AVX-512 F/VL/BW/DQ over
// it), each under its target (trace_level.inc turns RAYKIT_ISA_LEVEL into feature macros)
#define RAYKIT_ISA_NS isa_base
#define RAYKIT_ISA_LEVEL 0
#include "raykit/scene/trace_level.inc"
#if RAYKIT_ISA_BUILD_AVX2
RAYKIT_ISA_BEGIN("sse4.1,sse4.2,popcnt,avx,avx2,fma,bmi,bmi2")
#define RAYKIT_ISA_NS isa_avx2
#define RAYKIT_ISA_LEVEL 1
#include "raykit/scene/trace_level.inc"
RAYKIT_ISA_END
#endif
#if RAYKIT_ISA_BUILD_AVX512
RAYKIT_ISA_BEGIN("sse4.1,sse4.2,popcnt,avx,avx2,fma,bmi,bmi2,avx512f,avx512vl,avx512bw,avx512dq")
#define RAYKIT_ISA_NS isa_avx512
#define RAYKIT_ISA_LEVEL 2
#include "raykit/scene/trace_level.inc"
RAYKIT_ISA_END
#endif
#undef RAYKIT_ISA_PRAGMA
#undef RAYKIT_ISA_BEGIN
#undef RAYKIT_ISA_END

#undef RAYKIT_ISA_PASS

/// `return <level namespace>::CALL;` for the level active_isa() names.
#if RAYKIT_ISA_BUILD_AVX512
#define RAYKIT_ISA_CASE_AVX512(...) \
    case ::raykit::Isa::avx512:     \
        return ::raykit::isa_avx512::__VA_ARGS__;
#else
#define RAYKIT_ISA_CASE_AVX512(...)
#endif
#if RAYKIT_ISA_BUILD_AVX2
#define RAYKIT_ISA_CASE_AVX2(...) \
    case ::raykit::Isa::avx2:     \
        return ::raykit::isa_avx2::__VA_ARGS__;
#else
#define RAYKIT_ISA_CASE_AVX2(...)
#endif
#if RAYKIT_ISA_BUILD_AVX2 || RAYKIT_ISA_BUILD_AVX512
#define RAYKIT_ISA_DISPATCH(...)                    \
    switch (::raykit::active_isa()) {               \
        RAYKIT_ISA_CASE_AVX512(__VA_ARGS__)         \
        RAYKIT_ISA_CASE_AVX2(__VA_ARGS__)           \
        default:                                    \
            return ::raykit::isa_base::__VA_ARGS__; \
    }
#else
#define RAYKIT_ISA_DISPATCH(...) return ::raykit::isa_base::__VA_ARGS__;
#endif

namespace raykit {

// The per-ray state types, as the base level has them (tests compare them with their scalar forms).
using isa_base::SlabRay;
using isa_base::Watertight4;
using isa_base::WideSlabRay;

/// Ordered single-ray walk of a Bvh or WideBvhT (bvh/traverse.hpp, bvh/traverse_wide.hpp).
template <class Mode = ClosestHit, class Tree, class LeafFn, class Stats = std::nullptr_t>
bool traverse(const Tree& tree, const Ray& ray, float& tmax, LeafFn&& leaf, Stats stats = nullptr) {
    RAYKIT_ISA_DISPATCH(traverse_entry<Mode>(tree, ray, tmax, leaf, stats))
}

template <class Tree, class Leaves, class Keep, class Stats>
Hit closest_hit_within(const Tree& tree, const Leaves& leaves, const Ray& ray, float tmax, const Keep& keep,
                       Stats stats) {
    RAYKIT_ISA_DISPATCH(closest_hit_within(tree, leaves, ray, tmax, keep, stats))
}

template <class Tree, class Leaves, class Keep, class Stats>
Hit closest_hit(const Tree& tree, const Leaves& leaves, const Ray& ray, const Keep& keep, Stats stats) {
    RAYKIT_ISA_DISPATCH(closest_hit_within(tree, leaves, ray, ray.tmax, keep, stats))
}

template <class Tree, class Leaves, class Keep, class Stats>
bool any_hit(const Tree& tree, const Leaves& leaves, const Ray& ray, const Keep& keep, Stats stats) {
    RAYKIT_ISA_DISPATCH(any_hit(tree, leaves, ray, keep, stats))
}

template <class Tree, class Leaves, class Keep>
void closest_hit_packet(const Tree& tree, const Leaves& leaves, const Ray* rays, const float* tmax, unsigned n,
                        Hit* hits, const Keep& keep) {
    RAYKIT_ISA_DISPATCH(closest_hit_packet(tree, leaves, rays, tmax, n, hits, keep))
}

template <class Tree, class Leaves, class Keep>
unsigned any_hit_packet(const Tree& tree, const Leaves& leaves, const Ray* rays, unsigned n, const Keep& keep) {
    RAYKIT_ISA_DISPATCH(any_hit_packet(tree, leaves, rays, n, keep))
}

}  // namespace raykit

#endif  // RAYKIT_SCENE_TRACE_HPP
