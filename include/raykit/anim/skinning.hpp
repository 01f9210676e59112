// raykit/anim/skinning.hpp — linear blend skinning on the CPU, and the packed
// per-vertex weight layout the device path will share.
//
// Packed layout (one definition for host and device)
// --------------------------------------------------
//   struct SkinMatrix { float m[12]; };            // 48 bytes per bone
//       Row-major 3x4 [R | t]: x' = m[0] x + m[1] y + m[2] z + m[3],
//       y' = m[4..7] . (x y z 1), z' = m[8..11] . (x y z 1).
//   struct PackedLink { uint16 bone; uint16 weight; };   // 4 bytes per link
//       weight is unorm16: w = weight * (1.0f / 65535.0f). The weights of a
//       vertex sum to exactly 65535, so a single-link vertex has weight 65535
//       and the kernel uses its bone's matrix as is (exact).
//   struct PackedSkin {
//       std::vector<uint32> offsets;   // vertex_count + 1 entries
//       std::vector<PackedLink> links; // vertex v owns links[offsets[v] .. offsets[v+1])
//       uint32 bone_count;             // every link's bone is < bone_count
//   };
//   Cost: 4 + 4 * k bytes per vertex with k links (plus one uint32 in all):
//   8 bytes for a Half-Life 1 vertex (one bone), 12 for two links, 20 for
//   four. Any number of links per vertex; at most 65535 bones. Quantizing the
//   weights to 1/65535 moves a vertex by at most k/2 * 1/65535 of the
//   distance between its bones' candidate positions (about 1e-5 of the model
//   for two links); single-bone vertices are exact.
//
// Interface
// ---------
//   PackedSkin pack_skin(std::span<const VertexWeights> weights, std::size_t bone_count);
//       Quantizes weights (rescaled to sum 1, rounded, the rounding error
//       given to the largest weight so the sum is 65535; links that round to
//       0 are dropped). Throws std::invalid_argument for a bone >= bone_count,
//       bone_count > 65535, a negative or non-finite weight, or weights of a
//       vertex summing to 0. A vertex without links gets no links (it stays
//       at its rest position when skinned).
//   SkinMatrix to_skin_matrix(const glm::dmat4& m);
//   std::vector<SkinMatrix> skin_matrices(const Skeleton&, std::span<const BoneTransform> local);
//       Skeleton::skinning_matrices (world * inverse bind, in double)
//       rounded to float.
//   void skin_vertices(const PackedSkin& skin, std::span<const SkinMatrix> matrices,
//                      std::span<const vec3> rest_positions, std::span<const vec3> rest_normals,
//                      std::span<vec3> out_positions, std::span<vec3> out_normals,
//                      unsigned threads = 0);
//       Linear blend skinning: M_v = sum_k w_k * matrices[bone_k] (a
//       single-link vertex uses its matrix as is), p' = M_v (p, 1),
//       n' = normalize(M_v (n, 0)) (zero stays zero). rest_normals and
//       out_normals may both be empty (positions only). Parallel over
//       vertices with raykit::parallel_for (threads = 0: all hardware
//       threads). Throws std::invalid_argument on mismatched sizes or fewer
//       matrices than skin.bone_count. out_* must not alias rest_*.
//   std::vector<vec3> skin_positions(const PackedSkin&, std::span<const SkinMatrix>,
//                                    std::span<const vec3> rest_positions, unsigned threads = 0);
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include <glm/glm.hpp>

#include "raykit/anim/skeleton.hpp"
#include "raykit/config.hpp"
#include "raykit/math/types.hpp"
#include "raykit/scene/skeleton_data.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// Row-major 3x4 rigid (or blended) transform, 48 bytes; crosses to the device.
struct SkinMatrix {
    float m[12];
};
static_assert(sizeof(SkinMatrix) == 48 && alignof(SkinMatrix) == 4);

/// One bone influence: bone index and unorm16 weight; crosses to the device.
struct PackedLink {
    std::uint16_t bone;
    std::uint16_t weight;
};
static_assert(sizeof(PackedLink) == 4 && alignof(PackedLink) == 2);

inline constexpr std::uint32_t kPackedWeightOne = 65535;  ///< sum of a vertex's packed weights

/// Per-vertex bone links in compressed-row form (see the header comment).
struct PackedSkin {
    std::vector<std::uint32_t> offsets{0};  ///< vertex_count() + 1 entries
    std::vector<PackedLink> links;
    std::uint32_t bone_count = 0;

    std::size_t vertex_count() const noexcept { return offsets.empty() ? 0 : offsets.size() - 1; }
    /// Bytes the device needs for the weights (offsets + links).
    std::size_t bytes() const noexcept {
        return offsets.size() * sizeof(std::uint32_t) + links.size() * sizeof(PackedLink);
    }
};

inline PackedSkin pack_skin(std::span<const VertexWeights> weights, std::size_t bone_count) {
    if (bone_count > 65535) throw std::invalid_argument("pack_skin: more than 65535 bones");
    PackedSkin s;
    s.bone_count = static_cast<std::uint32_t>(bone_count);
    s.offsets.reserve(weights.size() + 1);
    std::size_t total = 0;
    for (const VertexWeights& w : weights) total += w.links.size();
    s.links.reserve(total);
    std::vector<std::uint32_t> q;
    for (std::size_t v = 0; v < weights.size(); ++v) {
        const std::vector<BoneWeight>& links = weights[v].links;
        double sum = 0.0;
        for (const BoneWeight& l : links) {
            if (l.bone >= bone_count) {
                throw std::invalid_argument("pack_skin: vertex " + std::to_string(v) + " links to bone " +
                                            std::to_string(l.bone) + " (" + std::to_string(bone_count) + " bones)");
            }
            if (!std::isfinite(l.weight) || l.weight < 0.0f) {
                throw std::invalid_argument("pack_skin: vertex " + std::to_string(v) + " has a bad weight");
            }
            sum += l.weight;
        }
        if (!links.empty() && !(sum > 0.0)) {
            throw std::invalid_argument("pack_skin: weights of vertex " + std::to_string(v) + " sum to 0");
        }
        q.assign(links.size(), 0);
        std::int64_t qsum = 0;
        std::size_t largest = 0;
        for (std::size_t k = 0; k < links.size(); ++k) {
            q[k] = static_cast<std::uint32_t>(std::lround(links[k].weight / sum * kPackedWeightOne));
            qsum += q[k];
            if (links[k].weight > links[largest].weight) largest = k;
        }
        if (!links.empty()) {
            // |rounding error| <= k/2 and the largest weight is >= 65535/k, so this stays >= 0.
            q[largest] = static_cast<std::uint32_t>(static_cast<std::int64_t>(q[largest]) + kPackedWeightOne - qsum);
        }
        for (std::size_t k = 0; k < links.size(); ++k) {
            if (q[k] == 0) continue;
            s.links.push_back(PackedLink{static_cast<std::uint16_t>(links[k].bone), static_cast<std::uint16_t>(q[k])});
        }
        if (s.links.size() >= 0xFFFFFFFFu) throw std::invalid_argument("pack_skin: too many links");
        s.offsets.push_back(static_cast<std::uint32_t>(s.links.size()));
    }
    return s;
}

inline SkinMatrix to_skin_matrix(const glm::dmat4& m) noexcept {
    SkinMatrix s;
    for (int r = 0; r < 3; ++r) {
        for (int c = 0; c < 4; ++c) s.m[4 * r + c] = static_cast<float>(m[c][r]);  // glm is column-major
    }
    return s;
}

inline std::vector<SkinMatrix> skin_matrices(const Skeleton& skeleton, std::span<const BoneTransform> local) {
    const std::vector<glm::dmat4> m = skeleton.skinning_matrices(local);
    std::vector<SkinMatrix> out(m.size());
    for (std::size_t i = 0; i < m.size(); ++i) out[i] = to_skin_matrix(m[i]);
    return out;
}

namespace detail {

/// The blended matrix of one vertex's links.
RAYKIT_INLINE void skin_blend(const PackedLink* RAYKIT_RESTRICT l, std::uint32_t count,
                              const SkinMatrix* RAYKIT_RESTRICT mats, float* RAYKIT_RESTRICT acc) noexcept {
    if (count == 1) {
        const float* m = mats[l[0].bone].m;
        for (int j = 0; j < 12; ++j) acc[j] = m[j];
        return;
    }
    for (int j = 0; j < 12; ++j) acc[j] = 0.0f;
    for (std::uint32_t k = 0; k < count; ++k) {
        const float w = static_cast<float>(l[k].weight) * (1.0f / 65535.0f);
        const float* m = mats[l[k].bone].m;
        for (int j = 0; j < 12; ++j) acc[j] += w * m[j];
    }
}

}  // namespace detail

inline void skin_vertices(const PackedSkin& skin, std::span<const SkinMatrix> matrices,
                          std::span<const vec3> rest_positions, std::span<const vec3> rest_normals,
                          std::span<vec3> out_positions, std::span<vec3> out_normals, unsigned threads = 0) {
    if (skin.offsets.empty() || skin.offsets.back() != skin.links.size()) {
        throw std::invalid_argument("skin_vertices: corrupt PackedSkin (offsets do not end at links.size())");
    }
    const std::size_t n = skin.vertex_count();
    if (rest_positions.size() != n || out_positions.size() != n) {
        throw std::invalid_argument("skin_vertices: positions need one entry per skinned vertex");
    }
    const bool normals = !rest_normals.empty();
    if (normals ? (rest_normals.size() != n || out_normals.size() != n) : !out_normals.empty()) {
        throw std::invalid_argument("skin_vertices: normals need one entry per skinned vertex (or none)");
    }
    if (matrices.size() < skin.bone_count) {
        throw std::invalid_argument("skin_vertices: fewer matrices than bones");
    }
    const std::uint32_t* RAYKIT_RESTRICT off = skin.offsets.data();
    const PackedLink* RAYKIT_RESTRICT links = skin.links.data();
    const SkinMatrix* RAYKIT_RESTRICT mats = matrices.data();
    const vec3* RAYKIT_RESTRICT rp = rest_positions.data();
    const vec3* RAYKIT_RESTRICT rn = rest_normals.data();
    vec3* RAYKIT_RESTRICT op = out_positions.data();
    vec3* RAYKIT_RESTRICT on = out_normals.data();
    parallel_for(n, threads, [&](std::size_t v) {
        const std::uint32_t b = off[v], count = off[v + 1] - b;
        if (count == 0) {
            op[v] = rp[v];
            if (normals) on[v] = rn[v];
            return;
        }
        float a[12];
        detail::skin_blend(links + b, count, mats, a);
        const vec3 p = rp[v];
        op[v] = vec3(a[0] * p.x + a[1] * p.y + a[2] * p.z + a[3], a[4] * p.x + a[5] * p.y + a[6] * p.z + a[7],
                     a[8] * p.x + a[9] * p.y + a[10] * p.z + a[11]);
        if (normals) {
            const vec3 nn = rn[v];
            const vec3 t(a[0] * nn.x + a[1] * nn.y + a[2] * nn.z, a[4] * nn.x + a[5] * nn.y + a[6] * nn.z,
                         a[8] * nn.x + a[9] * nn.y + a[10] * nn.z);
            const float len2 = t.x * t.x + t.y * t.y + t.z * t.z;
            on[v] = len2 > 0.0f ? t * (1.0f / std::sqrt(len2)) : vec3(0.0f);
        }
    });
}

inline std::vector<vec3> skin_positions(const PackedSkin& skin, std::span<const SkinMatrix> matrices,
                                        std::span<const vec3> rest_positions, unsigned threads = 0) {
    std::vector<vec3> out(rest_positions.size());
    skin_vertices(skin, matrices, rest_positions, {}, out, {}, threads);
    return out;
}

}  // namespace raykit
