// raykit/bvh/sortaxis.hpp — bottom-up "sort by axis" fast builder (the
// thesis's second method).
//
//   Bvh bvh = SortAxisBuilder::build(prim_boxes, prim_centers);    // Morton, mutual, area, W = 2
//   SortAxisBuilder::Config thesis;                                 // the thesis's configuration:
//   thesis.axis = SortAxisBuilder::Config::Axis::x;
//   thesis.pairing = SortAxisBuilder::Config::Pairing::greedy;
//   thesis.metric = SortAxisBuilder::Config::Metric::centre;
//   thesis.window = 6;
//
// Level by level until one element is left (level 0 = the primitives):
//   1. sort the level's elements by their centre along Config::axis:
//        Axis::x       the x coordinate (thesis),
//        Axis::longest the coordinate of the longest axis of the
//                      primitives' centroid bounds,
//        Axis::morton  the 30-bit Morton code of the centres (a 3-D
//                      generalisation of "along an axis"; the grid is
//                      fitted to the primitives' centroids);
//      (a stable sort: ties keep the previous level's order);
//   2. cut the sorted list into chunks of 2048 to 4095 elements (the
//      boundaries depend only on the element count, so the tree does not
//      depend on the thread count) and pair each chunk, the chunks on
//      separate threads, by one of two rules:
//        Pairing::greedy (thesis): walk the chunk in order; the first
//          unpaired element pairs with the nearest of the next `window`
//          unpaired elements (ties: the earlier one) and both are removed.
//          Every element is paired on every level (a chunk's last one, if
//          any, is carried to the next level unchanged).
//        Pairing::mutual: every element finds its nearest among the
//          `window` elements on each side of it in the chunk; two elements
//          that are each other's nearest pair, every other element waits,
//          unchanged, for the next level (ties are broken by a rank of the
//          pair, so a chunk always has a mutual pair and equal distances pair
//          neighbours two by two). A level of more than 256 elements where
//          fewer than 1/16 are paired (chains: each element nearest to the
//          next) pairs greedily instead, so the level count stays O(log n);
//          none of the measured scenes ever needs it.
//      Distances: Metric::centre, between centres (a node's centre is the
//      centre of its box; thesis), or Metric::area, the surface area of the
//      merged box (the agglomerative-clustering metric).
//   The next level keeps the chunks' order: new nodes and carried elements,
//   a new node where its first child was; the sort of step 1 then only has to
//   place the new nodes (carried elements keep their keys and order). It is
//   an insertion sort of the next level's elements themselves, per chunk while
//   pairing and then across the chunks, so the next level is ready in sorted
//   order; only where it would move more than four elements per element does
//   a radix sort of (key, position) words and a gather take over (no measured
//   mesh needs it). Each level used to be written unsorted, its new nodes'
//   keys sorted and merged with the carried ones', and the level gathered
//   through the merged keys: paired builds in one process (medians of 6-20),
//   together with the back end's prefetches, now run 1.21x as fast on the 1M
//   torus on two threads, 1.18x on one, 1.27x / 1.20x on the 100k torus, the
//   same trees (hashed: 576 settings x meshes x 1-3 threads, and 96 inputs
//   whose boxes lie far from their centroids, the radix sort's case).
// The merge tree then goes through the shared back end (bvh/bottom_up.hpp):
// the optional post-pass of bvh/optimize.hpp (off by default here), the depth
// bound (a long run of mutual levels could pass RAYKIT_BVH_MAX_DEPTH; any
// such subtree is rebuilt with median splits), SAH leaf merge
// (Config::leaf) and the pre-order
// output. Degenerate or NaN primitives are handled as in the other builders:
// non-finite centroids move to the centre of the finite ones.
//
// Quality. SAH cost relative to BinnedSahBuilder (same leaf size and cost
// constants), Stanford bunny / thesis scene / bumpy torus 100k / 1M:
//   greedy, x, centre (thesis), W 6:   28.8 / 3.59 / 28.2 / 205
//   greedy, Morton, centre, W 6:        3.37 / 3.94 / 2.99 / 3.86
//   greedy, Morton, centre, W 64:       2.51 / 3.05 / 2.23 / 2.96
//   mutual, Morton, centre, W 2:        1.14 / 1.07 / 1.12 / 1.13
//   mutual, Morton, area, W 1:          1.16 / 1.01 / 1.13 / 1.14
//   mutual, Morton, area, W 2:          1.10 / 0.79 / 1.09 / 1.09  (default)
//   mutual, Morton, area, W 4:          1.10 / 0.75 / 1.08 / 1.10
// Forcing every element into a pair on every level is what costs the
// thesis's rule its quality: a dense, even mesh then gets a balanced tree
// whose upper boxes overlap. Letting elements without a mutual partner wait
// keeps the sort, the window and the chunked parallel pairing, and builds
// about as fast (the waiting elements add levels, but the sort of a level
// only places the new nodes). Against Embree's Morton (LOW) build, set on
// the scene and the geometry both, the default builds 0.34-0.79x as many
// triangles per second on two threads on the same four meshes (README: the
// 1M torus 0.68-0.79x, the smaller meshes 0.34-0.71x, after the neighbour
// search in SIMD (nearest, area_rows; 1.11-1.18x in paired builds); 0.29-0.67x
// before it, 0.30-0.38x before the level sort above; an earlier 1.4-2.0x timed
// a MEDIUM build by mistake). W = 2 on each
// side is the best measured trade: W = 1 is 5-22 % faster but loses 4-5 %,
// W = 4 gains under 1 % on the meshes for 5-19 % more time.
#pragma once

#include <algorithm>
#include <bit>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <type_traits>
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

struct SortAxisBuilder {
    struct Config {
        enum class Axis {
            x,        ///< sort along x (thesis)
            longest,  ///< along the longest axis of the centroid bounds
            morton,   ///< by 30-bit Morton code of the centres
        };
        enum class Metric {
            centre,  ///< distance between centres (thesis)
            area,    ///< surface area of the merged box
        };
        enum class Pairing {
            greedy,  ///< every element pairs with the nearest of the next W unpaired ones (thesis)
            mutual,  ///< only mutual nearest neighbours within W on each side pair; the rest wait a level
        };
        unsigned window = 2;                ///< W: candidates looked at per element, per side for mutual (1..4096; thesis: 6)
        Axis axis = Axis::morton;           ///< (thesis: x; see Quality above)
        Metric metric = Metric::area;       ///< (thesis: centre)
        Pairing pairing = Pairing::mutual;  ///< (thesis: greedy; see Quality above)
        LeafCost leaf;                      ///< the back end's leaf merge: max leaf size, Ct, Ci, leaf_block
        unsigned threads = 0;               ///< 0 = all hardware threads; at most kMaxThreads (else std::invalid_argument)
        OptimizeConfig optimize = OptimizeConfig::off();  ///< post-pass (bvh/optimize.hpp)
    };

    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers) {
        return build(boxes, centers, Config{});
    }
    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg) {
        if (boxes.size() != centers.size())
            throw std::invalid_argument("SortAxisBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("SortAxisBuilder: too many primitives");
        check_threads(cfg.threads, "SortAxisBuilder");
        check_leaf_block(cfg.leaf.leaf_block, "SortAxisBuilder");
        if (cfg.window < 1 || cfg.window > 4096)
            throw std::invalid_argument("SortAxisBuilder: window must be in [1, 4096]");
        const unsigned threads = resolve_threads(cfg.threads);
        const bool area = cfg.metric == Config::Metric::area;
        const bool mutual = cfg.pairing == Config::Pairing::mutual;
        const auto n = static_cast<std::uint32_t>(boxes.size());
        // Helper threads for the whole build: a level is a few short passes.
        detail::WorkTeam team(n >= 2 * kChunk ? threads : 1u);
        const detail::SanitizedCenters sc = detail::sanitize_centers(centers, team.size(), &team);
        detail::MergeTree tree;
        tree.prims = n;
        tree.info.reserve(n > 0 ? n - 1 : 0);

        // Sort keys, the same function on every level: the Morton grid and
        // the longest axis come from the primitives' centroid bounds.
        const KeyMaker key{cfg.axis == Config::Axis::morton, cfg.axis == Config::Axis::longest ? max_axis(sc.bounds.extent()) : 0,
                           detail::MortonQuantizer(sc.bounds)};
        const LeafCost& lc = cfg.leaf;
        // The leaf-merge data of each new node are filled in while pairing;
        // they hold when every primitive box is real (finite, non-empty),
        // else finish_bottom_up recomputes them from the real boxes.
        std::vector<std::uint8_t> substituted(std::max(1u, threads), 0);
        Level srt, next;  // this level's elements in sorted order; the next level's, as paired
        detail::RawArray<std::uint32_t> skey, nkey;  // their sort keys
        // Sort words (key << 32 | element index): level 0's, and a level's
        // whose new nodes would move too far for the insertion sort.
        detail::RawArray<std::uint64_t> keys(n), scratch;
        detail::RawArray<std::uint32_t> nn;  // mutual pairing: nearest neighbour (sorted positions)
        team.chunks(n, detail::pass_chunks(n), [&](std::size_t, std::size_t lo, std::size_t hi) {
            for (std::size_t i = lo; i < hi; ++i) keys[i] = key(sc[i], static_cast<std::uint32_t>(i));
        });
        detail::radix_sort_words(keys, 32, 64, team, scratch);
        std::vector<std::uint32_t> chunk_out, chunk_pairs;
        std::size_t m = n;
        bool first = true;  // level 0 reads the primitives directly
        // level 0: the sorted primitives [lo, hi) into srt, in key order (a
        // random gather, so it prefetches ahead); later levels are already
        // in order (step 3)
        auto gather_primitives = [&](std::size_t w, std::size_t lo, std::size_t hi) {
            constexpr std::size_t kAhead = 16;
            bool bad = false;
            for (std::size_t s = lo; s < hi; ++s) {
                if (s + kAhead < hi) {
                    const auto f = static_cast<std::uint32_t>(keys[s + kAhead]);
                    __builtin_prefetch(&boxes[f]);
                    __builtin_prefetch(&sc[f]);
                }
                const auto e = static_cast<std::uint32_t>(keys[s]);
                const AABB& b = boxes[e];
                const bool real = !b.is_empty() && detail::box_is_finite(b);
                bad |= !real;
                srt.e[s] = {real ? b : AABB::of_point(sc[e]), e, detail::primitive_cost(b, lc)};
                if (!area) srt.centre[s] = sc[e];
                skey[s] = static_cast<std::uint32_t>(keys[s] >> 32);
            }
            substituted[w] |= bad;
        };
        srt.resize(n, !area);
        skey.resize(n);
        while (m > 1) {
            // chunks: boundaries depend on m only
            const std::size_t chunks = std::max<std::size_t>(1, m / kChunk);
            auto lo_of = [&](std::size_t c) { return m * c / chunks; };
            const unsigned workers = static_cast<unsigned>(std::min<std::size_t>(threads, chunks));
            chunk_out.assign(chunks + 1, 0);
            chunk_pairs.assign(chunks + 1, 0);
            // 1. level 0: gather the primitives in sorted order; mutual:
            //    nearest neighbours within ±W in the chunk and the chunk's
            //    count of mutual pairs
            if (mutual) nn.resize(m);
            team.chunks(chunks, workers, [&](std::size_t w, std::size_t c0, std::size_t c1) {
                std::vector<float> fwd;
                for (std::size_t c = c0; c < c1; ++c) {
                    const std::size_t lo = lo_of(c), hi = lo_of(c + 1);
                    if (first) gather_primitives(w, lo, hi);
                    if (!mutual) continue;
                    nearest(srt, lo, hi, cfg.window, area, nn, fwd);
                    std::uint32_t pairs = 0;
                    for (std::size_t i = lo; i < hi; ++i) pairs += nn[i] > i && nn[nn[i]] == i;
                    chunk_pairs[c + 1] = pairs;
                    chunk_out[c + 1] = static_cast<std::uint32_t>(hi - lo) - pairs;
                }
            });
            bool greedy = !mutual;
            if (mutual && m > kGreedyFallbackMin) {
                // Too few mutual pairs (ties, chains): this level pairs
                // every element as the thesis does, so a large input
                // never needs more than O(log n) levels.
                std::size_t pairs = 0;
                for (std::size_t c = 0; c < chunks; ++c) pairs += chunk_pairs[c + 1];
                greedy = pairs * kMinMutualShare < m;
            }
            if (greedy) {
                for (std::size_t c = 0; c < chunks; ++c) {
                    const std::size_t len = lo_of(c + 1) - lo_of(c);
                    chunk_out[c + 1] = static_cast<std::uint32_t>((len + 1) / 2);
                    chunk_pairs[c + 1] = static_cast<std::uint32_t>(len / 2);
                }
            }
            for (std::size_t c = 0; c < chunks; ++c) {
                chunk_out[c + 1] += chunk_out[c];
                chunk_pairs[c + 1] += chunk_pairs[c];
            }
            const auto base = static_cast<std::uint32_t>(tree.size());
            const std::size_t m2 = chunk_out[chunks], new_nodes = chunk_pairs[chunks];
            tree.info.resize(base + new_nodes);
            next.resize(m2, !area);
            nkey.resize(m2);
            // 2. pair the chunks on separate threads, then sort each chunk's
            //    output by key (stable: insertion, as it moves few elements)
            team.chunks(chunks, workers, [&](std::size_t, std::size_t c0, std::size_t c1) {
                for (std::size_t c = c0; c < c1; ++c) {
                    const Out out{n, base + chunk_pairs[c], chunk_out[c], !area, &tree, &next, &nkey, &skey, &key, &lc};
                    if (greedy) pair_greedy(srt, lo_of(c), lo_of(c + 1), cfg.window, area, out);
                    else pair_mutual(srt, lo_of(c), lo_of(c + 1), nn, out);
                    const std::size_t len = chunk_out[c + 1] - chunk_out[c];
                    insertion_sort(next, nkey, chunk_out[c], chunk_out[c + 1], !area, 4 * len + 64);
                }
            });
            tree.close_batch();
            // 3. the next level in key order, ties in element order (a stable
            //    sort): the carried elements keep their keys and order, and a
            //    new node's key is near its first child's, so an insertion
            //    sort across the chunks finishes it; where it would move too
            //    many, a radix sort of (key, position) words and a gather.
            if (!insertion_sort(next, nkey, 0, m2, !area, 4 * m2 + 64)) {
                keys.resize(m2);
                team.chunks(m2, detail::pass_chunks(m2), [&](std::size_t, std::size_t lo, std::size_t hi) {
                    for (std::size_t i = lo; i < hi; ++i) keys[i] = std::uint64_t(nkey[i]) << 32 | i;
                });
                detail::radix_sort_words(keys, 32, 64, team, scratch);
                srt.resize(m2, !area);
                skey.resize(m2);
                team.chunks(m2, detail::pass_chunks(m2), [&](std::size_t, std::size_t lo, std::size_t hi) {
                    for (std::size_t s = lo; s < hi; ++s) {
                        const auto e = static_cast<std::uint32_t>(keys[s]);
                        srt.e[s] = next.e[e];
                        if (!area) srt.centre[s] = next.centre[e];
                        skey[s] = nkey[e];
                    }
                });
            } else {
                std::swap(srt, next);
                skey.swap(nkey);
            }
            first = false;
            m = m2;
        }
        tree.root = n <= 1 ? 0 : srt.e[0].node;
        tree.info_ready = std::find(substituted.begin(), substituted.end(), 1) == substituted.end();
        detail::optimize_merge_tree(tree, boxes, sc.view, lc, cfg.optimize, team.size(), &team);
        Bvh bvh = detail::finish_bottom_up(tree, boxes, sc.view, lc, team.size(), &team);
        return bvh;
    }

    /// A level's chunks: max(1, m / kChunk) of them (the device twin, cl/device_build.hpp, uses
    /// these three constants too).
    static constexpr std::size_t kChunk = 2048;
    /// Pairing::mutual: a level of more than kGreedyFallbackMin elements
    /// with fewer than 1 / kMinMutualShare of them in mutual pairs pairs
    /// greedily instead (only ever seen on ties and chains; none of the
    /// measured scenes has one).
    static constexpr std::size_t kMinMutualShare = 16;
    static constexpr std::size_t kGreedyFallbackMin = 256;

private:

    /// One element of a level: its working box, node id and leaf-merge
    /// data, kept together so a gather moves one record.
    struct Elem {
        AABB box;
        std::uint32_t node;
        detail::SubtreeCost sub;
    };
    struct Level {
        detail::RawArray<Elem> e;
        detail::RawArray<vec3> centre;  // Metric::centre only
        void resize(std::size_t m, bool centres) {
            e.resize(m);
            if (centres) centre.resize(m);
        }
    };

    /// Stable insertion sort of L's elements [lo, hi) by key, moving at most `budget` of them;
    /// returns false when it would move more. Each step swaps strictly inverted neighbours
    /// only, so a sort cut short leaves equal keys in their first order.
    static bool insertion_sort(Level& L, detail::RawArray<std::uint32_t>& key, std::size_t lo, std::size_t hi,
                               bool centres, std::size_t budget) {
        for (std::size_t i = lo + 1; i < hi; ++i) {
            const std::uint32_t k = key[i];
            if (key[i - 1] <= k) continue;
            const Elem e = L.e[i];
            const vec3 c = centres ? L.centre[i] : vec3(0.0f);
            std::size_t j = i;
            do {
                if (budget-- == 0) {  // put back what is held: the range stays a permutation
                    key[j] = k;
                    L.e[j] = e;
                    if (centres) L.centre[j] = c;
                    return false;
                }
                key[j] = key[j - 1];
                L.e[j] = L.e[j - 1];
                if (centres) L.centre[j] = L.centre[j - 1];
                --j;
            } while (j > lo && key[j - 1] > k);
            key[j] = k;
            L.e[j] = e;
            if (centres) L.centre[j] = c;
        }
        return true;
    }

    struct KeyMaker {
        bool morton;
        int axis;
        detail::MortonQuantizer mq;
        std::uint32_t operator()(const vec3& c) const noexcept {
            return morton ? mq.code30(c) : detail::orderable_bits(c[axis]);
        }
        std::uint64_t operator()(const vec3& c, std::uint32_t element) const noexcept {
            return std::uint64_t((*this)(c)) << 32 | element;
        }
    };

    /// Half the surface area of a ∪ b (fused_proof_half_area: the device builder's twin computes
    /// the same float).
    static float area_dist(const AABB& a, const AABB& b) noexcept {
        const float ex = detail::clamp_extent(std::max(a.max.x, b.max.x) - std::min(a.min.x, b.min.x));
        const float ey = detail::clamp_extent(std::max(a.max.y, b.max.y) - std::min(a.min.y, b.min.y));
        const float ez = detail::clamp_extent(std::max(a.max.z, b.max.z) - std::min(a.min.z, b.min.z));
        return fused_proof_half_area(ex, ey, ez);
    }
    /// Squared distance between centres.
    static float centre_dist(const vec3& a, const vec3& b) noexcept {
        const vec3 d = a - b;
        return d.x * d.x + d.y * d.y + d.z * d.z;
    }
    static float dist(const Level& L, std::size_t i, std::size_t j, bool area) noexcept {
        return area ? area_dist(L.e[i].box, L.e[j].box) : centre_dist(L.centre[i], L.centre[j]);
    }

    /// Where a chunk's results go: new node p is tree->info[first_pair + p];
    /// next-level element t is level[first_out + t], with its sort key in
    /// level_key (a carried element keeps its key).
    struct Out {
        std::uint32_t n, first_pair, first_out;
        bool centres;
        detail::MergeTree* tree;
        Level* level;
        detail::RawArray<std::uint32_t>* level_key;
        const detail::RawArray<std::uint32_t>* sorted_key;  // this level's, in sorted order
        const KeyMaker* key;
        const LeafCost* lc;

        /// Carries S[k] (sorted position k) as element t.
        void carry(const Level& S, std::size_t k, std::uint32_t t) const {
            const std::uint32_t o = first_out + t;
            level->e[o] = S.e[k];
            if (centres) level->centre[o] = S.centre[k];
            (*level_key)[o] = (*sorted_key)[k];
        }
        /// Makes the node over S[a], S[b] new node p and element t.
        void pair(const Level& S, std::size_t a, std::size_t b, std::uint32_t p, std::uint32_t t) const {
            const Elem& ea = S.e[a];
            const Elem& eb = S.e[b];
            const AABB box = merge(ea.box, eb.box);
            const std::uint32_t id = first_pair + p;
            const detail::SubtreeCost sub = detail::node_cost(box, ea.sub, eb.sub, *lc);
            detail::MergeInfo& in = tree->info[id];
            in.box = box;
            in.kid[0] = ea.node;
            in.kid[1] = eb.node;
            in.sub = sub;
            const std::uint32_t o = first_out + t;
            const vec3 c = detail::box_centre(box);
            level->e[o] = {box, n + id, sub};
            if (centres) level->centre[o] = c;
            (*level_key)[o] = (*key)(c);
        }
    };

    /// nn[i] for i in [lo, hi): the nearest of S[i−W … i+W] within the
    /// chunk (nn[i] = i when i is alone). Each distance is computed once, for
    /// both ends: fwd[k−1][i − lo] = dist(i, i + k). Ties are broken by a
    /// key of the pair alone — the smaller offset |i − j|, then the pair
    /// whose lower position is even (relative to the chunk), then the lower
    /// position — so every pair has one rank for both ends, the chunk's
    /// best-ranked pair is always mutual, and equal distances (identical
    /// triangles, regular grids) pair up neighbours two by two.
    static void nearest(const Level& S, std::size_t lo, std::size_t hi, unsigned window, bool area,
                        detail::RawArray<std::uint32_t>& nn, std::vector<float>& fwd) {
        const std::size_t len = hi - lo, W = std::min<std::size_t>(window, len > 0 ? len - 1 : 0);
        if (W == 0) {
            for (std::size_t i = lo; i < hi; ++i) nn[i] = static_cast<std::uint32_t>(i);
            return;
        }
        fwd.resize(W * len + (area ? 6 * len : 0));
        if (area) {
            area_rows(S, lo, len, W, fwd.data(), fwd.data() + W * len);
        } else {
            for (std::size_t k = 1; k <= W; ++k) {
                float* f = fwd.data() + (k - 1) * len;
                for (std::size_t i = lo; i + k < hi; ++i) f[i - lo] = centre_dist(S.centre[i], S.centre[i + k]);
            }
        }
        // Candidate c (0 .. 2W−1, in position order: i−W … i−1, i+1 … i+W)
        // ranks by the 64-bit key  bits(d) << 32 | (2k + parity) << 13 | c:
        // distances are ≥ +0, so their bits order like them; the minimum
        // key is the nearest, ties broken as above.
        auto key_of = [&](float d, std::size_t k, std::size_t lower, std::size_t c) {
            return std::uint64_t(std::bit_cast<std::uint32_t>(d)) << 32 |
                   std::uint64_t(2 * k + ((lower - lo) & 1)) << 13 | c;
        };
        // the general case (chunk ends, any W)
        auto pick = [&](std::size_t i) {
            const std::size_t r = i - lo;
            std::uint64_t best = ~std::uint64_t(0);
            for (std::size_t k = std::min(W, r); k >= 1; --k)
                best = std::min(best, key_of(fwd[(k - 1) * len + r - k], k, i - k, W - k));
            for (std::size_t k = 1; k <= W && r + k < len; ++k)
                best = std::min(best, key_of(fwd[(k - 1) * len + r], k, i, W - 1 + k));
            const std::size_t c = best & 0x1FFF;
            nn[i] = static_cast<std::uint32_t>(c < W ? i - W + c : i - W + c + 1);
        };
        // interior elements with a small window: the same, unrolled
        auto interior = [&]<std::size_t K>(std::integral_constant<std::size_t, K>) {
            // four elements at a time: a key as two 32-bit lanes, the distance's bits and the
            // rest, compared in that order (the 64-bit key's order; distances are >= +0, so their
            // bits order like them as signed integers too); the keys are distinct, so the
            // minimum does not depend on the order they are taken in
            typedef std::int32_t vi __attribute__((vector_size(16)));
            const vi lane = {0, 1, 2, 3};
            std::size_t i = lo + K;
            for (; i + 3 + K < hi; i += 4) {
                const std::size_t r = i - lo;
                vi bd{}, bs{};
                const auto take = [&](const float* d, std::size_t k, std::size_t lower, std::size_t c) RAYKIT_LAMBDA_INLINE {
                    vi dv;
                    __builtin_memcpy(&dv, d, sizeof(vi));
                    const vi sv = (std::int32_t(2 * k) + ((std::int32_t(lower & 1) + lane) & 1)) << 13 | std::int32_t(c);
                    if (c == 0) {
                        bd = dv;
                        bs = sv;
                    } else {
                        const vi lt = (dv < bd) | ((dv == bd) & (sv < bs));
                        bd = lt ? dv : bd;
                        bs = lt ? sv : bs;
                    }
                };
                for (std::size_t k = K; k >= 1; --k) take(fwd.data() + (k - 1) * len + r - k, k, r - k, K - k);
                for (std::size_t k = 1; k <= K; ++k) take(fwd.data() + (k - 1) * len + r, k, r, K - 1 + k);
                const vi c = bs & 0x1FFF;
                const vi out = (std::int32_t(i - K) + lane) + c - (c >= std::int32_t(K));  // true is -1
                __builtin_memcpy(&nn[i], &out, sizeof(vi));
            }
            for (; i + K < hi; ++i) {
                const std::size_t r = i - lo;
                // the 2K keys (all distinct) reduced pairwise: a shorter chain of minima
                std::uint64_t cand[2 * K];
                for (std::size_t k = K; k >= 1; --k) cand[K - k] = key_of(fwd[(k - 1) * len + r - k], k, i - k, K - k);
                for (std::size_t k = 1; k <= K; ++k) cand[K - 1 + k] = key_of(fwd[(k - 1) * len + r], k, i, K - 1 + k);
                for (std::size_t left = 2 * K; left > 1; left = (left + 1) / 2)
                    for (std::size_t q = 0; q < left / 2; ++q) cand[q] = std::min(cand[q], cand[q + (left + 1) / 2]);
                const std::uint64_t best = cand[0];
                const std::size_t c = best & 0x1FFF;
                nn[i] = static_cast<std::uint32_t>(c < K ? i - K + c : i - K + c + 1);
            }
        };
        if (W <= 4 && len > 2 * W) {
            for (std::size_t i = lo; i < lo + W; ++i) pick(i);
            switch (W) {
                case 1: interior(std::integral_constant<std::size_t, 1>{}); break;
                case 2: interior(std::integral_constant<std::size_t, 2>{}); break;
                case 3: interior(std::integral_constant<std::size_t, 3>{}); break;
                default: interior(std::integral_constant<std::size_t, 4>{}); break;
            }
            for (std::size_t i = hi - W; i < hi; ++i) pick(i);
        } else {
            for (std::size_t i = lo; i < hi; ++i) pick(i);
        }
    }

    /// nearest()'s distance rows for Metric::area: fwd[(k−1)·len + r] = area_dist(S[lo + r],
    /// S[lo + r + k]) for k = 1..W, four pairs at a time (detail::merged_half_areas4, the same
    /// floats), from the chunk's boxes copied into six coordinate rows at `soa` (6·len floats).
    static void area_rows(const Level& S, std::size_t lo, std::size_t len, std::size_t W, float* fwd, float* soa) {
        float* c[6];
        for (std::size_t a = 0; a < 6; ++a) c[a] = soa + a * len;
        for (std::size_t r = 0; r < len; ++r) {
            const AABB& b = S.e[lo + r].box;
            c[0][r] = b.min.x;
            c[1][r] = b.min.y;
            c[2][r] = b.min.z;
            c[3][r] = b.max.x;
            c[4][r] = b.max.y;
            c[5][r] = b.max.z;
        }
        const float* const rows_lo[3] = {c[0], c[1], c[2]};
        const float* const rows_hi[3] = {c[3], c[4], c[5]};
        for (std::size_t k = 1; k <= W; ++k) {
            float* f = fwd + (k - 1) * len;
            const std::size_t pairs = len - k;
            std::size_t r = 0;
            for (; r + 4 <= pairs; r += 4) detail::merged_half_areas4(rows_lo, rows_hi, r, k, f + r);
            for (; r < pairs; ++r) f[r] = area_dist(S.e[lo + r].box, S.e[lo + r + k].box);
        }
    }

    /// Mutual pairing of one sorted chunk: i and nn[i] merge when each is
    /// the other's nearest; the others are carried to the next level. The
    /// next level keeps the chunk's order (a new node at its first child).
    static void pair_mutual(const Level& S, std::size_t lo, std::size_t hi, const detail::RawArray<std::uint32_t>& nn,
                            const Out& out) {
        std::uint32_t p = 0, t = 0;
        for (std::size_t i = lo; i < hi; ++i) {
            const std::uint32_t j = nn[i];
            if (j == i || nn[j] != i) {
                out.carry(S, i, t++);
            } else if (i < j) {
                out.pair(S, i, j, p++, t++);
            }
        }
    }

    /// The thesis's greedy windowed pairing of one sorted chunk S[lo, hi):
    /// the first unpaired element pairs with the nearest of the next W
    /// unpaired ones (ties: the earlier), until at most one is left, which
    /// is carried.
    static void pair_greedy(const Level& S, std::size_t lo, std::size_t hi, unsigned window, bool area,
                            const Out& out) {
        std::vector<std::uint32_t> win(window + 1);
        std::size_t wn = 0, p = lo;
        std::uint32_t t = 0;
        for (;;) {
            while (wn < win.size() && p < hi) win[wn++] = static_cast<std::uint32_t>(p++);
            if (wn == 0) break;
            const std::uint32_t k = win[0];
            if (wn == 1) {  // the chunk's last element: carried over
                out.carry(S, k, t);
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
            out.pair(S, k, win[best], t, t);
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
