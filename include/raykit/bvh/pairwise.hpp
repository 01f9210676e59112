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
//   - Metric::centre: Euclidean distance between centres (thesis; compared
//     squared). Level-0 centres are the caller's centroids; a node's centre
//     is the centre of its box.
//   - Metric::area: surface area of the merged box.
// Non-finite centroids (NaN triangles) are moved to the centre of the finite
// ones, and empty or non-finite boxes are replaced by the point box at the
// centroid for these decisions; the output boxes are the real ones.
// Distances are evaluated so that every rounding is a single, deterministic
// step (float differences, exact double products, a fixed summation order),
// so the fast builder and build_reference() give the same tree bit for bit.
//
// Cost. The greedy pairing is sequential by its rule; what makes it fast is
// the search. Per level the elements are sorted by the 30-bit Morton code of
// their centres (parallel radix sort) and a binary radix tree is laid over
// the sorted array (a range splits where its highest differing code bit
// changes, i.e. along octree cells, down to leaves of ≤ 16 elements), each
// node holding the bounds of its elements (centres, or boxes for the area
// metric), the smallest list index below it, and whether any element below
// is still present (a removal that empties a node marks its path up to the
// first node that is still not empty). A query scans its own leaf, then walks up
// to the root, searching each sibling subtree best-first; a subtree is
// skipped when it is empty, when a conservative lower bound of the distance
// exceeds the best found, or equals it and the subtree holds no lower list index. The bounds
// are evaluated with the same roundings as the distances, so they never
// exceed a distance they bound, and the search returns exactly the literal
// rule's answer. For the area metric the bound is the area of the query box
// grown to touch the subtree's box (the merged box must reach at least that
// far on every axis).
// Sorting and the per-element passes (keys, gathers, the next level's boxes)
// run on all threads, and so does the pairing itself, by guessing and checking
// (pair_fast); the result does not depend on the thread count.
//
// The merge tree then goes through the shared back end (bvh/bottom_up.hpp):
// SAH leaf merge into leaves of up to leaf.max_leaf_size primitives, the
// RAYKIT_BVH_MAX_DEPTH bound (automatically met: each level halves the
// element count) and pre-order output.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <span>
#include <stdexcept>
#include <utility>
#include <vector>

#include "raykit/bvh/bottom_up.hpp"
#include "raykit/bvh/morton.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sanitize.hpp"
#include "raykit/util/parallel.hpp"
#include "raykit/util/radix_sort.hpp"
#include "raykit/util/raw_array.hpp"

namespace raykit {

struct PairwiseBuilder {
    struct Config {
        enum class Metric {
            centre,  ///< distance between centres (thesis)
            area,    ///< surface area of the merged box
        };
        Metric metric = Metric::centre;
        LeafCost leaf;                   ///< the back end's leaf merge: max leaf size, Ct, Ci, leaf_block
        unsigned threads = 0;            ///< 0 = all hardware threads; at most kMaxThreads (else std::invalid_argument)
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
    static constexpr std::uint32_t kBucket = 16;      // elements per search-tree leaf
    using Mask = std::uint16_t;                       // live elements of a leaf
    static constexpr std::uint32_t kBruteLevel = 64;  // levels this small pair by brute force

    /// Squared centre distance, rounded the same way wherever it is evaluated.
    static double centre_dist(const vec3& a, const vec3& b) noexcept {
        const double dx = std::min(std::fabs(a.x - b.x), detail::kFloatMax);
        const double dy = std::min(std::fabs(a.y - b.y), detail::kFloatMax);
        const double dz = std::min(std::fabs(a.z - b.z), detail::kFloatMax);
        return (dx * dx + dy * dy) + dz * dz;  // products are exact: fused or not, the same
    }
    static double area_of(float fx, float fy, float fz) noexcept {
        const double ex = std::min(fx, detail::kFloatMax), ey = std::min(fy, detail::kFloatMax),
                     ez = std::min(fz, detail::kFloatMax);
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
            // max(·, 0) then the overflow clamp, branch-free (maxss/minss)
            return double(std::min(std::max(std::max(lo - x, x - hi), 0.0f), detail::kFloatMax));
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

    /// Search structure over one level (see the header comment). Aligned: see pair_fast.
    struct alignas(64) Index {
        struct TreeNode {
            AABB box;                 // bounds of the elements below (centres or boxes)
            std::uint32_t kid;        // inner: first child (the second is kid + 1); leaf: first position
            std::uint32_t count;      // 0: inner; leaf: number of positions
            std::uint32_t parent;     // kNone for the root
            std::uint32_t min_elem;   // smallest list index below, live or not
        };
        const Level& L;
        bool area;
        std::uint32_t m = 0;
        std::vector<std::uint32_t> elem;     // sorted position -> list index
        std::vector<std::uint32_t> pos;      // list index -> sorted position
        std::vector<std::uint32_t> leaf_of;  // sorted position -> tree leaf
        std::vector<vec3> pc;                // centres, sorted (centre metric)
        std::vector<AABB> pb;                // boxes, sorted (area metric)
        std::vector<Mask> alive;             // per tree node: a leaf's live positions; inner: 0 once all are gone
                                             // (the level's state: pair_fast plays removals on it and on copies)
        std::vector<TreeNode> tree;          // root 0; siblings side by side

        Index(const Level& lv, bool use_area, unsigned threads) : L(lv), area(use_area) {
            m = static_cast<std::uint32_t>(L.size());
            // Morton sort of the centres (30-bit codes: the order only affects speed)
            const detail::MortonQuantizer mq(detail::finite_point_bounds(L.centre, threads));
            detail::RawArray<std::uint64_t> keys(m), scratch;
            parallel_for(
                m, threads, [&](std::size_t i) { keys[i] = std::uint64_t(mq.code30(L.centre[i])) << 32 | i; },
                detail::kMinParallelPass);
            detail::radix_sort_words(keys, 32, 64, threads, scratch);
            scratch = {};
            elem.resize(m);
            pos.resize(m);
            leaf_of.resize(m);
            if (area) pb.resize(m);
            else pc.resize(m);
            parallel_for(m, threads, [&](std::size_t s) {
                const auto e = static_cast<std::uint32_t>(keys[s]);
                elem[s] = e;
                pos[e] = static_cast<std::uint32_t>(s);
                if (area) pb[s] = L.box[e];
                else pc[s] = L.centre[e];
            }, detail::kMinParallelPass);
            // Radix tree over the codes: a range splits where its highest
            // differing code bit changes (octree cells, so sibling boxes
            // barely overlap), equal codes in the middle, down to ≤ kBucket.
            auto code = [&](std::uint32_t s) { return static_cast<std::uint32_t>(keys[s] >> 32); };
            tree.reserve(2 * (std::size_t(m) / kBucket + 1) * 2);
            tree.push_back({AABB{}, 0, 0, kNone, kNone});
            struct Range {
                std::uint32_t node, lo, hi;
            };
            std::vector<Range> work{{0, 0, m}};
            while (!work.empty()) {
                const Range r = work.back();
                work.pop_back();
                if (r.hi - r.lo <= kBucket) {
                    tree[r.node].kid = r.lo;
                    tree[r.node].count = r.hi - r.lo;
                    continue;
                }
                std::uint32_t mid;
                const std::uint32_t a = code(r.lo), b = code(r.hi - 1);
                if (a == b) {
                    mid = r.lo + (r.hi - r.lo) / 2;
                } else {
                    const std::uint32_t bit = 1u << (31 - std::countl_zero(a ^ b));
                    std::uint32_t lo = r.lo, hi = r.hi - 1;  // first position with the bit set
                    while (lo < hi) {
                        const std::uint32_t c = lo + (hi - lo) / 2;
                        if (code(c) & bit) hi = c;
                        else lo = c + 1;
                    }
                    mid = lo;
                }
                const auto k = static_cast<std::uint32_t>(tree.size());
                tree[r.node].kid = k;
                tree.push_back({AABB{}, 0, 0, r.node, kNone});
                tree.push_back({AABB{}, 0, 0, r.node, kNone});
                work.push_back({k + 1, mid, r.hi});
                work.push_back({k, r.lo, mid});
            }
            keys = {};
            // leaves, then inner nodes (children come after their parent)
            alive.assign(tree.size(), 1);
            for (std::size_t k = tree.size(); k-- > 0;) {
                TreeNode& t = tree[k];
                if (t.count > 0) {
                    for (std::uint32_t s = t.kid; s < t.kid + t.count; ++s) {
                        t.box.grow(area ? pb[s] : AABB::of_point(pc[s]));
                        t.min_elem = std::min(t.min_elem, elem[s]);
                        leaf_of[s] = static_cast<std::uint32_t>(k);
                    }
                    alive[k] = static_cast<Mask>((std::uint64_t(1) << t.count) - 1u);
                } else {
                    t.box = merge(tree[t.kid].box, tree[t.kid + 1].box);
                    t.min_elem = std::min(tree[t.kid].min_elem, tree[t.kid + 1].min_elem);
                }
            }
        }

        /// Whether list element e is alive in state `a`.
        bool is_alive(std::uint32_t e, const std::vector<Mask>& a) const noexcept {
            const std::uint32_t s = pos[e], leaf = leaf_of[s];
            return (static_cast<unsigned>(a[leaf]) >> (s - tree[leaf].kid)) & 1u;
        }

        /// An inner node is marked empty when its last element goes, so a removal climbs the tree
        /// only then (once per node). It used to keep each node's smallest live list index, and
        /// climbed most of the way at most removals (elements go in list order); the tie bound now
        /// uses the smallest index live or not, which prunes less only on exact ties. Bunny, one
        /// thread: 40 -> 34 ms (centre), 67 -> 59 ms (area); the same trees.
        /// Puts list element e back into state `a` (the inverse of remove).
        void insert(std::uint32_t e, std::vector<Mask>& a) const noexcept {
            const std::uint32_t s = pos[e];
            std::uint32_t k = leaf_of[s];
            a[k] |= static_cast<Mask>(Mask(1) << (s - tree[k].kid));
            for (k = tree[k].parent; k != kNone && a[k] == 0; k = tree[k].parent) a[k] = 1;
        }

        void remove(std::uint32_t e, std::vector<Mask>& a) const noexcept {
            const std::uint32_t s = pos[e];
            std::uint32_t k = leaf_of[s];
            a[k] &= static_cast<Mask>(~(Mask(1) << (s - tree[k].kid)));
            for (std::uint32_t p = tree[k].parent; a[k] == 0 && p != kNone; k = p, p = tree[p].parent) {
                if (a[tree[p].kid + (tree[p].kid == k ? 1u : 0u)] != 0) break;
                a[p] = 0;
            }
        }

        struct Best {
            double d = kInf;
            std::uint32_t e = kNone;
        };

        /// Nearest element to list element q that is alive in state `a` and comes after q in the
        /// list (the rule's candidates: every earlier one is gone by q's turn), or `best` when none
        /// is nearer.
        Best nearest(std::uint32_t q, const std::vector<Mask>& alive,
                     std::vector<std::pair<double, std::uint64_t>>& stack) const {
            return nearest(q, alive, stack, Best{});
        }
        Best nearest(std::uint32_t q, const std::vector<Mask>& alive, std::vector<std::pair<double, std::uint64_t>>& stack,
                     Best best) const {
            const vec3 qc = L.centre[q];
            const AABB qb = L.box[q];
            auto bound = [&](std::uint32_t k) {
                return area ? area_bound(qb, tree[k].box) : centre_bound(qc, tree[k].box);
            };
            auto skip = [&](double lb, std::uint32_t k) {
                return lb > best.d || (lb == best.d && tree[k].min_elem >= best.e);
            };
            auto scan = [&](std::uint32_t k) {
                const std::uint32_t base = tree[k].kid;
                for (Mask mask = alive[k]; mask; mask &= mask - 1) {
                    const std::uint32_t s = base + static_cast<std::uint32_t>(std::countr_zero(mask));
                    const double d = area ? merged_area(qb, pb[s]) : centre_dist(qc, pc[s]);
                    const std::uint32_t e = elem[s];
                    if (e <= q) continue;
                    if (d < best.d || (d == best.d && e < best.e)) best = {d, e};
                }
            };
            // best first below `root`; the stack holds (bound, node), full
            // width entries (no partial store forwarding)
            auto down = [&](std::uint32_t root, double lb0) {
                stack.clear();
                stack.push_back({lb0, root});
                while (!stack.empty()) {
                    const auto [lb, k64] = stack.back();
                    stack.pop_back();
                    const auto k = static_cast<std::uint32_t>(k64);
                    if (skip(lb, k)) continue;
                    const TreeNode& t = tree[k];
                    if (t.count > 0) {
                        scan(k);
                        continue;
                    }
                    const std::uint32_t l = t.kid, r = l + 1;
                    const double bl = alive[l] != 0 ? bound(l) : kInf;
                    const double br = alive[r] != 0 ? bound(r) : kInf;
                    const bool hl = !skip(bl, l), hr = !skip(br, r);
                    if (bl <= br) {  // the farther first, so the nearer is searched first
                        if (hr) stack.push_back({br, r});
                        if (hl) stack.push_back({bl, l});
                    } else {
                        if (hl) stack.push_back({bl, l});
                        if (hr) stack.push_back({br, r});
                    }
                }
            };
            std::uint32_t k = leaf_of[pos[q]];
            scan(k);
            for (std::uint32_t p = tree[k].parent; p != kNone; k = p, p = tree[p].parent) {
                const std::uint32_t sib = tree[p].kid + (tree[p].kid == k ? 1u : 0u);
                if (alive[sib] == 0) continue;
                const double lb = bound(sib);
                if (!skip(lb, sib)) down(sib, lb);
            }
            return best;
        }
    };

    /// One part of a level's list: the state it plays on, and what each of its queries found.
    /// One part of a level's list (see pair_fast): the state it plays on and what its queries
    /// found. Cache-line aligned, so that no two threads write one line (the parts' stacks did).
    struct alignas(64) Part {
        std::vector<Mask> alive;
        std::vector<std::uint8_t> searched;
        std::vector<Index::Best> best;
        std::vector<std::pair<double, std::uint64_t>> stack;
        std::vector<Pair> pairs;  // part 0's: the caller's list sits beside data the other threads read
    };
    /// Elements per part below which a level is not cut (not tuned: it keeps the cut to levels
    /// whose parts take far longer than waking a thread).
    static constexpr std::uint32_t kMinPart = 4096;

    /// The rule on one level. With several threads the list is cut into one contiguous part per
    /// thread. Part 0 plays the rule on the level's state. Each later part plays it at the same
    /// time on a copy of the state at the level's start, as though the parts before it had
    /// paired nothing (their elements come before its queries, so only their partners inside it
    /// are missed). Then the later parts are committed in list order: a guess is kept when its
    /// partner is still alive and no element that its part wrongly took as gone (a "phantom": the
    /// partner of a guess not kept) is nearer, and is searched again otherwise. The set alive at
    /// a query's turn lies within the guess's set plus the live phantoms, so a kept guess is the
    /// rule's answer, ties included: the pairs, and so the tree, are the same for every thread
    /// count. (Guessing in rounds of 2048 queries per thread instead let wrong guesses cascade
    /// from every round's seams: 10 % searched again on the bunny, and no faster than 1 thread.)
    static std::uint32_t pair_fast(const Level& L, bool area, unsigned threads, detail::WorkTeam& team,
                                   std::vector<Part>& parts, std::vector<Pair>& pairs) {
        // on the heap and on cache lines of its own (Index is aligned): the other threads read its
        // fields all the time, so nothing the calling thread writes (its stack frames, a
        // neighbouring allocation) may share a line with them
        const auto index = std::make_unique<Index>(L, area, threads);
        Index& ix = *index;
        const auto m = static_cast<std::uint32_t>(L.size());
        const unsigned members = std::max(1u, std::min(team.size(), m / kMinPart));
        auto bounds = [&](unsigned c) { return std::uint32_t(std::uint64_t(m) * c / members); };
        parts.resize(members);
        for (unsigned c = 1; c < members; ++c) {
            parts[c].alive = ix.alive;
            parts[c].searched.assign(bounds(c + 1) - bounds(c), 0);
            parts[c].best.resize(bounds(c + 1) - bounds(c));
        }
        std::uint32_t carried = kNone;
        team.chunks(m, members, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            Part& p = parts[c];
            std::vector<Mask>& alive = c == 0 ? ix.alive : p.alive;
            for (std::uint32_t e = 0; e < lo; ++e) ix.remove(e, alive);  // gone by the part's first turn
            for (auto q = static_cast<std::uint32_t>(lo); q < hi; ++q) {
                if (!ix.is_alive(q, alive)) continue;
                ix.remove(q, alive);
                const Index::Best b = ix.nearest(q, alive, p.stack);
                if (c > 0) {
                    p.searched[q - lo] = 1;
                    p.best[q - lo] = b;
                } else if (b.e == kNone) {
                    carried = q;  // nothing else is alive
                    return;
                } else {
                    p.pairs.push_back({q, b.e});
                }
                if (b.e != kNone) ix.remove(b.e, alive);
            }
        });
        pairs.insert(pairs.end(), parts[0].pairs.begin(), parts[0].pairs.end());
        parts[0].pairs.clear();
        std::vector<Mask> phantoms;  // a state of the live phantoms only
        for (unsigned c = 1; c < members && carried == kNone; ++c) {
            Part& p = parts[c];
            phantoms.assign(ix.alive.size(), 0);
            auto gone = [&](std::uint32_t e) {
                ix.remove(e, ix.alive);
                ix.remove(e, phantoms);
            };
            for (std::uint32_t q = bounds(c); q < bounds(c + 1); ++q) {
                const bool guessed = p.searched[q - bounds(c)] != 0;
                const Index::Best guess = guessed ? p.best[q - bounds(c)] : Index::Best{};
                if (!ix.is_alive(q, ix.alive)) {
                    if (guess.e != kNone && ix.is_alive(guess.e, ix.alive)) ix.insert(guess.e, phantoms);
                    continue;
                }
                gone(q);
                bool keep = guessed && (guess.e == kNone || ix.is_alive(guess.e, ix.alive));
                keep = keep && (phantoms[0] == 0 || ix.nearest(q, phantoms, p.stack, guess).e == guess.e);
                const Index::Best b = keep ? guess : ix.nearest(q, ix.alive, p.stack);
                if (!keep && guess.e != kNone && ix.is_alive(guess.e, ix.alive)) ix.insert(guess.e, phantoms);
                if (b.e == kNone) {
                    carried = q;
                    break;
                }
                gone(b.e);
                pairs.push_back({q, b.e});
            }
        }
        return carried;
    }

    static Bvh run(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg, bool reference) {
        if (boxes.size() != centers.size())
            throw std::invalid_argument("PairwiseBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("PairwiseBuilder: too many primitives");
        check_leaf_block(cfg.leaf.leaf_block, "PairwiseBuilder");
        check_threads(cfg.threads, "PairwiseBuilder");
        const unsigned threads = resolve_threads(cfg.threads);
        const bool area = cfg.metric == Config::Metric::area;
        const auto n = static_cast<std::uint32_t>(boxes.size());
        const detail::SanitizedCenters sc = detail::sanitize_centers(centers, threads);
        detail::MergeTree tree;
        tree.prims = n;
        tree.info.reserve(n > 0 ? n - 1 : 0);
        Level cur, next;
        cur.centre.assign(sc.view.begin(), sc.view.end());
        cur.box.resize(n);
        cur.node.resize(n);
        parallel_for(n, threads, [&](std::size_t i) {
            cur.box[i] = detail::working_box(boxes[i], sc[i]);
            cur.node[i] = static_cast<std::uint32_t>(i);
        }, detail::kMinParallelPass);
        std::vector<Pair> pairs;
        detail::WorkTeam team(!reference && n >= 2 * kMinPart ? threads : 1u);
        std::vector<Part> parts;
        while (cur.size() > 1) {
            pairs.clear();
            const std::uint32_t carried = (reference || cur.size() <= kBruteLevel)
                                              ? pair_brute(cur, area, pairs)
                                              : pair_fast(cur, area, threads, team, parts, pairs);
            const std::size_t np = pairs.size(), m2 = np + (carried != kNone);
            const auto base = static_cast<std::uint32_t>(tree.size());
            tree.info.resize(base + np);
            next.centre.resize(m2);
            next.box.resize(m2);
            next.node.resize(m2);
            parallel_for(np, threads, [&](std::size_t t) {
                const Pair p = pairs[t];
                const AABB b = merge(cur.box[p.a], cur.box[p.b]);
                tree.set(base + t, cur.node[p.a], cur.node[p.b]);
                next.box[t] = b;
                next.centre[t] = detail::box_centre(b);
                next.node[t] = n + base + static_cast<std::uint32_t>(t);
            }, detail::kMinParallelPass);
            if (carried != kNone) {
                next.centre[np] = cur.centre[carried];
                next.box[np] = cur.box[carried];
                next.node[np] = cur.node[carried];
            }
            tree.close_batch();
            std::swap(cur, next);
        }
        tree.root = n > 0 ? cur.node[0] : 0;
        return detail::finish_bottom_up(tree, boxes, sc.view, cfg.leaf, threads);
    }
};

}  // namespace raykit
