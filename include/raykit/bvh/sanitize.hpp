// raykit/bvh/sanitize.hpp — the centroids and boxes the builders reason with
// when the input is not finite.
//
// A mesh may hold NaN or infinite vertices (a broken export, a skinning bug),
// and an empty box has min > max. Sorting, Morton codes and nearest-neighbour
// distances must never see those, or orders stop being orders and the builders
// loop or crash. So every builder (BinnedSahBuilder included) works with
// sanitized centroids (a non-finite one sits at the centre of the finite ones)
// and "working" boxes (a primitive's own box when it is finite and non-empty,
// else the point box at its sanitized centroid). These are used for decisions
// only: the output boxes are always the real ones.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

#include "raykit/math/aabb.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit::detail {

inline constexpr float kFloatMax = std::numeric_limits<float>::max();

/// Bounds of a set of points (finite ones only) and whether any was not
/// finite. Exact for any chunking. On `team` when a build has one.
inline AABB finite_point_bounds(std::span<const vec3> pts, unsigned threads, bool* any_bad = nullptr,
                                WorkTeam* team = nullptr) {
    const std::size_t chunks = pass_chunks(pts.size());
    std::vector<AABB> part(chunks);
    std::vector<std::uint8_t> bad(chunks, 0);
    run_chunks(team, threads, pts.size(), chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
        AABB b;
        bool nb = false;
        for (std::size_t i = lo; i < hi; ++i) {
            if (is_finite(pts[i])) b.grow(pts[i]);
            else nb = true;
        }
        part[c] = b;
        bad[c] = nb;
    });
    AABB all;
    for (const AABB& b : part) all.grow(b);
    if (any_bad) *any_bad = std::find(bad.begin(), bad.end(), 1) != bad.end();
    return all;
}

/// The centroids a builder works with: the caller's, or, when some are not
/// finite (NaN triangles), a copy where those sit at the centre of the
/// finite ones, so that binning, sorting, Morton codes and distances never see a NaN.
struct SanitizedCenters {
    std::vector<vec3> copy;       ///< used only when an input centroid was not finite
    std::span<const vec3> view;   ///< the centroids to use
    AABB bounds;                  ///< bounds of the finite input centroids (empty if none)
    const vec3& operator[](std::size_t i) const noexcept { return view[i]; }
    std::size_t size() const noexcept { return view.size(); }
};

/// SanitizedCenters of `centers`: the same for any thread count (finite_point_bounds is exact).
inline SanitizedCenters sanitize_centers(std::span<const vec3> centers, unsigned threads, WorkTeam* team = nullptr) {
    SanitizedCenters s;
    bool bad = false;
    s.bounds = finite_point_bounds(centers, threads, &bad, team);
    s.view = centers;
    if (bad) {
        s.copy.assign(centers.begin(), centers.end());
        const vec3 fill = s.bounds.is_empty() ? vec3(0.0f) : s.bounds.center();
        parallel_for(
            s.copy.size(), threads, [&](std::size_t i) {
                if (!is_finite(s.copy[i])) s.copy[i] = fill;
            },
            kMinParallelPass);
        s.view = s.copy;
        if (s.bounds.is_empty()) s.bounds = AABB::of_point(fill);
    }
    return s;
}

inline bool box_is_finite(const AABB& b) noexcept { return is_finite(b.min) && is_finite(b.max); }

/// The box a builder reasons with: the primitive's own box when it is
/// finite and non-empty, else the point box at its (sanitized) centroid.
inline AABB working_box(const AABB& b, const vec3& sanitized_center) noexcept {
    return (!b.is_empty() && box_is_finite(b)) ? b : AABB::of_point(sanitized_center);
}

/// Centre of a finite box without overflow.
inline vec3 box_centre(const AABB& b) noexcept { return b.min * 0.5f + b.max * 0.5f; }

/// Clamp of a non-negative float difference that overflowed.
inline float clamp_extent(float e) noexcept { return e < kFloatMax ? e : kFloatMax; }

/// The bottom-up builders' neighbour distance four pairs at a time: out[l] = the half area
/// (fused_proof_half_area, bvh/sah.hpp) of the merged box of boxes p + l and p + k + l, each
/// extent clamped (clamp_extent), for l = 0..3, the boxes given as coordinate rows lo[axis][i],
/// hi[axis][i]. Each lane takes the scalar steps (the corners by std::max / std::min's selects,
/// the clamp, the products summed in double), so every distance is the scalar one bit for bit.
/// Sort by axis (area_rows) and PLOC (nearest) search with it; one pair at a time, those
/// distances were half of sort by axis's search and most of PLOC's. GCC's vector extensions:
/// SSE2 vectors in a plain -O2 build.
inline void merged_half_areas4(const float* const lo[3], const float* const hi[3], std::size_t p, std::size_t k,
                               float* out) noexcept {
    // vectors stay local (no vector parameters or returns: -Wpsabi)
    typedef float vf __attribute__((vector_size(16)));
    typedef double vd __attribute__((vector_size(32)));
    const vf big = vf{} + kFloatMax;
    vf e[3];
    for (std::size_t a = 0; a < 3; ++a) {
        vf l0, l1, h0, h1;
        __builtin_memcpy(&l0, lo[a] + p, sizeof(vf));
        __builtin_memcpy(&l1, lo[a] + p + k, sizeof(vf));
        __builtin_memcpy(&h0, hi[a] + p, sizeof(vf));
        __builtin_memcpy(&h1, hi[a] + p + k, sizeof(vf));
        const vf d = (h0 < h1 ? h1 : h0) - (l1 < l0 ? l1 : l0);  // std::max(h0, h1) - std::min(l0, l1)
        e[a] = d < big ? d : big;
    }
    const vd x = __builtin_convertvector(e[0], vd), y = __builtin_convertvector(e[1], vd),
             z = __builtin_convertvector(e[2], vd);
    const vf s = __builtin_convertvector((x * y + y * z) + z * x, vf);
    __builtin_memcpy(out, &s, sizeof(vf));
}

}  // namespace raykit::detail
