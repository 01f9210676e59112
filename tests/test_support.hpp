// Helpers shared by raykit's test programs (not part of the library).
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <fstream>
#include <string>
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

/// Camera rays, random rays (mixed octants in every packet), rays with narrowed intervals,
/// axis-parallel and zero-component directions, and rays aimed at vertices: the cases where a
/// packet's lanes disagree with each other.
inline std::vector<Ray> batch_test_rays(const Mesh& m, std::size_t n_random, std::uint64_t seed) {
    AABB box;
    for (const vec3& p : m.positions) box.grow(p);
    std::vector<Ray> rays = random_rays(m, n_random, seed);
    const Camera cam = frame_scene(box, 48, 40);
    for (const Ray& r : camera_rays(cam)) rays.push_back(r);
    const Camera centre = camera_looking_at(box, 33, 17, vec3(0.0f, 0.0f, 1.0f), 30.0f);  // tiles straddle octants
    for (const Ray& r : camera_rays(centre, 0.3f, 0.7f)) rays.push_back(r);
    std::mt19937_64 rng(seed + 1);
    std::uniform_real_distribution<float> U(0.0f, 1.0f);
    const vec3 c = box.center(), e = box.extent();
    for (int i = 0; i < 200; ++i) {
        Ray r;
        r.org = c + (vec3(U(rng), U(rng), U(rng)) - 0.5f) * e * 1.5f;
        const int axis = i % 3;
        r.dir = vec3(0.0f);
        r.dir[axis] = i % 2 ? 1.0f : -1.0f;
        if (i % 5 == 0) r.dir[(axis + 1) % 3] = -0.0f;
        if (i % 7 == 0) {
            r.tmin = 0.25f * e[axis];
            r.tmax = 0.75f * e[axis];
        }
        rays.push_back(r);
    }
    for (std::size_t i = 0; i < rays.size(); i += 13) rays[i].tmax = 0.5f * glm::length(e) / glm::length(rays[i].dir);
    return rays;
}

/// batch_test_rays, then packets whose lanes share an octant but not an origin, so packet walks
/// take them and their frusta are wide: batch_test_rays's random rays again (another seed),
/// sorted by octant, and shadow rays (tmax 1) from triangle centroids to one light outside the
/// mesh's box, 16 triangles of one region a packet.
inline std::vector<Ray> packet_test_rays(const Mesh& m, std::size_t n_random, std::uint64_t seed) {
    std::vector<Ray> rays = batch_test_rays(m, n_random, seed);
    std::vector<Ray> sorted = random_rays(m, n_random, seed + 100);
    const auto octant = [](const Ray& r) {
        return int(std::signbit(r.dir.x)) | int(std::signbit(r.dir.y)) << 1 | int(std::signbit(r.dir.z)) << 2;
    };
    std::stable_sort(sorted.begin(), sorted.end(), [&](const Ray& a, const Ray& b) { return octant(a) < octant(b); });
    rays.insert(rays.end(), sorted.begin(), sorted.end());
    AABB box;
    for (const vec3& p : m.positions) box.grow(p);
    const vec3 light = box.center() + box.extent() * vec3(0.9f, 1.3f, 1.7f);
    const std::size_t tris = m.triangles.size();
    std::mt19937_64 rng(seed + 200);
    for (std::size_t k = 0; k < 64 && tris > 0; ++k) {
        const std::size_t first = rng() % tris;
        for (std::size_t j = 0; j < 16; ++j) {
            const Triangle& t = m.triangles[(first + j * 7) % tris];
            const vec3 c = (m.positions[t.v[0]] + m.positions[t.v[1]] + m.positions[t.v[2]]) / 3.0f;
            Ray r;
            r.org = c;
            r.dir = light - c;
            r.tmin = 1e-4f;
            r.tmax = 1.0f;
            rays.push_back(r);
        }
    }
    return rays;
}

/// The "VmFlags:" line of the mapping that holds `p` in /proc/self/smaps ("" where there is
/// none, or no smaps): huge-page advice shows there as " hg".
inline std::string vm_flags_of(const void* p) {
    std::ifstream smaps("/proc/self/smaps");
    std::string line, flags;
    bool inside = false;
    const auto at = reinterpret_cast<std::uintptr_t>(p);
    while (std::getline(smaps, line)) {
        unsigned long lo = 0, hi = 0;
        if (std::sscanf(line.c_str(), "%lx-%lx ", &lo, &hi) == 2 && line.find(':') > line.find(' '))
            inside = lo <= at && at < hi;
        else if (inside && line.rfind("VmFlags:", 0) == 0)
            flags = line;
    }
    return flags;
}

/// True where huge-page advice can show: Linux with transparent huge pages, not under
/// AddressSanitizer (whose allocator maps large blocks its own way).
inline bool huge_page_advice_visible() {
#if defined(__SANITIZE_ADDRESS__)
    return false;
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
    return false;
#endif
#endif
#if defined(__linux__)
    return bool(std::ifstream("/sys/kernel/mm/transparent_hugepage/enabled"));
#else
    return false;
#endif
}

}  // namespace raykit::test
