// raykit/bvh/ploc.hpp — PLOC: parallel locally-ordered clustering
// (after Meister & Bittner, "Parallel Locally-Ordered Clustering for
// Bounding Volume Hierarchy Construction", IEEE TVCG 2018).
//
//   Bvh bvh = PlocBuilder::build(prim_boxes, prim_centers);              // radius 16
//   Bvh bvh = PlocBuilder::build(prim_boxes, prim_centers, {.radius = 8});
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
// does not depend on the thread count.
//
// Merging can chain (one cluster absorbing singletons iteration after
// iteration), so the merge tree may be deep: the shared back end
// (bvh/collapse.hpp) rebuilds any subtree that would pass
// RAYKIT_BVH_MAX_DEPTH with median splits, collapses subtrees into leaves by
// the SAH (max_leaf_size, traversal_cost, intersection_cost) and writes the
// pre-order layout. NaN or degenerate primitives: as in the other builders,
// non-finite centroids move to the centre of the finite ones.
#pragma once

#include <algorithm>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/collapse.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct PlocBuilder {
    struct Config {
        unsigned radius = 16;            ///< R: neighbours searched on each side (1..1024)
        unsigned max_leaf_size = 8;      ///< leaf collapse: larger subtrees stay split (0 acts as 1)
        float traversal_cost = 1.0f;     ///< Ct for the leaf collapse
        float intersection_cost = 1.0f;  ///< Ci for the leaf collapse
        unsigned threads = 0;            ///< 0 = all hardware threads
    };

    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers) {
        return build(boxes, centers, Config{});
    }
    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg) {
        if (boxes.size() != centers.size())
            throw std::invalid_argument("PlocBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("PlocBuilder: too many primitives");
        if (cfg.radius < 1 || cfg.radius > 1024) throw std::invalid_argument("PlocBuilder: radius must be in [1, 1024]");
        const unsigned threads = resolve_threads(cfg.threads);
        const auto n = static_cast<std::uint32_t>(boxes.size());
        const std::vector<vec3> sc = detail::sanitize_centers(centers, threads);
        detail::MergeTree tree;
        tree.prims = n;
        tree.kids.reserve(n > 0 ? n - 1 : 0);

        // Morton order
        std::vector<std::uint32_t> order(n);
        {
            const detail::MortonQuantizer mq(detail::finite_point_bounds(sc, threads));
            std::vector<std::uint64_t> keys(n);
            parallel_for(n, threads, [&](std::size_t i) {
                keys[i] = mq(sc[i]);
                order[i] = static_cast<std::uint32_t>(i);
            });
            detail::radix_sort(keys, order, 63, threads);
        }
        Clusters cur, next;
        cur.resize(n);
        parallel_for(n, threads, [&](std::size_t s) {
            const std::uint32_t p = order[s];
            cur.set(s, detail::working_box(boxes[p], sc[p]), p);
        });
        order = {};

        const std::size_t R = cfg.radius;
        std::vector<std::uint32_t> nn;
        std::vector<std::uint32_t> merges, keeps;  // per chunk, then exclusive prefix sums
        while (cur.size() > 1) {
            const std::size_t m = cur.size();
            const std::size_t chunks = detail::pass_chunks(m);
            nn.resize(m);
            // 1. nearest neighbours
            parallel_chunks(m, chunks, threads, [&](std::size_t, std::size_t lo, std::size_t hi) {
                std::vector<float> d(2 * R + 1);
                for (std::size_t i = lo; i < hi; ++i) {
                    const std::size_t b = i >= R ? i - R : 0, e = std::min(m, i + R + 1);
                    cur.areas_with(i, b, e, d.data());
                    d[i - b] = kInf;
                    std::size_t best = i == b ? 1 : 0;
                    for (std::size_t j = 0; j < e - b; ++j)
                        if (d[j] < d[best]) best = j;
                    nn[i] = static_cast<std::uint32_t>(b + best);
                }
            });
            // 2. count merges and survivors per chunk
            merges.assign(chunks + 1, 0);
            keeps.assign(chunks + 1, 0);
            parallel_chunks(m, chunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
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
            // 3. merge and compact
            const auto base = static_cast<std::uint32_t>(tree.kids.size());
            tree.kids.resize(base + merges[chunks]);
            next.resize(keeps[chunks]);
            parallel_chunks(m, chunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
                std::uint32_t mg = merges[c], kp = keeps[c];
                for (std::size_t i = lo; i < hi; ++i) {
                    const std::uint32_t j = nn[i];
                    const bool mutual = nn[j] == i;
                    if (mutual && j < i) continue;
                    if (mutual) {
                        tree.kids[base + mg] = {cur.node[i], cur.node[j]};
                        next.set(kp++, merge(cur.box(i), cur.box(j)), n + base + mg);
                        ++mg;
                    } else {
                        next.copy(kp++, cur, i);
                    }
                }
            });
            tree.close_batch();
            std::swap(cur, next);
        }
        tree.root = n > 0 ? cur.node[0] : 0;
        const LeafCollapseConfig lc{cfg.max_leaf_size, cfg.traversal_cost, cfg.intersection_cost};
        return detail::finish_bottom_up(tree, boxes, sc, lc, threads);
    }

private:
    /// Cluster array, boxes as six float arrays (the neighbour search runs
    /// over contiguous floats and vectorises).
    struct Clusters {
        std::vector<float> lx, ly, lz, hx, hy, hz;
        std::vector<std::uint32_t> node;
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
        /// d[j - b] = half area of box(i) ∪ box(j) for j in [b, e).
        void areas_with(std::size_t i, std::size_t b, std::size_t e, float* RAYKIT_RESTRICT d) const noexcept {
            const float ax = lx[i], ay = ly[i], az = lz[i], bx = hx[i], by = hy[i], bz = hz[i];
            const float* RAYKIT_RESTRICT plx = lx.data() + b;
            const float* RAYKIT_RESTRICT ply = ly.data() + b;
            const float* RAYKIT_RESTRICT plz = lz.data() + b;
            const float* RAYKIT_RESTRICT phx = hx.data() + b;
            const float* RAYKIT_RESTRICT phy = hy.data() + b;
            const float* RAYKIT_RESTRICT phz = hz.data() + b;
            const std::size_t k = e - b;
            for (std::size_t j = 0; j < k; ++j) {
                float ex = (phx[j] > bx ? phx[j] : bx) - (plx[j] < ax ? plx[j] : ax);
                float ey = (phy[j] > by ? phy[j] : by) - (ply[j] < ay ? ply[j] : ay);
                float ez = (phz[j] > bz ? phz[j] : bz) - (plz[j] < az ? plz[j] : az);
                ex = ex < detail::kFloatMax ? ex : detail::kFloatMax;
                ey = ey < detail::kFloatMax ? ey : detail::kFloatMax;
                ez = ez < detail::kFloatMax ? ez : detail::kFloatMax;
                d[j] = ex * ey + ey * ez + ez * ex;
            }
        }
    };
};

}  // namespace raykit
