// raykit/bvh/binned_sah.hpp — top-down binned SAH builder (the quality reference).
//
//   Bvh bvh = BinnedSahBuilder::build(prim_boxes, prim_centers, {.leaf = {.max_leaf_size = 4}});
//
// Each node bins primitive centroids into `bins` buckets on all three axes
// (nodes of at most 16 primitives instead sort them on each axis and try all
// n-1 splits exactly), sweeps the buckets for the split of least SAH cost
//   Ct·SA(node) + Ci·(SA(L)·|L| + SA(R)·|R|)
// and makes a leaf instead when that is cheaper than Ci·SA(node)·|node| and the
// node holds at most `leaf.max_leaf_size` primitives. With leaf.leaf_block = B,
// every |set| above counts ceil(|set| / B): the cost of SIMD leaf tests. Coincident centroids fall back
// to a split by index; below kMedianDepth (bvh/depth.hpp) splits are medians.
//
// Non-finite centroids (NaN triangles) sit at the centre of the finite ones,
// by bvh/sanitize.hpp's rule, the one every builder uses: they still need a
// place in the tree, and binning must never see a NaN. This builder used to
// carry its own copy of the rule, which copied every centroid; the shared one
// copies only when some centroid is not finite. Same trees bit for bit, same
// build time (1M-triangle torus, 1 thread: 466-471 ms before and after).
//
// The builder partitions a compact array of (box, centroid, index) records in
// place, so every pass streams through memory; a partition pass also
// accumulates both children's bounds.
//
// Parallel: the two subtrees of large nodes build on separate threads
// (fork/join, down to a depth of log2(threads)+2), and the binning and bounds
// passes of nodes over 64k primitives run in chunks on all threads. The tree is
// the same for every thread count: splits depend only on the primitive set,
// and the final layout is a depth-first pre-order pass.
#pragma once

#include <algorithm>
#include <array>
#include <cstdint>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/depth.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/bvh/sanitize.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

struct BinnedSahBuilder {
    struct Config {
        unsigned bins = 32;                     ///< buckets per axis (2..256)
        unsigned min_leaf_size = 1;             ///< nodes this small always become leaves
        LeafCost leaf;                          ///< max leaf size (larger nodes are always split), Ct, Ci, leaf_block
        unsigned threads = 0;                   ///< 0 = all hardware threads; at most kMaxThreads (else std::invalid_argument)
        std::size_t parallel_threshold = 4096;  ///< subtrees smaller than this stay on one thread
    };

    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers) {
        return build(boxes, centers, Config{});
    }
    static Bvh build(std::span<const AABB> boxes, std::span<const vec3> centers, const Config& cfg) {
        if (boxes.size() != centers.size())
            throw std::invalid_argument("BinnedSahBuilder: boxes and centers differ in size");
        if (boxes.size() >= 0x7FFFFFFFu) throw std::length_error("BinnedSahBuilder: too many primitives");
        if (cfg.bins < 2 || cfg.bins > 256) throw std::invalid_argument("BinnedSahBuilder: bins must be in [2, 256]");
        check_leaf_block(cfg.leaf.leaf_block, "BinnedSahBuilder");
        check_threads(cfg.threads, "BinnedSahBuilder");
        Bvh bvh;
        const auto n = static_cast<std::uint32_t>(boxes.size());
        if (n == 0) return bvh;
        Impl impl{{}, {}, cfg, resolve_threads(cfg.threads), 0};
        {
            const detail::SanitizedCenters c = detail::sanitize_centers(centers, impl.threads);
            impl.refs.resize(n);
            parallel_for(n, impl.threads, [&](std::size_t i) {
                impl.refs[i] = {boxes[i], c[i], static_cast<std::uint32_t>(i)};
            });
        }
        impl.tmp.resize(2 * std::size_t(n) - 1);
        int fd = 1;
        while ((1u << (fd - 1)) < impl.threads) ++fd;
        impl.fork_depth = impl.threads > 1 ? fd + 1 : 0;
        AABB box, cbox;
        impl.bounds(0, n, box, cbox);
        impl.node(0, 1, 0, n, 0, box, cbox);
        bvh.nodes = detail::compact_preorder(impl.tmp);
        bvh.prim_ids.resize(n);
        for (std::uint32_t i = 0; i < n; ++i) bvh.prim_ids[i] = impl.refs[i].id;
        return bvh;
    }

private:
    struct Bin {
        AABB box;
        std::uint32_t count = 0;
    };

    /// What the builder partitions: a primitive's box, centroid and index,
    /// kept together so each pass streams through memory.
    struct Ref {
        AABB box;
        vec3 c;
        std::uint32_t id;
    };

    struct Impl {
        std::vector<Ref> refs;
        std::vector<Node> tmp;
        Config cfg;
        unsigned threads;
        int fork_depth;

        static constexpr std::size_t kParallelPass = 65536;

        void bounds(std::uint32_t b, std::uint32_t e, AABB& box, AABB& cbox) const {
            auto pass = [&](std::size_t lo, std::size_t hi, AABB& bx, AABB& cb) {
                for (std::size_t i = lo; i < hi; ++i) {
                    bx.grow(refs[i].box);
                    cb.grow(refs[i].c);
                }
            };
            const std::size_t n = e - b;
            if (n < kParallelPass || threads == 1) {
                pass(b, e, box, cbox);
                return;
            }
            constexpr std::size_t kChunks = 16;
            std::array<AABB, kChunks> bx{}, cb{};
            parallel_chunks(n, kChunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
                pass(b + lo, b + hi, bx[c], cb[c]);
            });
            for (std::size_t c = 0; c < kChunks; ++c) {
                box.grow(bx[c]);
                cbox.grow(cb[c]);
            }
        }

        struct Binner {
            vec3 lo, scale;
            std::size_t nb;
            std::size_t index(const vec3& c, int a) const {
                const float f = (c[a] - lo[a]) * scale[a];
                const std::size_t k = f > 0.0f ? static_cast<std::size_t>(f) : 0;
                return k < nb ? k : nb - 1;
            }
        };

        void bin(std::uint32_t b, std::uint32_t e, const Binner& bn, std::vector<Bin>& out) const {
            const std::size_t nb = bn.nb;
            auto pass = [&](std::size_t lo, std::size_t hi, Bin* dst) {
                for (std::size_t i = lo; i < hi; ++i) {
                    const vec3& c = refs[i].c;
                    const AABB& bx = refs[i].box;
                    Bin& bxn = dst[bn.index(c, 0)];
                    Bin& byn = dst[nb + bn.index(c, 1)];
                    Bin& bzn = dst[2 * nb + bn.index(c, 2)];
                    bxn.box.grow(bx), ++bxn.count;
                    byn.box.grow(bx), ++byn.count;
                    bzn.box.grow(bx), ++bzn.count;
                }
            };
            out.assign(3 * nb, Bin{});
            const std::size_t n = e - b;
            if (n < kParallelPass || threads == 1) {
                pass(b, e, out.data());
                return;
            }
            constexpr std::size_t kChunks = 16;
            std::vector<Bin> part(kChunks * 3 * nb);
            parallel_chunks(n, kChunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
                pass(b + lo, b + hi, part.data() + c * 3 * nb);
            });
            for (std::size_t c = 0; c < kChunks; ++c)
                for (std::size_t k = 0; k < 3 * nb; ++k) {
                    out[k].box.grow(part[c * 3 * nb + k].box);
                    out[k].count += part[c * 3 * nb + k].count;
                }
        }

        static constexpr std::uint32_t kSweepMax = 16;

        /// Sorts refs[b, e) by centroid on `axis`, ties by primitive index.
        void sort_axis(std::uint32_t b, std::uint32_t e, int axis) {
            std::sort(refs.begin() + b, refs.begin() + e, [axis](const Ref& x, const Ref& y) {
                return x.c[axis] < y.c[axis] || (x.c[axis] == y.c[axis] && x.id < y.id);
            });
        }

        struct SweepResult {
            int axis = -1;
            std::uint32_t split = 0;  ///< left child = the first `split` records
            float cost = kInf;        ///< SA(L)·|L| + SA(R)·|R|, half areas
        };

        /// Exact SAH sweep of a small node: tries all n-1 splits of the
        /// centroid order on each axis, and leaves refs[b, e) sorted on the
        /// best axis.
        SweepResult sweep(std::uint32_t b, std::uint32_t e) {
            const std::uint32_t n = e - b;
            SweepResult best;
            for (int a = 0; a < 3; ++a) {
                sort_axis(b, e, a);
                float rarea[kSweepMax];
                AABB acc;
                for (std::uint32_t k = n - 1; k > 0; --k) {
                    acc.grow(refs[b + k].box);
                    rarea[k] = acc.half_area();
                }
                acc = AABB{};
                for (std::uint32_t k = 1; k < n; ++k) {
                    acc.grow(refs[b + k - 1].box);
                    const float c = acc.half_area() * cfg.leaf.blocks(k) + rarea[k] * cfg.leaf.blocks(n - k);
                    if (c < best.cost) best = {a, k, c};
                }
            }
            if (best.axis >= 0 && best.axis != 2) sort_axis(b, e, best.axis);
            return best;
        }

        /// Median split on `axis` (ties by primitive index: the result depends
        /// on the set of primitives only).
        std::uint32_t median(std::uint32_t b, std::uint32_t e, int axis) {
            const std::uint32_t mid = b + (e - b) / 2;
            std::nth_element(refs.begin() + b, refs.begin() + mid, refs.begin() + e, [axis](const Ref& x, const Ref& y) {
                return x.c[axis] < y.c[axis] || (x.c[axis] == y.c[axis] && x.id < y.id);
            });
            return mid;
        }

        void make_leaf(std::uint32_t node, std::uint32_t b, std::uint32_t e, const AABB& box) {
            Node& nd = tmp[node];
            nd.box = box;
            nd.index = b;
            nd.count = e - b;
        }

        /// Scratch for one node's binning, reused by every node on a thread
        /// (a node is done with its bins before it recurses).
        struct Scratch {
            std::vector<Bin> bins;
            std::vector<float> rarea;
            std::vector<std::uint32_t> rcount;
        };
        static Scratch& scratch() {
            thread_local Scratch s;
            return s;
        }

        /// Builds the subtree of ids[b, e) into tmp[node]; `box`/`cbox` are the
        /// bounds of the primitives' boxes and centroids (from the parent's
        /// partition pass).
        void node(std::uint32_t node, std::uint32_t desc, std::uint32_t b, std::uint32_t e, int depth,
                  const AABB& box, const AABB& cbox) {
            const std::uint32_t n = e - b;
            if (n <= std::max(1u, cfg.min_leaf_size)) return make_leaf(node, b, e, box);

            std::uint32_t mid = 0;
            const vec3 ext = cbox.extent();
            const int widest = max_axis(ext);
            AABB lbox, lcbox, rbox, rcbox;
            bool have_bounds = false;
            if (depth >= kMedianDepth) {
                mid = median(b, e, widest);
            } else if (n <= kSweepMax) {
                // small node: exact SAH over all n-1 splits of each axis' sorted order
                const SweepResult sw = sweep(b, e);
                const float sa = box.half_area();
                const float split_cost = cfg.leaf.traversal_cost * sa + cfg.leaf.intersection_cost * sw.cost;
                if (n <= cfg.leaf.max_leaf_size && cfg.leaf.leaf_cost(sa, n) <= split_cost)
                    return make_leaf(node, b, e, box);
                mid = sw.axis >= 0 ? b + sw.split : median(b, e, widest);
            } else if (!(ext[widest] > 0.0f)) {
                // all centroids coincide: nothing to bin
                if (n <= cfg.leaf.max_leaf_size) return make_leaf(node, b, e, box);
                mid = median(b, e, 0);
            } else {
                const std::size_t nb = cfg.bins;
                Binner bn{cbox.min, vec3(0.0f), nb};
                for (int a = 0; a < 3; ++a)
                    bn.scale[a] = ext[a] > 0.0f ? static_cast<float>(nb) * (1.0f - 1e-6f) / ext[a] : 0.0f;
                Scratch& sc = scratch();
                bin(b, e, bn, sc.bins);
                sc.rarea.resize(nb);
                sc.rcount.resize(nb);
                float best = kInf;
                int best_axis = -1;
                std::size_t best_split = 0;
                for (int a = 0; a < 3; ++a) {
                    if (!(ext[a] > 0.0f)) continue;
                    const Bin* ab = sc.bins.data() + static_cast<std::size_t>(a) * nb;
                    AABB acc;
                    std::uint32_t cnt = 0;
                    for (std::size_t k = nb - 1; k > 0; --k) {
                        acc.grow(ab[k].box);
                        cnt += ab[k].count;
                        sc.rarea[k] = acc.half_area();
                        sc.rcount[k] = cnt;
                    }
                    acc = AABB{};
                    cnt = 0;
                    for (std::size_t k = 1; k < nb; ++k) {
                        acc.grow(ab[k - 1].box);
                        cnt += ab[k - 1].count;
                        if (cnt == 0 || sc.rcount[k] == 0) continue;
                        const float c =
                            acc.half_area() * cfg.leaf.blocks(cnt) + sc.rarea[k] * cfg.leaf.blocks(sc.rcount[k]);
                        if (c < best) {
                            best = c;
                            best_axis = a;
                            best_split = k;
                        }
                    }
                }
                const float sa = box.half_area();
                const float split_cost = cfg.leaf.traversal_cost * sa + cfg.leaf.intersection_cost * best;
                const float leaf_cost = cfg.leaf.leaf_cost(sa, n);
                if (n <= cfg.leaf.max_leaf_size && (best_axis < 0 || leaf_cost <= split_cost))
                    return make_leaf(node, b, e, box);
                if (best_axis < 0) {
                    mid = median(b, e, widest);
                } else {
                    // partition, accumulating both sides' bounds on the way
                    std::uint32_t i = b, j = e;
                    while (i < j) {
                        const Ref& r = refs[i];
                        if (bn.index(r.c, best_axis) < best_split) {
                            lbox.grow(r.box);
                            lcbox.grow(r.c);
                            ++i;
                        } else {
                            --j;
                            rbox.grow(r.box);
                            rcbox.grow(r.c);
                            std::swap(refs[i], refs[j]);
                        }
                    }
                    mid = i;
                    have_bounds = true;
                    if (mid == b || mid == e) {
                        mid = median(b, e, widest);
                        have_bounds = false;
                    }
                }
            }
            if (!have_bounds) {
                bounds(b, mid, lbox, lcbox);
                bounds(mid, e, rbox, rcbox);
            }
            Node& nd = tmp[node];
            nd.box = box;
            nd.index = desc;
            nd.count = 0;
            const std::uint32_t nl = mid - b;
            const std::uint32_t left_desc = desc + 2, right_desc = desc + 2 + (2 * nl - 2);
            fork_join(
                depth < fork_depth && n >= cfg.parallel_threshold,
                [&] { this->node(desc, left_desc, b, mid, depth + 1, lbox, lcbox); },
                [&] { this->node(desc + 1, right_desc, mid, e, depth + 1, rbox, rcbox); });
        }
    };
};

}  // namespace raykit
