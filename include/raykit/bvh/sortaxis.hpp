// raykit/bvh/sortaxis.hpp — bottom-up "sort by axis" fast builder (the
// thesis's second method).
//
//   Bvh bvh = SortAxisBuilder::build(prim_boxes, prim_centers);             // Morton, W = 6
//   Bvh bvh = SortAxisBuilder::build(prim_boxes, prim_centers,
//                                    {.window = 6, .axis = SortAxisBuilder::Config::Axis::x});  // thesis
//
// Level by level until one element is left (level 0 = the primitives):
//   1. sort the level's elements by their centre along Config::axis:
//        Axis::x       the x coordinate (thesis),
//        Axis::longest the coordinate of the longest axis of the level's
//                      centre bounds,
//        Axis::morton  the 63-bit Morton code of the centres (a 3-D
//                      generalisation of "along an axis");
//      (stable parallel radix sort: ties keep the previous level's order);
//   2. cut the sorted list into chunks of 8192 to 16383 elements (the
//      boundaries depend only on the element count, so the tree does not
//      depend on the thread count) and, on separate threads, walk each chunk
//      in order: the first unpaired element pairs with the nearest of the
//      next `window` unpaired elements (ties: the earlier one) and both are
//      removed. A chunk's last unpaired element, if any, is carried to the
//      next level unchanged. Distances: Metric::centre, the distance between
//      centres (a node's centre is the centre of its box; thesis), or
//      Metric::area, the surface area of the merged box.
//   The next level is the new nodes, chunk by chunk in the order they were
//   created, each chunk's carried element after its new nodes.
// Every level halves the element count (up to one per chunk), so the height
// stays within about log2(n) + 1 and RAYKIT_BVH_MAX_DEPTH is never at risk.
// The merge tree then goes through the shared back end (bvh/collapse.hpp):
// SAH leaf collapse (max_leaf_size, traversal_cost, intersection_cost) and
// pre-order output. Degenerate or NaN primitives are handled as in the other
// builders: non-finite centroids move to the centre of the finite ones.
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

struct SortAxisBuilder {
    struct Config {
        enum class Axis {
            x,        ///< sort along x (thesis)
            longest,  ///< along the longest axis of each level's centre bounds
            morton,   ///< by 63-bit Morton code of the centres
        };
        enum class Metric {
            centre,  ///< distance between centres (thesis)
            area,    ///< surface area of the merged box
        };
        unsigned window = 6;             ///< W: candidates looked at per element (≥ 1; thesis: 6)
        Axis axis = Axis::morton;
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
        if (boxes.size() != centers.size())
            throw std::invalid_argument("SortAxisBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("SortAxisBuilder: too many primitives");
        if (cfg.window < 1 || cfg.window > 4096)
            throw std::invalid_argument("SortAxisBuilder: window must be in [1, 4096]");
        const unsigned threads = resolve_threads(cfg.threads);
        const bool area = cfg.metric == Config::Metric::area;
        const auto n = static_cast<std::uint32_t>(boxes.size());
        const std::vector<vec3> sc = detail::sanitize_centers(centers, threads);
        detail::MergeTree tree;
        tree.prims = n;
        tree.kids.reserve(n > 0 ? n - 1 : 0);

        Level cur, sorted;
        cur.resize(n);
        parallel_for(n, threads, [&](std::size_t i) {
            cur.box[i] = detail::working_box(boxes[i], sc[i]);
            cur.centre[i] = sc[i];
            cur.node[i] = static_cast<std::uint32_t>(i);
        });
        std::vector<std::uint32_t> order, keys32;
        std::vector<std::uint64_t> keys64;
        std::vector<std::uint32_t> chunk_out, chunk_pairs;
        while (cur.size() > 1) {
            const std::size_t m = cur.size();
            // 1. sort
            order.resize(m);
            if (cfg.axis == Config::Axis::morton) {
                const detail::MortonQuantizer mq(detail::finite_point_bounds(cur.centre, threads));
                keys64.resize(m);
                parallel_for(m, threads, [&](std::size_t i) {
                    keys64[i] = mq(cur.centre[i]);
                    order[i] = static_cast<std::uint32_t>(i);
                });
                detail::radix_sort(keys64, order, 63, threads);
            } else {
                int axis = 0;
                if (cfg.axis == Config::Axis::longest)
                    axis = max_axis(detail::finite_point_bounds(cur.centre, threads).extent());
                keys32.resize(m);
                parallel_for(m, threads, [&](std::size_t i) {
                    keys32[i] = detail::orderable_bits(cur.centre[i][axis]);
                    order[i] = static_cast<std::uint32_t>(i);
                });
                detail::radix_sort(keys32, order, 32, threads);
            }
            sorted.resize(m);
            parallel_for(m, threads, [&](std::size_t s) {
                const std::uint32_t e = order[s];
                sorted.centre[s] = cur.centre[e];
                sorted.box[s] = cur.box[e];
                sorted.node[s] = cur.node[e];
            });
            // 2. chunks and their output slots
            const std::size_t chunks = std::max<std::size_t>(1, m / kChunk);
            chunk_out.assign(chunks + 1, 0);
            chunk_pairs.assign(chunks + 1, 0);
            for (std::size_t c = 0; c < chunks; ++c) {
                const std::size_t len = m * (c + 1) / chunks - m * c / chunks;
                chunk_out[c + 1] = chunk_out[c] + static_cast<std::uint32_t>((len + 1) / 2);
                chunk_pairs[c + 1] = chunk_pairs[c] + static_cast<std::uint32_t>(len / 2);
            }
            const auto base = static_cast<std::uint32_t>(tree.kids.size());
            tree.kids.resize(base + chunk_pairs[chunks]);
            cur.resize(chunk_out[chunks]);
            parallel_chunks(chunks, chunks, threads, [&](std::size_t c, std::size_t, std::size_t) {
                pair_chunk(sorted, m * c / chunks, m * (c + 1) / chunks, cfg.window, area, n, base + chunk_pairs[c],
                           chunk_out[c], tree, cur);
            });
            tree.close_batch();
        }
        tree.root = n > 0 ? cur.node[0] : 0;
        const LeafCollapseConfig lc{cfg.max_leaf_size, cfg.traversal_cost, cfg.intersection_cost};
        return detail::finish_bottom_up(tree, boxes, sc, lc, threads);
    }

private:
    static constexpr std::size_t kChunk = 8192;

    struct Level {
        std::vector<vec3> centre;
        std::vector<AABB> box;  // working boxes
        std::vector<std::uint32_t> node;
        std::size_t size() const noexcept { return node.size(); }
        void resize(std::size_t m) {
            centre.resize(m);
            box.resize(m);
            node.resize(m);
        }
    };

    static float dist(const Level& L, std::uint32_t i, std::uint32_t j, bool area) noexcept {
        if (area) {
            const AABB& a = L.box[i];
            const AABB& b = L.box[j];
            const float ex = detail::clamp_extent(std::max(a.max.x, b.max.x) - std::min(a.min.x, b.min.x));
            const float ey = detail::clamp_extent(std::max(a.max.y, b.max.y) - std::min(a.min.y, b.min.y));
            const float ez = detail::clamp_extent(std::max(a.max.z, b.max.z) - std::min(a.min.z, b.min.z));
            return ex * ey + ey * ez + ez * ex;
        }
        const vec3 d = L.centre[i] - L.centre[j];
        return d.x * d.x + d.y * d.y + d.z * d.z;
    }

    /// Greedy windowed pairing of sorted[lo, hi); writes new nodes from
    /// kids[first_pair] and next-level elements from out[first_out].
    static void pair_chunk(const Level& S, std::size_t lo, std::size_t hi, unsigned window, bool area,
                           std::uint32_t n, std::uint32_t first_pair, std::uint32_t first_out,
                           detail::MergeTree& tree, Level& out) {
        std::vector<std::uint32_t> win(window + 1);
        std::size_t wn = 0, p = lo;
        std::uint32_t t = 0;
        for (;;) {
            while (wn < win.size() && p < hi) win[wn++] = static_cast<std::uint32_t>(p++);
            if (wn == 0) break;
            const std::uint32_t k = win[0];
            if (wn == 1) {  // the chunk's last element: carried over
                const std::uint32_t o = first_out + t;
                out.centre[o] = S.centre[k];
                out.box[o] = S.box[k];
                out.node[o] = S.node[k];
                break;
            }
            std::size_t best = 1;
            float bd = dist(S, k, win[1], area);
            for (std::size_t j = 2; j < wn; ++j) {
                const float d = dist(S, k, win[j], area);
                if (d < bd) {
                    bd = d;
                    best = j;
                }
            }
            const std::uint32_t b = win[best];
            const AABB box = merge(S.box[k], S.box[b]);
            const std::uint32_t id = first_pair + t;
            tree.kids[id] = {S.node[k], S.node[b]};
            const std::uint32_t o = first_out + t;
            out.box[o] = box;
            out.centre[o] = detail::box_centre(box);
            out.node[o] = n + id;
            ++t;
            // drop win[0] and win[best]
            std::size_t w = 0;
            for (std::size_t j = 1; j < wn; ++j)
                if (j != best) win[w++] = win[j];
            wn = w;
        }
    }
};

}  // namespace raykit
