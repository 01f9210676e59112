// raykit/bvh/ploc.hpp — PLOC: parallel locally-ordered clustering
// (after Meister & Bittner, "Parallel Locally-Ordered Clustering for
// Bounding Volume Hierarchy Construction", IEEE TVCG 2018).
//
//   Bvh bvh = PlocBuilder::build(prim_boxes, prim_centers);               // radius 4, post-pass on
//   PlocBuilder::Config c;
//   c.optimize = OptimizeConfig::off();                                     // plain PLOC
//   Bvh fast = PlocBuilder::build(prim_boxes, prim_centers, c);
//
// The primitives are sorted once by the 63-bit Morton code of their centres
// (ties by index). Then, while more than one cluster is left:
//   1. every cluster i finds its nearest neighbour among clusters
//      i−R … i+R of the current array (R = Config::radius): the one whose
//      merged box has the least surface area, ties to the lower index;
//   2. every pair of mutual nearest neighbours i < j is merged into a new
//      node that takes i's place; j's place is dropped;
//   3. the array is compacted, keeping its order.
// Ties going to the lower index make the smallest (area, index) edge always
// mutual, so every iteration merges at least one pair. Steps 1–3 run in
// chunks on all threads; new nodes are numbered in array order, so the tree
// does not depend on the thread count. Once an iteration merges only a few
// pairs (chains, coincident clusters), the rest runs incrementally on one
// thread with the same result: only clusters near a merge search again, so
// chain-like inputs do not cost O(n·R) per merged pair.
//
// The merge tree then goes through the post-pass of bvh/optimize.hpp
// (Config::optimize: reinsertion of the largest subtrees, then treelet
// restructuring). Plain PLOC's trees cost 1.08-1.10x binned SAH's on the
// bunny and the bumpy tori (0.75x on the thesis scene); with the default
// pass 1.043-1.045x (0.73x), at 3-4x plain PLOC's build time (1.2-1.3x
// binned SAH's, two threads; 4-5x since step 1 runs in SIMD, nearest(): plain
// PLOC 1.56-1.74x faster in paired builds, the same trees).
//
// Merging can chain (one cluster absorbing singletons iteration after
// iteration), so the merge tree may be deep: the shared back end
// (bvh/bottom_up.hpp) rebuilds any subtree that would pass
// RAYKIT_BVH_MAX_DEPTH with median splits, merges subtrees into leaves by
// the SAH (Config::leaf) and writes the
// pre-order layout. NaN or degenerate primitives: as in the other builders,
// non-finite centroids move to the centre of the finite ones.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/bottom_up.hpp"
#include "raykit/bvh/morton.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/optimize.hpp"
#include "raykit/bvh/sanitize.hpp"
#include "raykit/util/parallel.hpp"
#include "raykit/util/radix_sort.hpp"
#include "raykit/util/raw_array.hpp"

namespace raykit {

struct PlocBuilder {
    struct Config {
        /// R: neighbours searched on each side (1..1024). Measured SAH cost
        /// relative to binned SAH without the post-pass (bumpy torus 100k /
        /// 1M, Stanford bunny, thesis scene): R 4: 1.08 / 1.10 / 1.10 / 0.75,
        /// R 8: 1.09 / 1.10 / 1.09 / 0.74, R 16: 1.10 / 1.12 / 1.10 / 0.79,
        /// R 32: 1.13 / 1.13 / 1.10 / 0.78 (a wider search makes the greedy
        /// clustering worse here); with the post-pass R 4 stays ahead, and
        /// time grows with R, so 4.
        unsigned radius = 4;
        LeafCost leaf;                   ///< the back end's leaf merge: max leaf size, Ct, Ci, leaf_block
        unsigned threads = 0;            ///< 0 = all hardware threads; at most kMaxThreads (else std::invalid_argument)
        OptimizeConfig optimize{};       ///< post-pass (bvh/optimize.hpp); OptimizeConfig::off() for plain PLOC
    };

    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers) {
        return build(boxes, centers, Config{});
    }
    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg) {
        if (boxes.size() != centers.size())
            throw std::invalid_argument("PlocBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("PlocBuilder: too many primitives");
        check_threads(cfg.threads, "PlocBuilder");
        check_leaf_block(cfg.leaf.leaf_block, "PlocBuilder");
        if (cfg.radius < 1 || cfg.radius > 1024) throw std::invalid_argument("PlocBuilder: radius must be in [1, 1024]");
        const unsigned threads = resolve_threads(cfg.threads);
        const auto n = static_cast<std::uint32_t>(boxes.size());
        // Helper threads for the whole build: an iteration is a few short passes.
        detail::WorkTeam team(n >= detail::kMinParallelPass ? threads : 1u);
        const detail::SanitizedCenters sc = detail::sanitize_centers(centers, team.size(), &team);
        detail::MergeTree tree;
        tree.prims = n;
        tree.info.reserve(n > 0 ? n - 1 : 0);

        auto par_for = [&](std::size_t m, auto&& fn) {
            team.chunks(m, detail::team_chunks(m, team.size()),
                        [&](std::size_t, std::size_t lo, std::size_t hi) {
                            for (std::size_t i = lo; i < hi; ++i) fn(i);
                        });
        };
        // Morton order
        detail::RawArray<std::uint32_t> order(n);
        {
            const detail::MortonQuantizer mq(sc.bounds);
            detail::RawArray<std::uint64_t> keys(n);
            par_for(n, [&](std::size_t i) {
                keys[i] = mq(sc[i]);
                order[i] = static_cast<std::uint32_t>(i);
            });
            detail::radix_sort(keys, order, 63, team);
        }
        Clusters cur, next;
        cur.resize(n);
        par_for(n, [&](std::size_t s) {
            const std::uint32_t p = order[s];
            cur.set(s, detail::working_box(boxes[p], sc[p]), p);
        });
        order = detail::RawArray<std::uint32_t>();

        const std::size_t R = cfg.radius;
        detail::RawArray<std::uint32_t> nn, nn_next, remap;
        std::vector<std::uint32_t> merges, keeps;  // per chunk, then exclusive prefix sums
        while (cur.size() > 1) {
            const std::size_t m = cur.size();
            const std::size_t chunks = detail::team_chunks(m, team.size());
            nn.resize(m);
            // 1. nearest neighbours
            team.chunks(m, chunks, [&](std::size_t, std::size_t lo, std::size_t hi) {
                nearest(cur, lo, hi, R, nn);
            });
            // 2. count merges and survivors per chunk
            merges.assign(chunks + 1, 0);
            keeps.assign(chunks + 1, 0);
            team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
                std::uint32_t mg = 0, kp = 0;
                for (std::size_t i = lo; i < hi; ++i) {
                    const std::uint32_t j = nn[i];
                    const bool mutual = nn[j] == i;
                    mg += mutual && i < j;
                    kp += !(mutual && j < i);
                }
                merges[c + 1] = mg;
                keeps[c + 1] = kp;
            });
            for (std::size_t c = 0; c < chunks; ++c) {
                merges[c + 1] += merges[c];
                keeps[c + 1] += keeps[c];
            }
            // 3. merge and compact; remap[i] = i's new index (for a dropped
            //    cluster: the index of the next survivor)
            const auto base = static_cast<std::uint32_t>(tree.size());
            tree.info.resize(base + merges[chunks]);
            next.resize(keeps[chunks]);
            remap.resize(m);
            team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
                std::uint32_t mg = merges[c], kp = keeps[c];
                for (std::size_t i = lo; i < hi; ++i) {
                    const std::uint32_t j = nn[i];
                    const bool mutual = nn[j] == i;
                    remap[i] = kp;
                    if (mutual && j < i) continue;
                    if (mutual) {
                        tree.set(base + mg, cur.node[i], cur.node[j]);
                        next.set(kp++, merge(cur.box(i), cur.box(j)), n + base + mg);
                        ++mg;
                    } else {
                        next.copy(kp++, cur, i);
                    }
                }
            });
            tree.close_batch();
            // 4. Few merges (chains, coincident clusters): hand over to the
            //    incremental phase, which searches again only where windows
            //    changed. Clusters farther than R from every merged or
            //    dropped cluster see the same window as before (same clusters,
            //    same order), so they keep their neighbour, renumbered.
            const std::size_t m2 = keeps[chunks];
            if (m2 > 1 && 2 * std::size_t(merges[chunks]) * (2 * R + 2) < m2) {
                std::vector<std::uint8_t> dirty(m2, 0);
                for (std::size_t i = 0; i < m; ++i) {
                    if (nn[nn[i]] != i) continue;
                    const std::size_t p = remap[i];
                    const std::size_t lo = p > R ? p - R - 1 : 0, hi = std::min(m2, p + R + 1);
                    for (std::size_t k = lo; k < hi; ++k) dirty[k] = 1;
                }
                nn_next.resize(m2);
                for (std::size_t i = 0; i < m; ++i) {
                    const std::uint32_t j = nn[i];
                    if (!(nn[j] == i && j < i)) nn_next[remap[i]] = remap[j];
                }
                std::swap(cur, next);
                incremental_phase(cur, nn_next, dirty, tree, R);
                break;
            }
            std::swap(cur, next);
        }
        tree.root = n > 0 ? cur.node[0] : 0;  // merges keep the lower position: 0 survives
        const LeafCost& lc = cfg.leaf;
        detail::optimize_merge_tree(tree, boxes, sc.view, lc, cfg.optimize, team.size(), &team);
        return detail::finish_bottom_up(tree, boxes, sc.view, lc, team.size(), &team);
    }

private:
    /// Cluster array, boxes as six float arrays (the neighbour search runs
    /// over contiguous floats and vectorises).
    struct Clusters {
        detail::RawArray<float> lx, ly, lz, hx, hy, hz;
        detail::RawArray<std::uint32_t> node;
        std::size_t size() const noexcept { return node.size(); }
        void resize(std::size_t m) {
            for (auto* v : {&lx, &ly, &lz, &hx, &hy, &hz}) v->resize(m);
            node.resize(m);
        }
        void set(std::size_t i, const AABB& b, std::uint32_t id) noexcept {
            lx[i] = b.min.x, ly[i] = b.min.y, lz[i] = b.min.z;
            hx[i] = b.max.x, hy[i] = b.max.y, hz[i] = b.max.z;
            node[i] = id;
        }
        void copy(std::size_t i, const Clusters& o, std::size_t j) noexcept {
            lx[i] = o.lx[j], ly[i] = o.ly[j], lz[i] = o.lz[j];
            hx[i] = o.hx[j], hy[i] = o.hy[j], hz[i] = o.hz[j];
            node[i] = o.node[j];
        }
        AABB box(std::size_t i) const noexcept { return {{lx[i], ly[i], lz[i]}, {hx[i], hy[i], hz[i]}}; }
    };

    /// d[j] = half area of a ∪ box j for the k boxes given as six arrays (fused_proof_half_area:
    /// the device builder computes the same floats).
    static void window_areas(const AABB& a, const float* RAYKIT_RESTRICT plx, const float* RAYKIT_RESTRICT ply,
                             const float* RAYKIT_RESTRICT plz, const float* RAYKIT_RESTRICT phx,
                             const float* RAYKIT_RESTRICT phy, const float* RAYKIT_RESTRICT phz, std::size_t k,
                             float* RAYKIT_RESTRICT d) noexcept {
        const float ax = a.min.x, ay = a.min.y, az = a.min.z, bx = a.max.x, by = a.max.y, bz = a.max.z;
        for (std::size_t j = 0; j < k; ++j) {
            float ex = (phx[j] > bx ? phx[j] : bx) - (plx[j] < ax ? plx[j] : ax);
            float ey = (phy[j] > by ? phy[j] : by) - (ply[j] < ay ? ply[j] : ay);
            float ez = (phz[j] > bz ? phz[j] : bz) - (plz[j] < az ? plz[j] : az);
            ex = ex < detail::kFloatMax ? ex : detail::kFloatMax;
            ey = ey < detail::kFloatMax ? ey : detail::kFloatMax;
            ez = ez < detail::kFloatMax ? ez : detail::kFloatMax;
            d[j] = fused_proof_half_area(ex, ey, ez);
        }
    }

    /// Step 1 for clusters [lo, hi): nn[i] = the first nearest of clusters i − R … i + R, j ≠ i,
    /// by window_areas. Where the window is whole, each pair's area is computed once, for both
    /// ends, four pairs at a time: row k − 1 of `d` holds the area of (p, p + k), window_areas'
    /// float for the window of p (the merged box's corners are selects, so the window of p + k
    /// can differ only in the sign of a zero extent, which leaves the sum of the three products
    /// the same float: it is −0 only if all three products are −0, and no three signs make
    /// that). Then four clusters take their first nearest at once, the candidates in window
    /// order with a strict `<`, as argmin_except does. Scalar, each pair was computed twice, once
    /// per end, and the search was 40 % of a plain PLOC build (100k torus, 2 threads, perf).
    static void nearest(const Clusters& c, std::size_t lo, std::size_t hi, std::size_t R,
                        detail::RawArray<std::uint32_t>& nn) {
        const std::size_t m = c.size();
        std::vector<float> w(2 * R + 1);  // one cluster's window
        const auto one = [&](std::size_t i) {
            const std::size_t b = i >= R ? i - R : 0, e = std::min(m, i + R + 1);
            window_areas(c.box(i), c.lx.data() + b, c.ly.data() + b, c.lz.data() + b, c.hx.data() + b,
                         c.hy.data() + b, c.hz.data() + b, e - b, w.data());
            nn[i] = static_cast<std::uint32_t>(b + argmin_except(w.data(), e - b, i - b));
        };
        // clusters [vlo, vhi) have whole windows; a window over 64 keeps the scalar path (the
        // rows below take R floats per cluster)
        constexpr std::size_t kLanes = 4;
        const std::size_t vlo = std::max(lo, R), vhi = std::min(hi, m > R ? m - R : 0);
        if (R > 64 || vhi < vlo + 2 * kLanes) {
            for (std::size_t i = lo; i < hi; ++i) one(i);
            return;
        }
        // vectors stay local to this function (no vector parameters or returns: -Wpsabi)
        typedef float vf __attribute__((vector_size(16)));
        typedef std::int32_t vi __attribute__((vector_size(16)));
        const std::size_t base = vlo - R, len = vhi - base;  // pairs (p, p + k), p in [base, vhi)
        std::vector<float> d(R * len);
        const float* const rows_lo[3] = {c.lx.data(), c.ly.data(), c.lz.data()};
        const float* const rows_hi[3] = {c.hx.data(), c.hy.data(), c.hz.data()};
        for (std::size_t k = 1; k <= R; ++k) {
            float* f = d.data() + (k - 1) * len;
            std::size_t p = base;
            // window_areas' float for p's window: its a is p's box, its candidate p + k's
            for (; p + kLanes <= vhi; p += kLanes) detail::merged_half_areas4(rows_lo, rows_hi, p, k, f + (p - base));
            for (; p < vhi; ++p) {
                window_areas(c.box(p), c.lx.data() + p + k, c.ly.data() + p + k, c.lz.data() + p + k,
                             c.hx.data() + p + k, c.hy.data() + p + k, c.hz.data() + p + k, 1, f + (p - base));
            }
        }
        for (std::size_t i = lo; i < vlo; ++i) one(i);
        const vi lane = {0, 1, 2, 3};
        std::size_t i = vlo;
        for (; i + kLanes <= vhi; i += kLanes) {
            // window order: i − R … i − 1 (pair (j, i): row i − j − 1 at j), then i + 1 … i + R
            vf bd;
            __builtin_memcpy(&bd, d.data() + (R - 1) * len + (i - R - base), sizeof(vf));
            vi bj = std::int32_t(i - R) + lane;
            for (std::size_t k = R - 1; k >= 1; --k) {
                vf dv;
                __builtin_memcpy(&dv, d.data() + (k - 1) * len + (i - k - base), sizeof(vf));
                const vi jv = std::int32_t(i - k) + lane;
                const vi lt = dv < bd;
                bd = lt ? dv : bd;
                bj = lt ? jv : bj;
            }
            for (std::size_t k = 1; k <= R; ++k) {
                vf dv;
                __builtin_memcpy(&dv, d.data() + (k - 1) * len + (i - base), sizeof(vf));
                const vi jv = std::int32_t(i + k) + lane;
                const vi lt = dv < bd;
                bd = lt ? dv : bd;
                bj = lt ? jv : bj;
            }
            __builtin_memcpy(&nn[i], &bj, sizeof(vi));
        }
        for (; i < hi; ++i) one(i);
    }

    /// Index of the first smallest d[j], j ≠ self (k ≥ 2).
    static std::size_t argmin_except(float* d, std::size_t k, std::size_t self) noexcept {
        d[self] = kInf;
        std::size_t best = self == 0 ? 1 : 0;
        for (std::size_t j = 0; j < k; ++j)
            if (d[j] < d[best]) best = j;
        return best;
    }

    /// The rest of the clustering once merges have become rare, with the
    /// same result as more rounds of steps 1–3: the clusters stay at fixed
    /// positions in a doubly linked list (a merge keeps the lower position,
    /// the other is unlinked), a window is R linked neighbours on each side,
    /// and only clusters whose window changed search again. A round costs
    /// O(changes·R) instead of O(clusters·R).
    static void incremental_phase(Clusters& c, detail::RawArray<std::uint32_t>& nn, const std::vector<std::uint8_t>& dirty0,
                                  detail::MergeTree& tree, std::size_t R) {
        constexpr std::uint32_t kNone = 0xFFFFFFFFu;
        const auto m = static_cast<std::uint32_t>(c.size());
        std::vector<std::uint32_t> prev(m), next(m), stamp(m, 0), dirty, win;
        std::vector<std::uint8_t> dead(m, 0);
        for (std::uint32_t i = 0; i < m; ++i) {
            prev[i] = i == 0 ? kNone : i - 1;
            next[i] = i + 1 == m ? kNone : i + 1;
            if (dirty0[i]) dirty.push_back(i);
        }
        std::vector<float> lx, ly, lz, hx, hy, hz, d;
        std::vector<std::array<std::uint32_t, 2>> pairs;
        std::uint32_t live = m, round = 0;
        while (live > 1) {
            // 1. nearest neighbours of the clusters whose window changed
            for (const std::uint32_t i : dirty) {
                win.clear();
                std::uint32_t p = prev[i];
                for (std::size_t k = 0; k < R && p != kNone; ++k, p = prev[p]) win.push_back(p);
                std::reverse(win.begin(), win.end());
                const std::size_t self = win.size();
                win.push_back(i);
                p = next[i];
                for (std::size_t k = 0; k < R && p != kNone; ++k, p = next[p]) win.push_back(p);
                const std::size_t k = win.size();
                for (auto* v : {&lx, &ly, &lz, &hx, &hy, &hz, &d}) v->resize(k);
                for (std::size_t t = 0; t < k; ++t) {
                    const std::uint32_t w = win[t];
                    lx[t] = c.lx[w], ly[t] = c.ly[w], lz[t] = c.lz[w];
                    hx[t] = c.hx[w], hy[t] = c.hy[w], hz[t] = c.hz[w];
                }
                window_areas(c.box(i), lx.data(), ly.data(), lz.data(), hx.data(), hy.data(), hz.data(), k, d.data());
                nn[i] = win[argmin_except(d.data(), k, self)];
            }
            // 2. new mutual pairs have a changed cluster on at least one side
            pairs.clear();
            for (const std::uint32_t i : dirty) {
                const std::uint32_t j = nn[i];
                if (nn[j] == i) pairs.push_back({std::min(i, j), std::max(i, j)});
            }
            std::sort(pairs.begin(), pairs.end());
            pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
            // 3. merge in position order (the node numbering of step 3)
            for (const auto [a, b] : pairs) {
                const std::uint32_t id = tree.add(c.node[a], c.node[b]);
                c.set(a, merge(c.box(a), c.box(b)), id);
                if (prev[b] != kNone) next[prev[b]] = next[b];
                if (next[b] != kNone) prev[next[b]] = prev[b];
                dead[b] = 1;
                --live;
            }
            tree.close_batch();
            // 4. clusters within R + 1 links of a merged or dropped one
            ++round;
            dirty.clear();
            auto mark = [&](std::uint32_t x) {
                if (stamp[x] != round) {
                    stamp[x] = round;
                    dirty.push_back(x);
                }
            };
            auto around = [&](std::uint32_t lo_start, std::uint32_t hi_start) {
                std::uint32_t p = lo_start;
                for (std::size_t k = 0; k <= R + 1 && p != kNone; ++k, p = prev[p]) mark(p);
                p = hi_start;
                for (std::size_t k = 0; k <= R + 1 && p != kNone; ++k, p = next[p]) mark(p);
            };
            for (const auto [a, b] : pairs) {
                around(a, a);
                // b's stale links lead to live clusters (links of a dropped
                // cluster pointed at clusters alive when it was dropped)
                std::uint32_t l = prev[b], r = next[b];
                while (l != kNone && dead[l]) l = prev[l];
                while (r != kNone && dead[r]) r = next[r];
                around(l, r);
            }
        }
    }
};

}  // namespace raykit
