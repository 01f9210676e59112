// raykit/bvh/pairwise.hpp — bottom-up "pairwise nearest" builder (the thesis's
// first method), sub-quadratic.
//
//   Bvh bvh = PairwiseBuilder::build(prim_boxes, prim_centers);
//   Bvh bvh = PairwiseBuilder::build(prim_boxes, prim_centers,
//                                    {.metric = PairwiseBuilder::Config::Metric::area});
//   Bvh ref = PairwiseBuilder::build_reference(prim_boxes, prim_centers);  // O(n²), small inputs
//
// The pairing rule (exactly the thesis's, level by level):
//   The level's elements form a list. Take the first remaining element,
//   find its nearest remaining element, make a node of the pair and remove
//   both; repeat. When only one element is left it is carried to the next
//   level unchanged. The next level's list is the new nodes in the order they
//   were created, followed by the carried element if there is one. Repeat
//   until one element is left: the root. Level 0 is the primitives in the
//   caller's order.
// "Nearest" is the smallest distance under Config::metric, ties going to the
// lower list index:
//   - Metric::centre: Euclidean distance between centres (thesis). Level-0
//     centres are the caller's centroids; a node's centre is the centre of
//     its box.
//   - Metric::area: surface area of the merged box.
// Distances are evaluated so that every rounding is a single, deterministic
// step (float differences, exact double products, a fixed summation order),
// so the fast builder and build_reference() give the same tree bit for bit.
//
// Cost. The greedy pairing is inherently sequential; what makes it fast is
// the search. Per level the elements are sorted by the 63-bit Morton code of
// their centres (parallel radix sort) and a complete binary tree is laid
// over the sorted array (buckets of 8), each node holding the bounds of its
// elements (centres, or boxes for the area metric) and the smallest list
// index still present below it (removal updates the path to the root). A
// query scans its own bucket, then walks up to the root, searching each
// sibling subtree best-first; a subtree is skipped when a conservative lower
// bound of the distance exceeds the best found, or equals it and the
// subtree holds no lower list index. The bounds are evaluated with the same
// roundings as the distances, so they never exceed a distance they bound
// and the search returns exactly the literal rule's answer. For the area
// metric the bound is the area of the query box grown to touch the subtree's
// box (the merged box must reach at least that far on every axis).
// Sorting, the search structure and the next level's boxes are built on all
// threads; the result does not depend on the thread count.
//
// The merge tree then goes through the shared back end (bvh/collapse.hpp):
// SAH leaf collapse into leaves of up to max_leaf_size primitives, the
// RAYKIT_BVH_MAX_DEPTH bound (automatically met: each level halves the
// element count) and pre-order output.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/collapse.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct PairwiseBuilder {
    struct Config {
        enum class Metric {
            centre,  ///< distance between centres (thesis)
            area,    ///< surface area of the merged box
        };
        Metric metric = Metric::centre;
        unsigned max_leaf_size = 8;      ///< leaf collapse: larger subtrees stay split (0 acts as 1)
        float traversal_cost = 1.0f;     ///< Ct for the leaf collapse
        float intersection_cost = 1.0f;  ///< Ci for the leaf collapse
        unsigned threads = 0;            ///< 0 = all hardware threads
    };

    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers) {
        return build(boxes, centers, Config{});
    }
    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg) {
        return run(boxes, centers, cfg, false);
    }
    /// The literal O(n²)-per-level version of the same rule (for tests).
    static Bvh build_reference(std::span<const AABB> boxes, std::span<const vec3> centers) {
        return build_reference(boxes, centers, Config{});
    }
    static Bvh build_reference(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg) {
        return run(boxes, centers, cfg, true);
    }

private:
    static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    static constexpr std::uint32_t kBucket = 8;       // elements per search-tree leaf
    static constexpr std::uint32_t kBruteLevel = 64;  // levels this small pair by brute force

    /// Squared centre distance, rounded the same way wherever it is evaluated.
    static double centre_dist(const vec3& a, const vec3& b) noexcept {
        const double dx = detail::clamp_extent(std::fabs(a.x - b.x));
        const double dy = detail::clamp_extent(std::fabs(a.y - b.y));
        const double dz = detail::clamp_extent(std::fabs(a.z - b.z));
        return (dx * dx + dy * dy) + dz * dz;  // products are exact: fused or not, the same
    }
    static double area_of(float fx, float fy, float fz) noexcept {
        const double ex = detail::clamp_extent(fx), ey = detail::clamp_extent(fy), ez = detail::clamp_extent(fz);
        return (ex * ey + ey * ez) + ez * ex;
    }
    /// Half surface area of the merged box.
    static double merged_area(const AABB& a, const AABB& b) noexcept {
        return area_of(std::max(a.max.x, b.max.x) - std::min(a.min.x, b.min.x),
                       std::max(a.max.y, b.max.y) - std::min(a.min.y, b.min.y),
                       std::max(a.max.z, b.max.z) - std::min(a.min.z, b.min.z));
    }
    /// ≤ centre_dist(q, p) for every p in `b` (same roundings, monotone).
    static double centre_bound(const vec3& q, const AABB& b) noexcept {
        auto gap = [](float lo, float hi, float x) {
            const float g = std::max(lo - x, x - hi);
            return g > 0.0f ? double(detail::clamp_extent(g)) : 0.0;
        };
        const double gx = gap(b.min.x, b.max.x, q.x), gy = gap(b.min.y, b.max.y, q.y),
                     gz = gap(b.min.z, b.max.z, q.z);
        return (gx * gx + gy * gy) + gz * gz;
    }
    /// ≤ merged_area(a, c) for every box c inside `b`.
    static double area_bound(const AABB& a, const AABB& b) noexcept {
        return area_of(std::max(a.max.x, b.min.x) - std::min(a.min.x, b.max.x),
                       std::max(a.max.y, b.min.y) - std::min(a.min.y, b.max.y),
                       std::max(a.max.z, b.min.z) - std::min(a.min.z, b.max.z));
    }

    struct Level {
        std::vector<vec3> centre;
        std::vector<AABB> box;  // working boxes
        std::vector<std::uint32_t> node;
        std::size_t size() const noexcept { return node.size(); }
    };
    struct Pair {
        std::uint32_t a, b;
    };

    static double dist(const Level& L, std::uint32_t i, std::uint32_t j, bool area) noexcept {
        return area ? merged_area(L.box[i], L.box[j]) : centre_dist(L.centre[i], L.centre[j]);
    }

    /// The literal rule: O(m²).
    static std::uint32_t pair_brute(const Level& L, bool area, std::vector<Pair>& pairs) {
        const auto m = static_cast<std::uint32_t>(L.size());
        std::vector<std::uint8_t> alive(m, 1);
        std::uint32_t carried = kNone;
        for (std::uint32_t i = 0; i < m; ++i) {
            if (!alive[i]) continue;
            alive[i] = 0;
            double bd = kInf;
            std::uint32_t bj = kNone;
            for (std::uint32_t j = i + 1; j < m; ++j) {
                if (!alive[j]) continue;
                const double d = dist(L, i, j, area);
                if (d < bd || bj == kNone) {  // j ascends: strict < keeps the lower index on ties
                    bd = d;
                    bj = j;
                }
            }
            if (bj == kNone) {
                carried = i;
            } else {
                alive[bj] = 0;
                pairs.push_back({i, bj});
            }
        }
        return carried;
    }

    /// Search structure over one level (see the header comment).
    struct Index {
        const Level& L;
        bool area;
        std::uint32_t m = 0, P = 1;
        std::vector<std::uint32_t> elem;  // sorted position -> list index
        std::vector<std::uint32_t> pos;   // list index -> sorted position
        std::vector<vec3> pc;             // centres, sorted
        std::vector<AABB> pb;             // boxes, sorted (area metric)
        std::vector<std::uint8_t> alive;  // bit mask per bucket
        std::vector<AABB> nbox;           // heap-ordered tree, root 1, leaves P..2P-1
        std::vector<std::uint32_t> nmin;  // smallest live list index below (kNone: empty)

        Index(const Level& lv, bool use_area, unsigned threads) : L(lv), area(use_area) {
            m = static_cast<std::uint32_t>(L.size());
            const std::uint32_t buckets = (m + kBucket - 1) / kBucket;
            P = std::bit_ceil(std::max(buckets, 1u));
            // Morton sort of the centres
            const detail::MortonQuantizer mq(detail::finite_point_bounds(L.centre, threads));
            std::vector<std::uint64_t> keys(m);
            elem.resize(m);
            parallel_for(m, threads, [&](std::size_t i) {
                keys[i] = mq(L.centre[i]);
                elem[i] = static_cast<std::uint32_t>(i);
            });
            detail::radix_sort(keys, elem, 63, threads);
            keys = {};
            pos.resize(m);
            pc.resize(m);
            if (area) pb.resize(m);
            parallel_for(m, threads, [&](std::size_t s) {
                const std::uint32_t e = elem[s];
                pos[e] = static_cast<std::uint32_t>(s);
                pc[s] = L.centre[e];
                if (area) pb[s] = L.box[e];
            });
            alive.assign(P, 0);
            nbox.assign(2 * std::size_t(P), AABB{});
            nmin.assign(2 * std::size_t(P), kNone);
            parallel_chunks(buckets, detail::pass_chunks(m), threads, [&](std::size_t, std::size_t lo, std::size_t hi) {
                for (std::size_t k = lo; k < hi; ++k) {
                    const std::uint32_t b = static_cast<std::uint32_t>(k) * kBucket;
                    const std::uint32_t e = std::min(b + kBucket, m);
                    AABB bx;
                    std::uint32_t mn = kNone;
                    for (std::uint32_t s = b; s < e; ++s) {
                        if (area) bx.grow(pb[s]);
                        else bx.grow(pc[s]);
                        mn = std::min(mn, elem[s]);
                    }
                    alive[k] = static_cast<std::uint8_t>((1u << (e - b)) - 1u);
                    nbox[P + k] = bx;
                    nmin[P + k] = mn;
                }
            });
            for (std::uint32_t k = P - 1; k >= 1; --k) {
                nbox[k] = merge(nbox[2 * k], nbox[2 * k + 1]);
                nmin[k] = std::min(nmin[2 * k], nmin[2 * k + 1]);
            }
        }

        bool is_alive(std::uint32_t s) const noexcept { return (alive[s / kBucket] >> (s % kBucket)) & 1u; }

        void remove(std::uint32_t s) noexcept {
            const std::uint32_t leaf = s / kBucket;
            const std::uint32_t e = elem[s];
            std::uint32_t mask = alive[leaf] & ~(1u << (s % kBucket));
            alive[leaf] = static_cast<std::uint8_t>(mask);
            std::uint32_t k = P + leaf;
            if (nmin[k] != e) return;
            std::uint32_t mn = kNone;
            for (; mask; mask &= mask - 1) mn = std::min(mn, elem[leaf * kBucket + std::countr_zero(mask)]);
            nmin[k] = mn;
            for (k >>= 1; k >= 1; k >>= 1) {
                const std::uint32_t v = std::min(nmin[2 * k], nmin[2 * k + 1]);
                if (nmin[k] == v) break;
                nmin[k] = v;
            }
        }

        struct Best {
            double d = kInf;
            std::uint32_t e = kNone, s = kNone;
        };

        /// Nearest live element to list element q (already removed).
        Best nearest(std::uint32_t q) const noexcept {
            const vec3 qc = L.centre[q];
            const AABB qb = L.box[q];
            Best best;
            auto bound = [&](std::uint32_t k) { return area ? area_bound(qb, nbox[k]) : centre_bound(qc, nbox[k]); };
            auto skip = [&](double lb, std::uint32_t k) {
                return lb > best.d || (lb == best.d && nmin[k] >= best.e);
            };
            auto scan = [&](std::uint32_t leaf) {
                const std::uint32_t base = leaf * kBucket;
                for (std::uint32_t mask = alive[leaf]; mask; mask &= mask - 1) {
                    const std::uint32_t s = base + std::countr_zero(mask);
                    const double d = area ? merged_area(qb, pb[s]) : centre_dist(qc, pc[s]);
                    const std::uint32_t e = elem[s];
                    if (d < best.d || (d == best.d && e < best.e)) best = {d, e, s};
                }
            };
            struct Entry {
                std::uint32_t k;
                double lb;
            };
            Entry stack[2 * 34];
            auto down = [&](std::uint32_t root, double lb0) {
                int sp = 0;
                stack[sp++] = {root, lb0};
                while (sp > 0) {
                    const Entry en = stack[--sp];
                    if (skip(en.lb, en.k)) continue;
                    if (en.k >= P) {
                        scan(en.k - P);
                        continue;
                    }
                    const std::uint32_t l = 2 * en.k, r = l + 1;
                    const bool hl = nmin[l] != kNone, hr = nmin[r] != kNone;
                    const double bl = hl ? bound(l) : kInf, br = hr ? bound(r) : kInf;
                    // push the farther first so the nearer is searched first
                    if (bl <= br) {
                        if (hr) stack[sp++] = {r, br};
                        if (hl) stack[sp++] = {l, bl};
                    } else {
                        if (hl) stack[sp++] = {l, bl};
                        if (hr) stack[sp++] = {r, br};
                    }
                }
            };
            const std::uint32_t leaf = pos[q] / kBucket;
            scan(leaf);
            for (std::uint32_t k = P + leaf; k > 1; k >>= 1) {
                const std::uint32_t sib = k ^ 1u;
                if (nmin[sib] == kNone) continue;
                const double lb = bound(sib);
                if (!skip(lb, sib)) down(sib, lb);
            }
            return best;
        }
    };

    static std::uint32_t pair_fast(const Level& L, bool area, unsigned threads, std::vector<Pair>& pairs) {
        Index ix(L, area, threads);
        const auto m = static_cast<std::uint32_t>(L.size());
        std::uint32_t carried = kNone;
        for (std::uint32_t i = 0; i < m; ++i) {
            const std::uint32_t s = ix.pos[i];
            if (!ix.is_alive(s)) continue;
            ix.remove(s);
            const Index::Best b = ix.nearest(i);
            if (b.e == kNone) {
                carried = i;
                break;  // nothing else is alive
            }
            ix.remove(b.s);
            pairs.push_back({i, b.e});
        }
        return carried;
    }

    static Bvh run(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg, bool reference) {
        if (boxes.size() != centers.size())
            throw std::invalid_argument("PairwiseBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("PairwiseBuilder: too many primitives");
        const unsigned threads = resolve_threads(cfg.threads);
        const bool area = cfg.metric == Config::Metric::area;
        const auto n = static_cast<std::uint32_t>(boxes.size());
        const std::vector<vec3> sc = detail::sanitize_centers(centers, threads);
        detail::MergeTree tree;
        tree.prims = n;
        tree.kids.reserve(n > 0 ? n - 1 : 0);
        Level cur, next;
        cur.centre = sc;
        cur.box.resize(n);
        cur.node.resize(n);
        parallel_for(n, threads, [&](std::size_t i) {
            cur.box[i] = detail::working_box(boxes[i], sc[i]);
            cur.node[i] = static_cast<std::uint32_t>(i);
        });
        std::vector<Pair> pairs;
        while (cur.size() > 1) {
            pairs.clear();
            const std::uint32_t carried = (reference || cur.size() <= kBruteLevel)
                                              ? pair_brute(cur, area, pairs)
                                              : pair_fast(cur, area, threads, pairs);
            const std::size_t np = pairs.size(), m2 = np + (carried != kNone);
            const auto base = static_cast<std::uint32_t>(tree.kids.size());
            tree.kids.resize(base + np);
            next.centre.resize(m2);
            next.box.resize(m2);
            next.node.resize(m2);
            parallel_for(np, threads, [&](std::size_t t) {
                const Pair p = pairs[t];
                const AABB b = merge(cur.box[p.a], cur.box[p.b]);
                tree.kids[base + t] = {cur.node[p.a], cur.node[p.b]};
                next.box[t] = b;
                next.centre[t] = detail::box_centre(b);
                next.node[t] = n + base + static_cast<std::uint32_t>(t);
            });
            if (carried != kNone) {
                next.centre[np] = cur.centre[carried];
                next.box[np] = cur.box[carried];
                next.node[np] = cur.node[carried];
            }
            tree.close_batch();
            std::swap(cur, next);
        }
        tree.root = n > 0 ? cur.node[0] : 0;
        const LeafCollapseConfig lc{cfg.max_leaf_size, cfg.traversal_cost, cfg.intersection_cost};
        return detail::finish_bottom_up(tree, boxes, sc, lc, threads);
    }
};

}  // namespace raykit
