// raykit/scene/leaf_triangles.hpp — opt-in copy of triangle vertices in leaf order.
//
//   LeafTriangles lt(mesh, bvh);                 // 36 bytes per triangle
//   Hit h = intersect_closest(lt, bvh, ray);     // same answers as (mesh, bvh, ray)
//   Hit w = intersect_closest(lt, wide, ray);    // a WideBvh collapsed from bvh (same prim_ids)
//
// The default trace path reads prim_ids → triangle → three vertex positions:
// three dependent loads per triangle, scattered in memory. This copy stores
// each leaf's triangles' vertices contiguously in prim_ids order, so a leaf is
// one or two cache lines. It is a trade, not a default: it costs 36 bytes per
// triangle (against 12 for the index triangle) and must be refreshed after
// vertices move (update()). Answers are bit-identical to the indexed path,
// including tie-breaking on the triangle index (looked up only on a hit).
// For speed, BlockBvh (scene/block_bvh.hpp) goes further with the same idea:
// the copy in 4-triangle SoA blocks tested in one SIMD step, on a tree built
// for them (README, "Performance against Embree 3").
#pragma once

#include <type_traits>
#include <vector>

#include "raykit/scene/mesh.hpp"
#include "raykit/scene/trace.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct LeafTriangles {
    std::vector<vec3> vertices;  ///< 3 per prim_ids slot: vertices[3k + c] = corner c of prim_ids[k]

    LeafTriangles() = default;
    /// `Tree` is a Bvh or a WideBvh: the copy follows its prim_ids order.
    template <class Tree>
    LeafTriangles(const MeshView& mesh, const Tree& bvh, unsigned threads = 0) {
        update(mesh, bvh, threads);
    }

    /// Re-copies the vertices (after a vertex stage moved them).
    template <class Tree>
    void update(const MeshView& mesh, const Tree& bvh, unsigned threads = 0) {
        vertices.resize(bvh.prim_ids.size() * 3);
        parallel_for(bvh.prim_ids.size(), threads, [&](std::size_t k) {
            const std::uint32_t p = bvh.prim_ids[k];
            for (int c = 0; c < 3; ++c) vertices[3 * k + c] = mesh.vertex(p, c);
        });
    }
    std::size_t memory_bytes() const noexcept { return vertices.size() * sizeof(vec3); }
};

namespace detail {
/// Corners of slot k of a leaf-ordered copy: three consecutive vertices.
struct LeafCorners {
    const vec3* RAYKIT_RESTRICT v;
    RAYKIT_INLINE void operator()(std::uint32_t k, const vec3*& a, const vec3*& b, const vec3*& c) const noexcept {
        a = v + 3 * k, b = a + 1, c = a + 2;
    }
};
}  // namespace detail

/// `Tree` is the Bvh or WideBvh the copy was made for (same prim_ids).
template <class Test = DefaultTriangleTest, class Tree, class Stats = std::nullptr_t>
    requires std::is_same_v<Tree, Bvh> || std::is_same_v<Tree, WideBvh> || std::is_same_v<Tree, WideBvh8>
Hit intersect_closest(const LeafTriangles& lt, const Tree& bvh, const Ray& ray, Stats stats = nullptr) {
    return detail::closest_over_slots<Test>(bvh, ray, detail::LeafCorners{lt.vertices.data()}, stats);
}

template <class Test = DefaultTriangleTest, class Tree, class Stats = std::nullptr_t>
    requires std::is_same_v<Tree, Bvh> || std::is_same_v<Tree, WideBvh> || std::is_same_v<Tree, WideBvh8>
bool intersect_any(const LeafTriangles& lt, const Tree& bvh, const Ray& ray, Stats stats = nullptr) {
    return detail::any_over_slots<Test>(bvh, ray, detail::LeafCorners{lt.vertices.data()}, stats);
}

}  // namespace raykit
