// raykit/scene/leaf_triangles.hpp — opt-in copy of triangle vertices in leaf order.
//
//   LeafTriangles lt(mesh, bvh);                 // 36 bytes per triangle
//   Hit h = intersect_closest(lt, bvh, ray);     // same answers as (mesh, bvh, ray)
//
// The default trace path reads prim_ids → triangle → three vertex positions:
// three dependent loads per triangle, scattered in memory. This copy stores
// each leaf's triangles' vertices contiguously in prim_ids order, so a leaf is
// one or two cache lines. It is a trade, not a default: it costs 36 bytes per
// triangle (against 12 for the index triangle) and must be refreshed after
// vertices move (update()). Answers are bit-identical to the indexed path,
// including tie-breaking on the triangle index (looked up only on a hit).
#pragma once

#include <vector>

#include "raykit/bvh/traverse.hpp"
#include "raykit/intersect/triangle.hpp"
#include "raykit/math/hit.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct LeafTriangles {
    std::vector<vec3> vertices;  ///< 3 per prim_ids slot: vertices[3k + c] = corner c of prim_ids[k]

    LeafTriangles() = default;
    LeafTriangles(const MeshView& mesh, const Bvh& bvh, unsigned threads = 0) { update(mesh, bvh, threads); }

    /// Re-copies the vertices (after a vertex stage moved them).
    void update(const MeshView& mesh, const Bvh& bvh, unsigned threads = 0) {
        vertices.resize(bvh.prim_ids.size() * 3);
        parallel_for(bvh.prim_ids.size(), threads, [&](std::size_t k) {
            const std::uint32_t p = bvh.prim_ids[k];
            for (int c = 0; c < 3; ++c) vertices[3 * k + c] = mesh.vertex(p, c);
        });
    }
    std::size_t memory_bytes() const noexcept { return vertices.size() * sizeof(vec3); }
};

template <class Test = DefaultTriangleTest, class Stats = std::nullptr_t>
Hit intersect_closest(const LeafTriangles& lt, const Bvh& bvh, const Ray& ray, Stats stats = nullptr) {
    const typename Test::RayData rd = Test::prepare(ray);
    const vec3* RAYKIT_RESTRICT v = lt.vertices.data();
    const std::uint32_t* RAYKIT_RESTRICT ids = bvh.prim_ids.data();
    Hit hit;
    float tmax = ray.tmax;
    traverse<ClosestHit>(
        bvh, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float& tm) RAYKIT_LAMBDA_INLINE {
            bool found = false;
            for (std::uint32_t k = first; k < first + count; ++k) {
                TriHit th;
                if (Test::intersect(rd, v[3 * k], v[3 * k + 1], v[3 * k + 2], ray.tmin, tm, th)) {
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

template <class Test = DefaultTriangleTest, class Stats = std::nullptr_t>
bool intersect_any(const LeafTriangles& lt, const Bvh& bvh, const Ray& ray, Stats stats = nullptr) {
    const typename Test::RayData rd = Test::prepare(ray);
    const vec3* RAYKIT_RESTRICT v = lt.vertices.data();
    float tmax = ray.tmax;
    return traverse<AnyHit>(
        bvh, ray, tmax,
        [&](std::uint32_t first, std::uint32_t count, float&) RAYKIT_LAMBDA_INLINE {
            for (std::uint32_t k = first; k < first + count; ++k) {
                TriHit th;
                if (Test::intersect(rd, v[3 * k], v[3 * k + 1], v[3 * k + 2], ray.tmin, ray.tmax, th)) return true;
            }
            return false;
        },
        stats);
}

}  // namespace raykit
