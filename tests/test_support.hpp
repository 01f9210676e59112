// Helpers shared by raykit's test programs (not part of the library).
#pragma once

#include <cstdint>
#include <random>
#include <vector>

#include "raykit.hpp"

namespace raykit::test {

/// Random rays over a mesh: origins in its box grown by 50 %, directions
/// uniform; half of the rays aimed at a triangle vertex or edge midpoint (the
/// hard cases for a triangle test). Deterministic for a seed.
inline std::vector<Ray> random_rays(const Mesh& m, std::size_t n, std::uint64_t seed) {
    AABB box;
    for (const vec3& p : m.positions)
        if (is_finite(p)) box.grow(p);
    if (box.is_empty()) box = {vec3(-1), vec3(1)};
    const vec3 c = box.center(), e = box.extent() * 0.75f + vec3(1e-3f);
    std::mt19937_64 rng(seed);
    std::uniform_real_distribution<float> U(-1.0f, 1.0f);
    std::vector<Ray> rays(n);
    for (std::size_t i = 0; i < n; ++i) {
        Ray& r = rays[i];
        r.org = c + vec3(U(rng), U(rng), U(rng)) * e;
        if (i % 2 && !m.triangles.empty()) {
            const Triangle& t = m.triangles[rng() % m.triangles.size()];
            const vec3 a = m.positions[t.v[0]], b = m.positions[t.v[1]];
            r.dir = (i % 4 == 1 ? a : (a + b) * 0.5f) - r.org;
        } else {
            r.dir = vec3(U(rng), U(rng), U(rng));
        }
    }
    return rays;
}

}  // namespace raykit::test
