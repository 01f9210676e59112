// raykit/scene/build.hpp — build a BVH over a triangle mesh.
//
//   Bvh bvh = build_bvh(mesh);                                  // binned SAH
//   Bvh bvh = build_bvh<BinnedSahBuilder>(mesh, {.leaf = {.max_leaf_size = 4}});
#pragma once

#include <vector>

#include "raykit/bvh/binned_sah.hpp"
#include "raykit/math/limits.hpp"
#include "raykit/scene/mesh.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// Per-triangle boxes and centroids, as every builder takes them. Triangles
/// with a non-finite vertex get an empty box and a NaN centroid (builders
/// place them somewhere harmless; they can never be hit). A finite vertex
/// coordinate beyond ±2^32 throws std::domain_error (math/limits.hpp): the
/// float triangle tests give wrong answers there.
struct PrimitiveRefs {
    std::vector<AABB> boxes;
    std::vector<vec3> centers;
};

inline PrimitiveRefs primitive_refs(const MeshView& mesh, unsigned threads = 0) {
    check_positions(mesh.positions, "raykit: mesh");
    PrimitiveRefs r;
    r.boxes.resize(mesh.size());
    r.centers.resize(mesh.size());
    parallel_for(mesh.size(), threads, [&](std::size_t i) {
        r.boxes[i] = mesh.bounds(i);
        r.centers[i] = r.boxes[i].is_empty() ? vec3(std::numeric_limits<float>::quiet_NaN())
                                             : r.boxes[i].center();
    });
    return r;
}

template <class Builder = BinnedSahBuilder>
Bvh build_bvh(const MeshView& mesh, const typename Builder::Config& cfg = {}) {
    const PrimitiveRefs r = primitive_refs(mesh, cfg.threads);
    return Builder::build(r.boxes, r.centers, cfg);
}

}  // namespace raykit
