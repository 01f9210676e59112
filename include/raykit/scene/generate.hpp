// raykit/scene/generate.hpp — procedural meshes for tests, benchmarks, demos.
//
// All generators are deterministic (seeded) and the closed ones share vertices
// between neighbouring triangles, so they are watertight: every ray that
// enters the surface's inside must hit a triangle.
//
// Sizes are checked against what 32-bit vertex indices can number (torus
// nv <= 46340, icosphere level <= 13, soup n <= 1,431,655,765): beyond that
// std::length_error / std::invalid_argument, where the torus once wrapped to
// an empty mesh for 2^64 - 1. These are representability limits, not
// memory ones: level 13 is 1.3e9 triangles; callers bound memory themselves.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <random>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <utility>

#include "raykit/scene/mesh.hpp"

namespace raykit {

/// A closed torus (major radius R, minor r) with a bumpy surface, about
/// `target_triangles` triangles (2·nu·nv, nu = 2·nv). `bumps` scales the
/// displacement (0 = smooth torus). Normals are not generated.
inline Mesh make_bumpy_torus(std::size_t target_triangles, float bumps = 0.15f, float R = 1.0f, float r = 0.4f) {
    const double nvd = std::max(3.0, std::round(std::sqrt(double(target_triangles) / 4.0)));
    if (nvd > 46340.0)  // nu·nv = 2·nv² vertices must fit 32-bit indices
        throw std::length_error("make_bumpy_torus: " + std::to_string(target_triangles) +
                                " triangles needs more vertices than 32-bit indices can number (at most 8589767760 triangles)");
    const auto nv = static_cast<std::uint32_t>(nvd);
    const std::uint32_t nu = 2 * nv;
    Mesh m;
    m.positions.reserve(std::size_t(nu) * nv);
    constexpr float kTau = 6.28318530717958647692f;
    for (std::uint32_t i = 0; i < nu; ++i) {
        const float u = kTau * float(i) / float(nu);
        for (std::uint32_t j = 0; j < nv; ++j) {
            const float v = kTau * float(j) / float(nv);
            const float rr = r * (1.0f + bumps * std::sin(7.0f * u) * std::sin(5.0f * v) +
                                  0.3f * bumps * std::sin(23.0f * u + 3.0f * v));
            m.positions.push_back({(R + rr * std::cos(v)) * std::cos(u), (R + rr * std::cos(v)) * std::sin(u),
                                   rr * std::sin(v)});
        }
    }
    m.triangles.reserve(2 * std::size_t(nu) * nv);
    for (std::uint32_t i = 0; i < nu; ++i)
        for (std::uint32_t j = 0; j < nv; ++j) {
            const std::uint32_t a = i * nv + j, b = ((i + 1) % nu) * nv + j, c = ((i + 1) % nu) * nv + (j + 1) % nv,
                                d = i * nv + (j + 1) % nv;
            m.triangles.push_back({{a, b, c}});
            m.triangles.push_back({{a, c, d}});
        }
    m.material_ids.assign(m.triangles.size(), kNoMaterial);
    return m;
}

/// Deepest icosphere subdivision whose 10·4^l + 2 vertices and 20·4^l triangles fit 32-bit indices.
inline constexpr int kMaxIcosphereLevel = 13;

/// The deepest level (0..kMaxIcosphereLevel) with at most `triangles` triangles (0 when even 20 is too many).
inline int icosphere_level_for(std::size_t triangles) noexcept {
    int level = 0;
    while (level < kMaxIcosphereLevel && (std::uint64_t(20) << (2 * (level + 1))) <= triangles) ++level;
    return level;
}

/// A closed icosphere of radius 1 subdivided `levels` times (20·4^levels triangles), levels in
/// 0..kMaxIcosphereLevel (else std::invalid_argument).
inline Mesh make_icosphere(int levels) {
    if (levels < 0 || levels > kMaxIcosphereLevel)
        throw std::invalid_argument("make_icosphere: levels must be in 0.." + std::to_string(kMaxIcosphereLevel) +
                                    ", not " + std::to_string(levels));
    Mesh m;
    const float t = (1.0f + std::sqrt(5.0f)) / 2.0f;
    m.positions = {{-1, t, 0}, {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                   {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
    for (vec3& p : m.positions) p = glm::normalize(p);
    m.triangles = {{{0, 11, 5}}, {{0, 5, 1}},  {{0, 1, 7}},   {{0, 7, 10}}, {{0, 10, 11}},
                   {{1, 5, 9}},  {{5, 11, 4}}, {{11, 10, 2}}, {{10, 7, 6}}, {{7, 1, 8}},
                   {{3, 9, 4}},  {{3, 4, 2}},  {{3, 2, 6}},   {{3, 6, 8}},  {{3, 8, 9}},
                   {{4, 9, 5}},  {{2, 4, 11}}, {{6, 2, 10}},  {{8, 6, 7}},  {{9, 8, 1}}};
    for (int l = 0; l < levels; ++l) {
        std::vector<Triangle> next;
        next.reserve(m.triangles.size() * 4);
        std::unordered_map<std::uint64_t, std::uint32_t> mid;
        mid.reserve(m.triangles.size() * 2);
        auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
            const std::uint64_t key = (std::uint64_t(std::min(a, b)) << 32) | std::max(a, b);
            auto [it, fresh] = mid.try_emplace(key, static_cast<std::uint32_t>(m.positions.size()));
            if (fresh) m.positions.push_back(glm::normalize(m.positions[a] + m.positions[b]));
            return it->second;
        };
        for (const Triangle& tr : m.triangles) {
            const std::uint32_t a = midpoint(tr.v[0], tr.v[1]), b = midpoint(tr.v[1], tr.v[2]),
                                c = midpoint(tr.v[2], tr.v[0]);
            next.push_back({{tr.v[0], a, c}});
            next.push_back({{tr.v[1], b, a}});
            next.push_back({{tr.v[2], c, b}});
            next.push_back({{a, b, c}});
        }
        m.triangles = std::move(next);
    }
    m.material_ids.assign(m.triangles.size(), kNoMaterial);
    return m;
}

/// `n` random triangles in the unit cube with edge lengths up to `size`
/// (a "soup": overlapping, unconnected).
inline Mesh make_random_soup(std::size_t n, std::uint64_t seed, float size = 0.1f) {
    if (n > 0xFFFFFFFFu / 3)  // 3·n vertices must fit 32-bit indices
        throw std::length_error("make_random_soup: " + std::to_string(n) +
                                " triangles is more than 32-bit indices can number (at most 1431655765)");
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> U(0.0f, 1.0f), S(-size, size);
    Mesh m;
    for (std::size_t i = 0; i < n; ++i) {
        const vec3 c(U(rng), U(rng), U(rng));
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        for (int k = 0; k < 3; ++k) m.positions.push_back(c + vec3(S(rng), S(rng), S(rng)));
        m.triangles.push_back({{base, base + 1, base + 2}});
    }
    m.material_ids.assign(m.triangles.size(), kNoMaterial);
    return m;
}

/// Applies p -> p·scale + offset to every position.
inline void transform_positions(Mesh& m, float scale, const vec3& offset) {
    for (vec3& p : m.positions) p = p * scale + offset;
}

}  // namespace raykit
