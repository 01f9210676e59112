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
// The walks and BlockLeaves' leaf loop are compiled once per instruction-set level
// (raykit/simd/dispatch.hpp): the part of this header below RAYKIT_ISA_PASS is their per-level
// part, and raykit::closest_hit & co. (declared here, defined there) call the level the CPU runs.
#ifndef RAYKIT_ISA_PASS
#include "raykit/simd/dispatch.hpp"  // first: it includes this part below, then the per-level parts
#endif
#ifndef RAYKIT_SCENE_TRACE_HPP
#define RAYKIT_SCENE_TRACE_HPP

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/traverse_packet.hpp"
#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/scene/mesh.hpp"

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

#endif  // RAYKIT_SCENE_TRACE_HPP

#ifdef RAYKIT_ISA_PASS
namespace raykit::RAYKIT_ISA_NS {

/// BlockLeaves with this level's 4-lane test.
struct BlockLeaves {
    const TriangleBlock4* RAYKIT_RESTRICT blocks;

    using RayData = Watertight4::RayData;
    RAYKIT_INLINE static RayData prepare(const Ray& r) noexcept { return Watertight4::prepare(r); }

    template <class Keep, class Stats>
    RAYKIT_INLINE bool closest(const RayData& rd, const Ray& ray, std::uint32_t first, std::uint32_t count,
                               float& tm, Hit& hit, const Keep& keep, Stats) const {
        bool found = false;
        for (std::uint32_t k = first; k < first + count; ++k) {
            alignas(16) float t[4], u[4], v[4];
            unsigned m = Watertight4::intersect(rd, blocks[k], ray.tmin, tm, t, u, v);
            while (m) {  // lanes in order, as a scalar loop over the leaf's triangles
                const int i = std::countr_zero(m);
                m &= m - 1;
                if (t[i] <= tm) found |= raykit::detail::take_closer(hit, tm, t[i], u[i], v[i], blocks[k].prim[i], keep);
            }
        }
        return found;
    }
    template <class Keep, class Stats>
    RAYKIT_INLINE bool any(const RayData& rd, const Ray& ray, std::uint32_t first, std::uint32_t count,
                           const Keep& keep, Stats) const {
        for (std::uint32_t k = first; k < first + count; ++k) {
            alignas(16) float t[4], u[4], v[4];
            unsigned m = Watertight4::intersect(rd, blocks[k], ray.tmin, ray.tmax, t, u, v);
            if constexpr (!kFilters<Keep>) {
                if (m) return true;
            } else {
                while (m) {
                    const int i = std::countr_zero(m);
                    m &= m - 1;
                    if (keep(blocks[k].prim[i], u[i], v[i])) return true;
                }
            }
        }
        return false;
    }
};

/// A leaf store as this level tests it: raykit::BlockLeaves becomes this level's BlockLeaves;
/// the others are used as they are.
template <class L>
RAYKIT_INLINE const L& at_level(const L& l) noexcept {
    return l;
}
RAYKIT_INLINE BlockLeaves at_level(const raykit::BlockLeaves& l) noexcept { return {l.blocks}; }

// The walks of raykit::closest_hit & co. (trace.hpp's declarations above) at this level; the
// calls between them are qualified, since the public ones are found by argument lookup too.

template <class Tree, class Leaves, class Keep = AcceptAll, class Stats = std::nullptr_t>
Hit closest_hit_within(const Tree& tree, const Leaves& leaves_in, const Ray& ray, float tmax, const Keep& keep = {},
                       Stats stats = nullptr) {
    const auto& leaves = RAYKIT_ISA_NS::at_level(leaves_in);
    using L = std::remove_cvref_t<decltype(leaves)>;
    const typename L::RayData rd = L::prepare(ray);
    Hit hit;
    RAYKIT_ISA_NS::traverse<ClosestHit>(
        tree, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float& tm) RAYKIT_LAMBDA_INLINE {
            return leaves.closest(rd, ray, first, count, tm, hit, keep, stats);
        },
        stats);
    return hit;
}

template <class Tree, class Leaves, class Keep = AcceptAll, class Stats = std::nullptr_t>
bool any_hit(const Tree& tree, const Leaves& leaves_in, const Ray& ray, const Keep& keep = {}, Stats stats = nullptr) {
    const auto& leaves = RAYKIT_ISA_NS::at_level(leaves_in);
    using L = std::remove_cvref_t<decltype(leaves)>;
    const typename L::RayData rd = L::prepare(ray);
    float tmax = ray.tmax;
    return RAYKIT_ISA_NS::traverse<AnyHit>(
        tree, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float&) RAYKIT_LAMBDA_INLINE {
            return leaves.any(rd, ray, first, count, keep, stats);
        },
        stats);
}

/// closest_hit_packet on n ≤ kPacketLanes rays: one packet walk.
template <class Tree, class Leaves, class Keep>
RAYKIT_INLINE void packet_closest(const Tree& tree, const Leaves& leaves, const Ray* rays, const float* tmax,
                                  unsigned n, Hit* hits, const Keep& keep) {
    if (!kPacketTree<Tree> || n < 2 || !one_octant(rays, n)) {
        for (unsigned k = 0; k < n; ++k)
            hits[k] = RAYKIT_ISA_NS::closest_hit_within(tree, leaves, rays[k], tmax ? tmax[k] : rays[k].tmax, keep);
    } else if constexpr (kPacketTree<Tree>) {
        RayPacket<> p(rays, n);
        typename Leaves::RayData rd[kPacketLanes];
        for (unsigned k = 0; k < n; ++k) {
            if (tmax) p.tmax[k] = tmax[k];
            hits[k] = Hit{};
            rd[k] = Leaves::prepare(rays[k]);
        }
        const auto leaf = [&](std::uint32_t first, std::uint32_t count, unsigned m) RAYKIT_LAMBDA_INLINE {
            for (; m; m &= m - 1) {
                const int k = std::countr_zero(m);
                leaves.closest(rd[k], rays[k], first, count, p.tmax[k], hits[k], keep, nullptr);
            }
            return 0u;
        };
        RAYKIT_ISA_NS::traverse_packet<ClosestHit>(tree, p, (1u << n) - 1, leaf);
    }
}

/// any_hit_packet on n ≤ kPacketLanes rays: one packet walk.
template <class Tree, class Leaves, class Keep>
RAYKIT_INLINE unsigned packet_any(const Tree& tree, const Leaves& leaves, const Ray* rays, unsigned n,
                                  const Keep& keep) {
    if (!kPacketTree<Tree> || n < 2 || !one_octant(rays, n)) {
        unsigned hit = 0;
        for (unsigned k = 0; k < n; ++k) hit |= unsigned(RAYKIT_ISA_NS::any_hit(tree, leaves, rays[k], keep)) << k;
        return hit;
    } else if constexpr (kPacketTree<Tree>) {
        const RayPacket<> p(rays, n);
        typename Leaves::RayData rd[kPacketLanes];
        for (unsigned k = 0; k < n; ++k) rd[k] = Leaves::prepare(rays[k]);
        const auto leaf = [&](std::uint32_t first, std::uint32_t count, unsigned m) RAYKIT_LAMBDA_INLINE {
            unsigned done = 0;
            for (; m; m &= m - 1) {
                const int k = std::countr_zero(m);
                if (leaves.any(rd[k], rays[k], first, count, keep, nullptr)) done |= 1u << k;
            }
            return done;
        };
        return RAYKIT_ISA_NS::traverse_packet<AnyHit>(tree, p, (1u << n) - 1, leaf);
    }
    return 0;
}

/// n ≤ kPacketWidth rays, in packets of this level's kPacketLanes.
template <class Tree, class Leaves, class Keep = AcceptAll>
void closest_hit_packet(const Tree& tree, const Leaves& leaves_in, const Ray* rays, const float* tmax, unsigned n,
                        Hit* hits, const Keep& keep = {}) {
    const auto& leaves = RAYKIT_ISA_NS::at_level(leaves_in);
    for (unsigned first = 0; first < n; first += unsigned(kPacketLanes))
        RAYKIT_ISA_NS::packet_closest(tree, leaves, rays + first, tmax ? tmax + first : nullptr,
                                      std::min(n - first, unsigned(kPacketLanes)), hits + first, keep);
}

/// n ≤ kPacketWidth rays, in packets of this level's kPacketLanes.
template <class Tree, class Leaves, class Keep = AcceptAll>
unsigned any_hit_packet(const Tree& tree, const Leaves& leaves_in, const Ray* rays, unsigned n, const Keep& keep = {}) {
    const auto& leaves = RAYKIT_ISA_NS::at_level(leaves_in);
    unsigned hit = 0;
    for (unsigned first = 0; first < n; first += unsigned(kPacketLanes))
        hit |= RAYKIT_ISA_NS::packet_any(tree, leaves, rays + first, std::min(n - first, unsigned(kPacketLanes)), keep)
               << first;
    return hit;
}

}  // namespace raykit::RAYKIT_ISA_NS
#endif  // RAYKIT_ISA_PASS
