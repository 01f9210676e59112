// raykit/bvh/optimize.hpp — an optional post-pass for the bottom-up builders'
// merge trees: reinsertion of large subtrees, then treelet restructuring.
//
//   PlocBuilder::Config c;                   // the pass is on by default for PLOC
//   c.optimize = OptimizeConfig::off();      // plain PLOC
//   SortAxisBuilder::Config s;
//   s.optimize = OptimizeConfig{};           // the same pass after sort-by-axis
//
// Bottom-up clustering decides every merge from local information, and its
// trees are local optima that a top-down SAH build does not share (on the
// bunny and a 100k torus PLOC's SAH cost is 1.08-1.10x binned SAH's, spread
// over all levels above the leaves). Two classic repairs run on the merge tree
// before the leaf merge (bvh/bottom_up.hpp):
//
//  1. Reinsertion (Bittner, Hapala & Havran, "Fast insertion-based
//     optimization of bounding volume hierarchies", CGF 2013). The
//     `reinsert_share` of all nodes with the largest boxes are, one after
//     the other, taken out of the tree (their parent goes, the sibling takes
//     its place) and put back as the sibling of the node X where the summed
//     surface area of the inner nodes grows least: A(X ∪ N) plus the growth
//     of X's ancestors, found by branch and bound from the root. A node moves
//     only when that is less than what removing it saved. This repairs the
//     top of the tree, where clusters met because they were neighbours in
//     Morton order.
//  2. Treelet restructuring (Karras & Aila, "Fast parallel construction of
//     high-quality bounding volume hierarchies", HPG 2013). Children before
//     parents, every node with at least `treelet_min_prims` primitives below
//     it (γ) roots a treelet: its subtree cut down to 7 leaves by repeatedly
//     opening the leaf with the largest box. A dynamic program over the 127
//     subsets of those leaves finds the binary tree over them of least cost,
//     with the rule and constants of the back end's leaf merge (a
//     subset of at most max_leaf_size primitives may become one leaf,
//     Ci·SA·n against Ct·SA + the halves' costs); the treelet is rebuilt when
//     that is cheaper. `treelet_rounds` rounds; after the first, only nodes
//     whose subtree changed run again. γ bounds the work: smaller subtrees
//     stay as built (PLOC's lowest levels are already as good as SAH's).
//
// The pass keeps its result only when the leaf-merge-aware SAH cost of the whole
// tree went down (else the tree is left as built), so it never makes a tree
// worse. It is deterministic and gives the same tree for any thread count:
// reinsertion is sequential, and the treelets of a round run children before
// parents, independent subtrees on separate threads. The result goes back as
// a merge tree (children first, one batch per height), so the depth bound and
// the output of finish_bottom_up apply unchanged: restructuring may deepen
// the tree, and any subtree that would pass RAYKIT_BVH_MAX_DEPTH is rebuilt
// with median splits there.
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <span>
#include <utility>
#include <vector>

#include "raykit/bvh/bottom_up.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sanitize.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// Settings of the post-pass (see the top of bvh/optimize.hpp). Defaults
/// from measurement, after PLOC R 4, SAH cost relative to binned SAH on the
/// bunny / thesis scene / bumpy torus 100k / 1M (plain PLOC: 1.099 / 0.747 /
/// 1.079 / 1.097):
///   reinsertion 2 % only:                         1.078 / 0.738 / 1.066 / 1.069
///   treelets only, 2 rounds, γ 16:                1.059 / 0.733 / 1.051 / 1.055
///   reinsertion 2 % + 1 round, γ 16:              1.049 / 0.730 / 1.048 / 1.049
///   reinsertion 2 % + 2 rounds, γ 16 (default):   1.043 / 0.729 / 1.045 / 1.044
///   reinsertion 2 % + 2 rounds, γ 32:             1.048 / 0.730 / 1.049 / 1.048
///   reinsertion 2 % + 3 rounds, γ 16:             1.041 / 0.728 / 1.043 / 1.043
/// The default keeps every mesh 0.5 % inside 1.05; γ 32 takes about a third
/// less time, a third round about 15 % more.
struct OptimizeConfig {
    /// Share of all nodes, largest boxes first, that are reinserted once (0: none).
    float reinsert_share = 0.02f;
    /// Rounds of treelet restructuring (0: none).
    unsigned treelet_rounds = 2;
    /// γ: only nodes with at least this many primitives below root a treelet.
    unsigned treelet_min_prims = 16;

    static constexpr OptimizeConfig off() noexcept { return {0.0f, 0u, 16u}; }
    bool enabled() const noexcept { return reinsert_share > 0.0f || treelet_rounds > 0; }
};

namespace detail {
/// The post-pass on a merge tree (any node order, possibly with nodes no
/// longer reachable from the root after a depth cut). `boxes` are the real
/// primitive boxes and `centers` the sanitized centroids; decisions use
/// working boxes. On return the tree is in batch order (children before
/// parents, one batch per height) with info_ready unset.
class MergeTreeOptimizer {
public:
    static constexpr std::uint32_t kNone = 0xFFFFFFFFu;
    static constexpr int kTreeletLeaves = 7;

    /// `in_order`: t is as a builder left it (batches, children first, every
    /// node reachable); else it is walked from the root.
    MergeTreeOptimizer(MergeTree& t, std::span<const AABB> boxes, std::span<const vec3> centers,
                       const LeafCost& lc, unsigned threads, bool in_order, WorkTeam* team = nullptr)
        : t_(t), lc_(lc), n_(t.prims), threads_(std::max(1u, threads)), team_(team), all_reachable_(in_order) {
        const std::size_t total = std::size_t(n_) + t.size();
        box_.resize(total);
        parent_.resize(total);
        count_.resize(total);
        cost_.resize(total);
        kid_.resize(t.size());
        auto prim = [&](std::size_t, std::size_t lo, std::size_t hi) {
            for (std::size_t p = lo; p < hi; ++p) {
                box_[p] = working_box(boxes[p], centers[p]);
                count_[p] = 1;
                cost_[p] = lc_.intersection_cost * ha(box_[p]);
                parent_[p] = kNone;
            }
        };
        const std::size_t chunks = threads_ > 1 && n_ >= kMinParallelPass ? threads_ : 1;
        run_chunks(team_, threads_, n_, chunks, prim);
        root_ = t.root;
        parent_[root_] = kNone;
        auto init = [&](std::size_t v) {  // inner node v, children done
            const std::uint32_t a = t.info[v - n_].kid[0], b = t.info[v - n_].kid[1];
            kid_[v - n_] = {a, b};
            parent_[a] = static_cast<std::uint32_t>(v);
            parent_[b] = static_cast<std::uint32_t>(v);
            box_[v] = merge(box_[a], box_[b]);
            eval(static_cast<std::uint32_t>(v));
        };
        if (in_order) {
            auto node = [&](std::size_t k) { init(n_ + k); };
            sweep_batches(t, threads_, node, team_);
            inner_reachable_ = t.size();
        } else {
            for (std::size_t k = 0; k < t.size(); ++k) kid_[k] = {t.info[k].kid[0], t.info[k].kid[1]};
            std::vector<std::uint32_t> order;
            post_order(root_, order);
            for (const std::uint32_t v : order) init(v);
            inner_reachable_ = order.size();
        }
        start_cost_ = inner(root_) ? cost_[root_] : 0.0f;
        start_kid_ = kid_;
        start_root_ = root_;
    }

    void run(const OptimizeConfig& oc) {
        if (n_ < 3) return;
        if (oc.reinsert_share > 0.0f) {
            reinsert(oc.reinsert_share);
            costs_valid_ = false;  // the moved paths; a treelet round evaluates every node first
        }
        flags_.assign(box_.size(), 0);
        changed_.assign(box_.size(), 0);
        for (std::size_t id = n_; id < box_.size(); ++id) flags_[id] = kFresh | kPending;
        for (unsigned r = 0; r < oc.treelet_rounds; ++r) {
            treelet_round(std::max(1u, oc.treelet_min_prims));
            costs_valid_ = true;
        }
    }

    /// Writes the tree back into the merge tree: inner nodes renumbered
    /// children first, one batch per height. When the passes did not lower
    /// the leaf-merge-aware SAH cost, the tree as it came in is written.
    void write_back() {
        MergeTree& t = t_;
        std::vector<std::uint32_t> order;
        post_order(root_, order);
        if (!costs_valid_)
            for (const std::uint32_t v : order) eval(v);
        if (!(inner(root_) && cost_[root_] < start_cost_)) {
            kid_ = start_kid_;
            root_ = start_root_;
            post_order(root_, order);
        }
        std::vector<std::uint32_t> height(kid_.size(), 0);
        std::uint32_t max_h = 0;
        auto h_of = [&](std::uint32_t id) { return id < n_ ? 0u : height[id - n_]; };
        for (const std::uint32_t v : order) {
            const auto& k = kid_[v - n_];
            height[v - n_] = 1 + std::max(h_of(k[0]), h_of(k[1]));
            max_h = std::max(max_h, height[v - n_]);
        }
        std::vector<std::uint32_t> start(max_h + 2, 0);
        for (const std::uint32_t v : order) ++start[height[v - n_]];
        std::uint32_t sum = 0;
        for (std::uint32_t h = 1; h <= max_h; ++h) {
            const std::uint32_t c = start[h];
            start[h] = sum;
            sum += c;
        }
        std::vector<std::uint32_t> remap(kid_.size(), kNone);
        for (const std::uint32_t v : order) remap[v - n_] = start[height[v - n_]]++;
        auto map = [&](std::uint32_t id) { return id < n_ ? id : n_ + remap[id - n_]; };
        t.info.resize(order.size());
        for (const std::uint32_t v : order) {
            MergeInfo& in = t.info[remap[v - n_]];
            in.kid[0] = map(kid_[v - n_][0]);
            in.kid[1] = map(kid_[v - n_][1]);
        }
        t.batch_end.clear();
        for (std::uint32_t h = 1; h <= max_h; ++h) t.batch_end.push_back(start[h]);
        t.root = map(root_);
        t.info_ready = false;
    }

    /// Leaf-merge-aware SAH cost (working boxes, not normalised) of the tree
    /// as it came in.
    float start_cost() const noexcept { return start_cost_; }

private:
    /// Half area of a working box (finite and non-empty), inlined.
    static float ha(const AABB& b) noexcept {
        const float ex = clamp_extent(b.max.x - b.min.x), ey = clamp_extent(b.max.y - b.min.y),
                    ez = clamp_extent(b.max.z - b.min.z);
        return ex * ey + ey * ez + ez * ex;
    }
    float area(std::uint32_t id) const noexcept { return ha(box_[id]); }
    bool inner(std::uint32_t id) const noexcept { return id >= n_; }

    /// Inner nodes of the subtree at v, children before parents.
    void post_order(std::uint32_t v, std::vector<std::uint32_t>& out) const {
        out.clear();
        if (!inner(v)) return;
        std::vector<std::pair<std::uint32_t, bool>> st{{v, false}};
        while (!st.empty()) {
            const auto [x, expanded] = st.back();
            st.pop_back();
            if (expanded) {
                out.push_back(x);
                continue;
            }
            st.push_back({x, true});
            const auto& k = kid_[x - n_];
            if (inner(k[1])) st.push_back({k[1], false});
            if (inner(k[0])) st.push_back({k[0], false});
        }
    }

    /// Box of v from its children.
    void refit_one(std::uint32_t v) { box_[v] = merge(box_[kid_[v - n_][0]], box_[kid_[v - n_][1]]); }

    /// Refits the boxes from v up to the root.
    void refit_up(std::uint32_t v) {
        for (; v != kNone; v = parent_[v]) refit_one(v);
    }

    void replace_child(std::uint32_t parent, std::uint32_t old_child, std::uint32_t new_child) {
        if (parent == kNone) {
            root_ = new_child;
        } else {
            auto& k = kid_[parent - n_];
            (k[0] == old_child ? k[0] : k[1]) = new_child;
        }
        parent_[new_child] = parent;
    }

    // ------------------------------------------------------------ reinsertion
    void reinsert(float share) {
        // candidates: every reachable node but the root and its children
        std::vector<std::pair<float, std::uint32_t>> cand;
        auto add_kids = [&](std::uint32_t v) {
            if (v == root_) return;
            for (const std::uint32_t c : kid_[v - n_]) cand.push_back({-area(c), c});
        };
        if (all_reachable_) {
            cand.reserve(std::size_t(n_) + kid_.size());
            for (std::size_t k = 0; k < kid_.size(); ++k) add_kids(static_cast<std::uint32_t>(n_ + k));
        } else {
            std::vector<std::uint32_t> order;
            post_order(root_, order);
            for (const std::uint32_t v : order) add_kids(v);
        }
        const auto k = static_cast<std::size_t>(
            std::min<double>(double(cand.size()), std::ceil(double(share) * double(n_ + inner_reachable_))));
        if (k == 0) return;
        std::nth_element(cand.begin(), cand.begin() + std::ptrdiff_t(k - 1), cand.end());
        std::sort(cand.begin(), cand.begin() + std::ptrdiff_t(k));
        for (std::size_t i = 0; i < k; ++i) reinsert_one(cand[i].second);
    }

    /// Takes N out and puts it back where the cost grows least.
    void reinsert_one(std::uint32_t N) {
        const std::uint32_t P = parent_[N];
        if (P == kNone) return;
        const std::uint32_t G = parent_[P];
        if (G == kNone) return;
        auto& pk = kid_[P - n_];
        const bool n_first = pk[0] == N;
        const std::uint32_t S = n_first ? pk[1] : pk[0];
        // cost removed with P, and the shrinking of its ancestors
        float gain = area(P);
        {
            AABB child = box_[S];
            std::uint32_t c = P;
            for (std::uint32_t v = G; v != kNone; c = v, v = parent_[v]) {
                const auto& vk = kid_[v - n_];
                const AABB nb = merge(child, box_[vk[0] == c ? vk[1] : vk[0]]);
                gain += area(v) - ha(nb);
                child = nb;
            }
        }
        // detach
        replace_child(G, P, S);
        refit_up(G);
        // branch and bound for the best sibling X: cost A(X ∪ N) + growth of
        // X's ancestors ("induced" cost ci)
        const AABB nb = box_[N];
        const float an = ha(nb);
        float best = kInf;
        std::uint32_t best_x = kNone;
        heap_.clear();
        heap_.push_back({0.0f, root_});
        auto cmp = [](const Entry& a, const Entry& b) { return a.ci > b.ci || (a.ci == b.ci && a.id > b.id); };
        while (!heap_.empty()) {
            std::pop_heap(heap_.begin(), heap_.end(), cmp);
            const Entry e = heap_.back();
            heap_.pop_back();
            if (e.ci + an >= best) break;
            const float u = ha(merge(box_[e.id], nb));
            const float direct = u + e.ci;
            if (direct < best) {
                best = direct;
                best_x = e.id;
            }
            if (inner(e.id)) {
                const float ci = e.ci + u - area(e.id);
                if (ci + an < best) {
                    for (const std::uint32_t c : kid_[e.id - n_]) {
                        heap_.push_back({ci, c});
                        std::push_heap(heap_.begin(), heap_.end(), cmp);
                    }
                }
            }
        }
        std::uint32_t X = best_x;
        bool keep = !(best_x != kNone && best < gain * (1.0f - 1e-6f));
        if (keep) X = S;
        // insert N as X's sibling under P
        const std::uint32_t xp = parent_[X];
        replace_child(xp, X, P);
        if (keep && n_first) pk = {N, X};
        else if (keep) pk = {X, N};
        else pk = {X, N};
        parent_[X] = P;
        parent_[N] = P;
        refit_up(P);
    }

    struct Entry {
        float ci;
        std::uint32_t id;
    };
    std::vector<Entry> heap_;

    // ------------------------------------------------------ treelet restructuring
    /// Leaf-merge-aware cost of inner node v from its children (as node_cost).
    void eval(std::uint32_t v) {
        const auto& k = kid_[v - n_];
        const float sa = area(v);
        const std::uint32_t cnt = count_[k[0]] + count_[k[1]];
        count_[v] = cnt;
        const float split = lc_.split_cost(sa, cost_[k[0]]) + cost_[k[1]];
        const float leaf = lc_.leaf_cost(sa, cnt);
        cost_[v] = cnt <= lc_.leaf_limit() && leaf <= split ? leaf : split;
    }

    /// For every subset s of the 7 treelet leaves, the subsets p that hold
    /// its lowest leaf, p ≠ s: each split of s into p and s \ p once.
    struct PartitionTable {
        std::array<std::uint16_t, (1 << kTreeletLeaves) + 1> begin{};
        std::array<std::uint8_t, 1024> p{};
    };
    static const PartitionTable& partition_table() {
        static const PartitionTable t = [] {
            PartitionTable r;
            std::size_t at = 0;
            for (unsigned s = 0; s < (1u << kTreeletLeaves); ++s) {
                r.begin[s] = static_cast<std::uint16_t>(at);
                if (s == 0 || (s & (s - 1)) == 0) continue;
                const unsigned low = s & (0u - s), rest = s ^ low;
                for (unsigned q = (rest - 1) & rest;; q = (q - 1) & rest) {
                    r.p[at++] = static_cast<std::uint8_t>(q | low);
                    if (q == 0) break;
                }
            }
            r.begin[1 << kTreeletLeaves] = static_cast<std::uint16_t>(at);
            return r;
        }();
        return t;
    }

    /// Restructures the treelet rooted at v (its subtree is final); returns
    /// whether it did. The inner nodes it reuses are marked fresh.
    bool treelet(std::uint32_t v) {
        std::array<std::uint32_t, kTreeletLeaves> leaf{};
        std::array<std::uint32_t, kTreeletLeaves> inner_ids{};
        std::array<float, kTreeletLeaves> la{};  // leaf areas, -1 for primitives (never opened)
        unsigned nl = 0, ni = 0;
        auto add = [&](unsigned at, std::uint32_t id) {
            leaf[at] = id;
            la[at] = inner(id) ? area(id) : -1.0f;
        };
        add(nl++, kid_[v - n_][0]);
        add(nl++, kid_[v - n_][1]);
        while (nl < kTreeletLeaves) {
            unsigned pick = 0;
            for (unsigned i = 1; i < nl; ++i)
                if (la[i] > la[pick]) pick = i;
            if (la[pick] < 0.0f) break;
            const std::uint32_t x = leaf[pick];
            inner_ids[ni++] = x;
            add(pick, kid_[x - n_][0]);
            add(nl++, kid_[x - n_][1]);
        }
        if (nl < 3) return false;
        const unsigned S = 1u << nl;
        const PartitionTable& tab = partition_table();
        std::array<AABB, 1 << kTreeletLeaves> sb;
        std::array<float, 1 << kTreeletLeaves> sa, copt;
        std::array<std::uint32_t, 1 << kTreeletLeaves> sc;
        const std::uint32_t max_leaf = lc_.leaf_limit();
        for (unsigned s = 1; s < S; ++s) {
            const unsigned low = s & (0u - s);
            if (s == low) {
                const std::uint32_t id = leaf[static_cast<unsigned>(std::countr_zero(s))];
                sb[s] = box_[id];
                sc[s] = count_[id];
                sa[s] = ha(sb[s]);
                copt[s] = cost_[id];
                continue;
            }
            sb[s] = merge(sb[s ^ low], sb[low]);
            sc[s] = sc[s ^ low] + sc[low];
            sa[s] = ha(sb[s]);
            // least cost of splitting s in two (four independent minima)
            const std::uint8_t* P = tab.p.data() + tab.begin[s];
            const unsigned np = unsigned(tab.begin[s + 1]) - tab.begin[s];
            float b0 = kInf, b1 = kInf, b2 = kInf, b3 = kInf;
            unsigned i = 0;
            for (; i + 4 <= np; i += 4) {
                b0 = std::min(b0, copt[P[i]] + copt[s ^ P[i]]);
                b1 = std::min(b1, copt[P[i + 1]] + copt[s ^ P[i + 1]]);
                b2 = std::min(b2, copt[P[i + 2]] + copt[s ^ P[i + 2]]);
                b3 = std::min(b3, copt[P[i + 3]] + copt[s ^ P[i + 3]]);
            }
            for (; i < np; ++i) b0 = std::min(b0, copt[P[i]] + copt[s ^ P[i]]);
            const float best = std::min(std::min(b0, b1), std::min(b2, b3));
            const float split = lc_.split_cost(sa[s], best);
            const float leaf_cost = lc_.leaf_cost(sa[s], sc[s]);
            copt[s] = sc[s] <= max_leaf && leaf_cost <= split ? leaf_cost : split;
        }
        // the split of s that reaches copt (the first in table order)
        auto part_of = [&](unsigned s) {
            const std::uint8_t* P = tab.p.data() + tab.begin[s];
            const unsigned np = unsigned(tab.begin[s + 1]) - tab.begin[s];
            float best = kInf;
            unsigned bp = P[0];
            for (unsigned i = 0; i < np; ++i) {
                const float c = copt[P[i]] + copt[s ^ P[i]];
                if (c < best) {
                    best = c;
                    bp = P[i];
                }
            }
            return bp;
        };
        if (!(copt[S - 1] < cost_[v] * (1.0f - 1e-6f))) return false;
        // rebuild: v keeps its place; the opened inner nodes are reused
        unsigned used = 0;
        auto build = [&](auto&& self, unsigned s, std::uint32_t into) -> void {
            const unsigned ps = part_of(s);
            const unsigned halves[2] = {ps, s ^ ps};
            auto& k = kid_[into - n_];
            for (unsigned h = 0; h < 2; ++h) {
                const unsigned q = halves[h];
                std::uint32_t id;
                if ((q & (q - 1)) == 0) {
                    id = leaf[static_cast<unsigned>(std::countr_zero(q))];
                } else {
                    id = inner_ids[used++];
                    flags_[id] = kFresh | kPending;
                    self(self, q, id);
                }
                k[h] = id;
                parent_[id] = into;
            }
            box_[into] = sb[s];
            count_[into] = sc[s];
            cost_[into] = copt[s];
        };
        build(build, S - 1, v);
        return true;
    }

    /// One node of a round, its children done: x runs its treelet when it
    /// is fresh (never optimized as it stands) or a child changed.
    void process(std::uint32_t x, std::uint32_t gamma) {
        const auto& k = kid_[x - n_];
        const bool kid_changed = changed_[k[0]] == round_ || changed_[k[1]] == round_;
        bool changed = false, rebuilt = false;
        if ((flags_[x] & kFresh) || kid_changed) {
            const float old = cost_[x];
            eval(x);
            rebuilt = count_[x] >= gamma && treelet(x);
            changed = rebuilt || cost_[x] != old;
        }
        flags_[x] = rebuilt || (flags_[k[0]] & kPending) || (flags_[k[1]] & kPending) ? kPending : 0;
        if (changed) changed_[x] = round_;
    }

    /// The pending part of the subtree at v, children first.
    void process_subtree(std::uint32_t v, std::uint32_t gamma, std::vector<std::pair<std::uint32_t, bool>>& st) {
        if (!inner(v) || !(flags_[v] & kPending)) return;
        st.assign(1, {v, false});
        while (!st.empty()) {
            const auto [x, expanded] = st.back();
            st.pop_back();
            if (expanded) {
                process(x, gamma);
                continue;
            }
            st.push_back({x, true});
            for (std::size_t side : {1u, 0u}) {
                const std::uint32_t c = kid_[x - n_][side];
                if (inner(c) && (flags_[c] & kPending)) st.push_back({c, false});
            }
        }
    }

    /// One round over the nodes whose subtree changed since they last ran
    /// (all of them in the first round).
    void treelet_round(std::uint32_t gamma) {
        if (!inner(root_) || !(flags_[root_] & kPending)) return;
        ++round_;
        // Nodes above a frontier run after the independent subtrees below it,
        // which run on separate threads; any children-first order gives the
        // same result.
        const std::uint32_t big = std::max<std::uint32_t>(1024, n_ / 256);
        std::vector<std::uint32_t> top, frontier;
        std::vector<std::uint32_t> st{root_};
        while (!st.empty()) {
            const std::uint32_t x = st.back();
            st.pop_back();
            if (!inner(x) || !(flags_[x] & kPending)) continue;
            if (threads_ > 1 && count_[x] > big) {
                top.push_back(x);
                st.push_back(kid_[x - n_][1]);
                st.push_back(kid_[x - n_][0]);
            } else {
                frontier.push_back(x);
            }
        }
        if (frontier.size() > 1) {
            auto part = [&](std::size_t, std::size_t lo, std::size_t hi) {
                std::vector<std::pair<std::uint32_t, bool>> stack;
                for (std::size_t i = lo; i < hi; ++i) process_subtree(frontier[i], gamma, stack);
            };
            run_chunks(team_, threads_, frontier.size(), frontier.size(), part);
        } else {
            std::vector<std::pair<std::uint32_t, bool>> stack;
            for (const std::uint32_t f : frontier) process_subtree(f, gamma, stack);
        }
        for (auto it = top.rbegin(); it != top.rend(); ++it) process(*it, gamma);  // top: parents before children
    }

    static constexpr std::uint8_t kFresh = 1, kPending = 2;
    MergeTree& t_;
    LeafCost lc_;
    std::uint32_t n_;
    unsigned threads_;
    WorkTeam* team_;
    std::uint32_t root_ = 0;
    bool all_reachable_;
    bool costs_valid_ = true;  // cost_ and count_ hold for every reachable node
    float start_cost_ = 0.0f;
    std::uint32_t start_root_ = 0;
    std::vector<std::array<std::uint32_t, 2>> start_kid_;
    std::size_t inner_reachable_ = 0;
    std::vector<AABB> box_;
    std::vector<std::uint32_t> parent_, count_;
    std::vector<float> cost_;
    std::vector<std::array<std::uint32_t, 2>> kid_;
    std::vector<std::uint8_t> flags_;      // kFresh, kPending (treelet rounds)
    std::vector<std::uint32_t> changed_;  // round in which the node's cost last changed
    std::uint32_t round_ = 0;
};

/// Runs the post-pass on a builder's merge tree (see the top of this file);
/// afterwards finish_bottom_up takes the tree as usual.
inline void optimize_merge_tree(MergeTree& t, std::span<const AABB> boxes, std::span<const vec3> centers,
                                const LeafCost& lc, const OptimizeConfig& oc, unsigned threads,
                                WorkTeam* team = nullptr) {
    if (!oc.enabled() || t.prims < 3) return;
    t.close_batch();
    // a chain-like merge tree is cut to the depth bound first, so that every
    // walk to the root is short
    const bool cut = t.batch_end.size() > std::size_t(RAYKIT_BVH_MAX_DEPTH) && limit_depth(t, centers);
    MergeTreeOptimizer opt(t, boxes, centers, lc, team ? team->size() : threads, !cut, team);
    opt.run(oc);
    opt.write_back();
}

}  // namespace detail
}  // namespace raykit
