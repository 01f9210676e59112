// raykit/scene/mesh.hpp — indexed triangle mesh with materials and groups.
//
// Triangles index one shared vertex array (never copies). Each vertex has a
// position and, when the source had them, a normal and texture coordinates:
// `normals` and `texcoords` are either empty or as long as `positions`. A loader
// that meets separate position/normal/uv indices (OBJ) makes one vertex per
// distinct (position, uv, normal) triple, so a closed mesh may hold several
// vertices with bit-identical positions along seams — the watertight test does
// not care, it sees the same coordinates.
#pragma once

#include <cstddef>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "raykit/math/aabb.hpp"

namespace raykit {

/// Three indices into the vertex arrays. 12 bytes, crosses to OpenCL unchanged.
struct Triangle {
    std::uint32_t v[3];
    std::uint32_t operator[](int i) const noexcept { return v[i]; }
};
static_assert(sizeof(Triangle) == 12 && alignof(Triangle) == 4);

/// Material as read from MTL (defaults follow the MTL specification).
struct Material {
    std::string name;
    vec3 ka{0.0f};       ///< Ka, ambient
    vec3 kd{0.8f};       ///< Kd, diffuse
    vec3 ks{0.0f};       ///< Ks, specular
    vec3 ke{0.0f};       ///< Ke, emission
    float ns = 0.0f;     ///< Ns, Phong exponent
    float ni = 1.0f;     ///< Ni, index of refraction
    float d = 1.0f;      ///< d (or 1 - Tr), opacity
    int illum = 2;       ///< illumination model
    std::string map_kd;  ///< diffuse texture path, resolved relative to the MTL file ("" if none)
};

/// A named run of consecutive triangles (`o` or `g` in OBJ).
struct Group {
    std::string name;
    std::uint32_t first_triangle = 0;
    std::uint32_t triangle_count = 0;
};

inline constexpr std::uint32_t kNoMaterial = kInvalidIndex;

struct Mesh {
    std::vector<vec3> positions;
    std::vector<vec3> normals;    ///< empty, or one per vertex (zero where the source had none)
    std::vector<vec2> texcoords;  ///< empty, or one per vertex
    std::vector<Triangle> triangles;
    std::vector<std::uint32_t> material_ids;  ///< one per triangle, kNoMaterial when none
    std::vector<Material> materials;
    std::vector<Group> objects;  ///< from `o`
    std::vector<Group> groups;   ///< from `g`
    std::vector<std::string> warnings;  ///< non-fatal loader messages (e.g. missing .mtl)

    std::size_t triangle_count() const noexcept { return triangles.size(); }
    std::size_t vertex_count() const noexcept { return positions.size(); }
    /// Bounds of the finite triangles (MeshView::bounds()).
    AABB bounds() const noexcept;
};

/// Non-owning view of the geometry a tracer needs.
struct MeshView {
    std::span<const vec3> positions;
    std::span<const Triangle> triangles;

    MeshView() = default;
    MeshView(std::span<const vec3> p, std::span<const Triangle> t) : positions(p), triangles(t) {}
    MeshView(const Mesh& m) : positions(m.positions), triangles(m.triangles) {}  // NOLINT implicit

    std::size_t triangle_count() const noexcept { return triangles.size(); }
    std::size_t vertex_count() const noexcept { return positions.size(); }
    /// triangle_count(), the container-style name the traversal code uses.
    std::size_t size() const noexcept { return triangles.size(); }
    const vec3& vertex(std::size_t tri, int corner) const noexcept {
        return positions[triangles[tri].v[corner]];
    }
    /// Bounds of a triangle; empty when any vertex is not finite (such a
    /// triangle can never be hit, so it needs no space in the tree).
    AABB bounds(std::size_t tri) const noexcept {
        AABB b;
        for (int c = 0; c < 3; ++c) {
            const vec3& p = vertex(tri, c);
            if (!is_finite(p)) return AABB{};
            b.grow(p);
        }
        return b;
    }
    /// Bounds of all triangles whose vertices are finite (what a tree over them encloses);
    /// empty for a mesh without such triangles.
    AABB bounds() const noexcept {
        AABB b;
        for (std::size_t t = 0; t < triangles.size(); ++t) b.grow(bounds(t));
        return b;
    }
};

inline AABB Mesh::bounds() const noexcept { return MeshView(*this).bounds(); }

}  // namespace raykit
