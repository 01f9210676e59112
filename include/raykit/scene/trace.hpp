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
#include "raykit/intersect/triangle.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/scene/mesh.hpp"

namespace raykit {

template <class Test = DefaultTriangleTest, class Stats = std::nullptr_t>
Hit intersect_closest(const MeshView& mesh, const Bvh& bvh, const Ray& ray, Stats stats = nullptr) {
    const typename Test::RayData rd = Test::prepare(ray);
    const vec3* RAYKIT_RESTRICT pos = mesh.positions.data();
    const Triangle* RAYKIT_RESTRICT tris = mesh.triangles.data();
    const std::uint32_t* RAYKIT_RESTRICT ids = bvh.prim_ids.data();
    Hit hit;
    float tmax = ray.tmax;
    traverse<ClosestHit>(
        bvh, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float& tm) RAYKIT_LAMBDA_INLINE {
            bool found = false;
            for (std::uint32_t k = first; k < first + count; ++k) {
                const std::uint32_t p = ids[k];
                const Triangle& t = tris[p];
                TriHit th;
                if (Test::intersect(rd, pos[t.v[0]], pos[t.v[1]], pos[t.v[2]], ray.tmin, tm, th) &&
                    (th.t < hit.t || p < hit.prim)) {
                    hit = {th.t, th.u, th.v, p, 0};
                    tm = th.t;
                    found = true;
                }
            }
            return found;
        },
        stats);
    return hit;
}

template <class Test = DefaultTriangleTest, class Stats = std::nullptr_t>
bool intersect_any(const MeshView& mesh, const Bvh& bvh, const Ray& ray, Stats stats = nullptr) {
    const typename Test::RayData rd = Test::prepare(ray);
    const vec3* RAYKIT_RESTRICT pos = mesh.positions.data();
    const Triangle* RAYKIT_RESTRICT tris = mesh.triangles.data();
    const std::uint32_t* RAYKIT_RESTRICT ids = bvh.prim_ids.data();
    float tmax = ray.tmax;
    return traverse<AnyHit>(
        bvh, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float&) RAYKIT_LAMBDA_INLINE {
            for (std::uint32_t k = first; k < first + count; ++k) {
                const Triangle& t = tris[ids[k]];
                TriHit th;
                if (Test::intersect(rd, pos[t.v[0]], pos[t.v[1]], pos[t.v[2]], ray.tmin, ray.tmax, th))
                    return true;
            }
            return false;
        },
        stats);
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
