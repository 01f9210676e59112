// raykit/scene/trace.hpp — closest-hit and any-hit queries on a mesh + BVH,
// and the brute-force oracle they are tested against.
//
//   Hit h = intersect_closest(mesh, bvh, ray);                // watertight test
//   Hit h = intersect_closest<MollerTrumbore>(mesh, bvh, ray);
//   bool blocked = intersect_any(mesh, bvh, shadow_ray);
//
// Ties (two triangles at the same t) go to the smaller triangle index, so the
// answer does not depend on the tree or traversal order.
#pragma once

#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit {

namespace detail {

/// Closest hit over a BVH whose leaf slots k yield their triangle's corners
/// through `corners(k, a, b, c)` (pointers to the three vertices). The
/// triangle index, prim_ids[k], is read only on a hit (for the tie rule), so
/// every triangle source — indexed mesh or leaf-ordered copy — shares this loop.
template <class Test, class Tree, class Corners, class Stats>
RAYKIT_INLINE Hit closest_over_slots(const Tree& bvh, const Ray& ray, Corners&& corners, Stats stats) {
    const typename Test::RayData rd = Test::prepare(ray);
    const std::uint32_t* RAYKIT_RESTRICT ids = bvh.prim_ids.data();
    Hit hit;
    float tmax = ray.tmax;
    traverse<ClosestHit>(
        bvh, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float& tm) RAYKIT_LAMBDA_INLINE {
            bool found = false;
            for (std::uint32_t k = first; k < first + count; ++k) {
                const vec3 *a, *b, *c;
                corners(k, a, b, c);
                TriHit th;
                if (Test::intersect(rd, *a, *b, *c, ray.tmin, tm, th)) {
                    const std::uint32_t p = ids[k];
                    if (th.t < hit.t || p < hit.prim) {
                        hit = {th.t, th.u, th.v, p, 0};
                        tm = th.t;
                        found = true;
                    }
                }
            }
            return found;
        },
        stats);
    return hit;
}

/// Any hit over leaf slots, with corners as in closest_over_slots.
template <class Test, class Tree, class Corners, class Stats>
RAYKIT_INLINE bool any_over_slots(const Tree& bvh, const Ray& ray, Corners&& corners, Stats stats) {
    const typename Test::RayData rd = Test::prepare(ray);
    float tmax = ray.tmax;
    return traverse<AnyHit>(
        bvh, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float&) RAYKIT_LAMBDA_INLINE {
            for (std::uint32_t k = first; k < first + count; ++k) {
                const vec3 *a, *b, *c;
                corners(k, a, b, c);
                TriHit th;
                if (Test::intersect(rd, *a, *b, *c, ray.tmin, ray.tmax, th)) return true;
            }
            return false;
        },
        stats);
}

/// Corners of slot k of an indexed mesh: prim_ids → triangle → positions.
struct IndexedCorners {
    const vec3* RAYKIT_RESTRICT pos;
    const Triangle* RAYKIT_RESTRICT tris;
    const std::uint32_t* RAYKIT_RESTRICT ids;
    RAYKIT_INLINE void operator()(std::uint32_t k, const vec3*& a, const vec3*& b, const vec3*& c) const noexcept {
        const Triangle& t = tris[ids[k]];
        a = pos + t.v[0], b = pos + t.v[1], c = pos + t.v[2];
    }
};

}  // namespace detail

template <class Test = DefaultTriangleTest, class Stats = std::nullptr_t>
Hit intersect_closest(const MeshView& mesh, const Bvh& bvh, const Ray& ray, Stats stats = nullptr) {
    return detail::closest_over_slots<Test>(
        bvh, ray, detail::IndexedCorners{mesh.positions.data(), mesh.triangles.data(), bvh.prim_ids.data()}, stats);
}

template <class Test = DefaultTriangleTest, class Stats = std::nullptr_t>
bool intersect_any(const MeshView& mesh, const Bvh& bvh, const Ray& ray, Stats stats = nullptr) {
    return detail::any_over_slots<Test>(
        bvh, ray, detail::IndexedCorners{mesh.positions.data(), mesh.triangles.data(), bvh.prim_ids.data()}, stats);
}

/// The same queries on a WideBvh or WideBvh8 (bvh/wide.hpp) collapsed from a
/// binary tree: same answers, fewer nodes visited.
template <class Test = DefaultTriangleTest, int W, class Stats = std::nullptr_t>
Hit intersect_closest(const MeshView& mesh, const WideBvhT<W>& bvh, const Ray& ray, Stats stats = nullptr) {
    return detail::closest_over_slots<Test>(
        bvh, ray, detail::IndexedCorners{mesh.positions.data(), mesh.triangles.data(), bvh.prim_ids.data()}, stats);
}

template <class Test = DefaultTriangleTest, int W, class Stats = std::nullptr_t>
bool intersect_any(const MeshView& mesh, const WideBvhT<W>& bvh, const Ray& ray, Stats stats = nullptr) {
    return detail::any_over_slots<Test>(
        bvh, ray, detail::IndexedCorners{mesh.positions.data(), mesh.triangles.data(), bvh.prim_ids.data()}, stats);
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
