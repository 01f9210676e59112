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
// accumulates both children's bounds, and classifies records in blocks without
// a branch (Impl::partition).
//
// Parallel: one team of `threads` threads per build (util/parallel.hpp). The
// root splits first, its passes in chunks on the team; a node of at least
// parallel_threshold primitives then hands its subtrees to a queue
// (detail::TaskQueue) that the team drains, largest subtree first, and inside
// it the binning and bounds passes of nodes over 64k primitives run in chunks
// on teams of the task's thread and the pool's idle members. The tree is the
// same for every thread count: splits depend only on the primitive set, and
// nodes are written in depth-first pre-order as they are made (a handed-off
// subtree into a buffer of its own; the buffers are put together at the end,
// on the team). Against forking
// two threads per node down to depth log2(threads)+2, the pool is 4-10 %
// faster on two threads (bunny 13.2-14.0 -> 11.9-12.3 ms, same trees). Against
// a one-call team per pass (nine per bunny build, ~56 µs each to start), the
// build's team is 3 % faster there (medians of 8 interleaved processes, 12.16
// -> 11.75 ms; BlockBvh8::build 16.43 -> 15.38 ms).
#pragma once

#include <algorithm>
#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <span>
#include <stdexcept>
#include <vector>

#include "raykit/bvh/depth.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/bvh/sanitize.hpp"
#include "raykit/simd/isa.hpp"
#include "raykit/util/parallel.hpp"
#include "raykit/util/raw_array.hpp"

namespace raykit {

namespace detail {

/// An AABB grown four lanes at a time (lane 3 unused), by AABB::grow's rule: MINPS(candidate,
/// current) is robust_min(candidate, current) lane by lane, NaN candidates included, so a box
/// grown here equals the AABB grown one coordinate at a time, bit for bit. The builder's passes
/// spend most of their time growing boxes (binning, bin sweeps, partitions).
struct GrowBox {
#if RAYKIT_ISA_X86
    __m128 lo = _mm_set1_ps(kInf), hi = _mm_set1_ps(-kInf);
    /// Grows by the box with corners at mn and mx; 4 floats must be readable at each.
    RAYKIT_INLINE void grow(const float* mn, const float* mx) noexcept {
        lo = _mm_min_ps(_mm_loadu_ps(mn), lo);
        hi = _mm_max_ps(_mm_loadu_ps(mx), hi);
    }
    /// Grows by a point; 4 floats must be readable at p.
    RAYKIT_INLINE void grow(const float* p) noexcept {
        const __m128 v = _mm_loadu_ps(p);
        lo = _mm_min_ps(v, lo);
        hi = _mm_max_ps(v, hi);
    }
    RAYKIT_INLINE void grow(const GrowBox& b) noexcept {
        lo = _mm_min_ps(b.lo, lo);
        hi = _mm_max_ps(b.hi, hi);
    }
    RAYKIT_INLINE AABB aabb() const noexcept {
        alignas(16) float a[4], b[4];
        _mm_store_ps(a, lo);
        _mm_store_ps(b, hi);
        return {vec3(a[0], a[1], a[2]), vec3(b[0], b[1], b[2])};
    }
    /// AABB::half_area's expression on the same extent (0 when empty or NaN).
    RAYKIT_INLINE float half_area() const noexcept {
        if ((_mm_movemask_ps(_mm_cmple_ps(lo, hi)) & 7) != 7) return 0.0f;
        alignas(16) float e[4];
        _mm_store_ps(e, _mm_sub_ps(hi, lo));
        return e[0] * e[1] + e[1] * e[2] + e[2] * e[0];
    }
#else
    AABB box;
    RAYKIT_INLINE void grow(const float* mn, const float* mx) noexcept {
        box.grow(AABB{vec3(mn[0], mn[1], mn[2]), vec3(mx[0], mx[1], mx[2])});
    }
    RAYKIT_INLINE void grow(const float* p) noexcept { box.grow(vec3(p[0], p[1], p[2])); }
    RAYKIT_INLINE void grow(const GrowBox& b) noexcept { box.grow(b.box); }
    RAYKIT_INLINE AABB aabb() const noexcept { return box; }
    RAYKIT_INLINE float half_area() const noexcept { return box.half_area(); }
#endif
};

/// A bin's box as binning grows it. Where the compiler targets AVX it is (min, −max) in one
/// 8-float vector (lanes 3 and 7 unused), so a record grows it with one minimum where GrowBox
/// takes a minimum and a maximum; a minimum of negated maxima is the negated maximum, NaN
/// candidates included (negation is exact), so box() is the GrowBox grown by the same records,
/// bit for bit. Elsewhere it is a GrowBox. Binning a record into its three bins took 40 % of a
/// 100k-triangle build's samples (perf); in a loop over the torus's records the 8-float form
/// bins them 1.5x as fast (8.7-14.0 -> 5.7-9.4 ns a record).
struct BinBox {
#if RAYKIT_ISA_X86 && defined(__AVX__)
    using Corners = __m256;  ///< a record as bins grow by it
    __m256 v = _mm256_set1_ps(kInf);
    /// A record's corners, from 4 readable floats at each of mn and mx.
    static RAYKIT_INLINE void corners(const float* mn, const float* mx, Corners& out) noexcept {
        out = _mm256_xor_ps(_mm256_loadu2_m128(mx, mn), _mm256_setr_ps(0.0f, 0.0f, 0.0f, 0.0f, -0.0f, -0.0f, -0.0f, -0.0f));
    }
    /// MINPS(candidate, current), GrowBox's rule.
    RAYKIT_INLINE void grow(const Corners& c) noexcept { v = _mm256_min_ps(c, v); }
    RAYKIT_INLINE void grow(const BinBox& b) noexcept { v = _mm256_min_ps(b.v, v); }
    RAYKIT_INLINE GrowBox box() const noexcept {
        GrowBox g;
        g.lo = _mm256_castps256_ps128(v);
        g.hi = _mm_xor_ps(_mm256_extractf128_ps(v, 1), _mm_set1_ps(-0.0f));
        return g;
    }
#else
    struct Corners {
        const float* mn;
        const float* mx;
    };
    GrowBox g;
    static RAYKIT_INLINE void corners(const float* mn, const float* mx, Corners& out) noexcept { out = {mn, mx}; }
    RAYKIT_INLINE void grow(const Corners& c) noexcept { g.grow(c.mn, c.mx); }
    RAYKIT_INLINE void grow(const BinBox& b) noexcept { g.grow(b.g); }
    RAYKIT_INLINE GrowBox box() const noexcept { return g; }
#endif
    RAYKIT_INLINE float half_area() const noexcept { return box().half_area(); }
};

}  // namespace detail

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
        const unsigned threads = resolve_threads(cfg.threads);
        // one team for the build's passes and its pool (a one-call team per pass cost ~56 µs to
        // start each, nine of them per bunny build on two threads)
        const bool pooled = threads > 1 && n >= cfg.parallel_threshold;
        detail::WorkTeam team(pooled || (threads > 1 && n >= detail::kMinParallelPass) ? threads : 1u);
        Impl impl{{}, cfg, threads, team.size() > 1 ? &team : nullptr, nullptr};
        {
            const detail::SanitizedCenters c = detail::sanitize_centers(centers, threads, impl.team);
            impl.refs.resize(n);
            detail::for_range(0, n, threads, impl.team,
                              [&](std::size_t i) { impl.refs[i] = {boxes[i], c[i], static_cast<std::uint32_t>(i)}; });
        }
        AABB box, cbox;
        impl.bounds(0, n, box, cbox);
        detail::TaskQueue<Task> pool;
        if (pooled) impl.pool = &pool;
        Buf top(n, impl.forks(n));
        // the root splits here, its passes on the team; when it forks, both its subtrees wait
        // in the pool, which the team then drains (their passes may not use the team meanwhile)
        impl.node(top, 0, 0, n, 0, box, cbox);
        if (impl.pool) {
            detail::WorkTeam* const own = impl.team;
            impl.team = nullptr;
            pool.drain(team, [&](const Task& t) { impl.node(*t.buf, 0, t.b, t.e, t.depth, t.box, t.cbox); });
            impl.team = own;
        }
        if (!top.kids[0]) {
            bvh.nodes = std::move(top.nodes);
        } else {
            bvh.nodes.resize(top.size());
            std::vector<Placed> unforked;
            top.layout(bvh.nodes.data(), 0, 1, unforked);
            detail::run_chunks(impl.team, threads, unforked.size(), unforked.size(),
                               [&](std::size_t, std::size_t lo, std::size_t hi) {
                                   for (std::size_t k = lo; k < hi; ++k)
                                       unforked[k].buf->copy(bvh.nodes.data(), unforked[k].at, unforked[k].next);
                               });
        }
        bvh.prim_ids.resize(n);
        detail::for_range(0, n, threads, impl.team, [&](std::size_t i) { bvh.prim_ids[i] = impl.refs[i].id; });
        return bvh;
    }

private:
    struct Bin {
        detail::BinBox box;
        std::uint32_t count = 0;
    };

    /// What the builder partitions: a primitive's box, centroid and index,
    /// kept together so each pass streams through memory (and the 4-float loads of
    /// GrowBox stay inside a record: max is followed by c, c by id).
    struct Ref {
        AABB box;
        vec3 c;
        std::uint32_t id;
        RAYKIT_INLINE void grow_box(detail::GrowBox& g) const noexcept { g.grow(&box.min.x, &box.max.x); }
        RAYKIT_INLINE void grow_center(detail::GrowBox& g) const noexcept { g.grow(&c.x); }
    };
    static_assert(offsetof(Ref, c) == offsetof(Ref, box) + sizeof(AABB) && offsetof(Ref, id) == offsetof(Ref, c) + 12);

    struct Buf;
    /// An unforked Buf and where its nodes go (Buf::layout).
    struct Placed {
        const Buf* buf;
        std::size_t at, next;
    };
    /// The nodes of one subtree in their final order (depth-first pre-order, children in adjacent
    /// pairs, compact_preorder's layout), indices local to it (its root at 0). A node splits by
    /// appending its children's pair, then builds the left subtree whole, then the right, which is
    /// that order. A node that forks keeps only itself here, and each child's subtree goes into
    /// a Buf of its own, built by whichever thread takes it; layout() and copy() then put them
    /// together. (The builder used to write every node into 2n−1 zeroed slots and reorder them
    /// afterwards: two passes on one thread, 1.6 ms each of a 16.3 ms bunny build on two threads.)
    struct alignas(64) Buf {
        NodeArray nodes;
        std::unique_ptr<Buf> kids[2];  ///< the forked children's subtrees, or none
        /// `prims`: the subtree's primitive count; `forks`: whether its root will hand its
        /// children on (then it keeps one node, where 2·prims − 1 is the most a subtree needs:
        /// reserving that for every handed-off subtree too reserved 612 MB, untouched but
        /// reserved, for the 12 MB of nodes of the 1M-triangle torus on two threads; 64 MB now).
        Buf(std::uint32_t prims, bool forks) {
            nodes.reserve(forks ? 1 : 2 * std::size_t(prims) - 1);
            nodes.resize(1);
        }
        /// Appends a pair of nodes; returns the first's index.
        std::uint32_t pair() {
            const auto first = static_cast<std::uint32_t>(nodes.size());
            nodes.resize(first + 2);
            return first;
        }
        std::size_t size() const noexcept { return kids[0] ? 1 + kids[0]->size() + kids[1]->size() : nodes.size(); }
        /// Lays the subtree out in `out`, its root at `at` and the rest from `next` on: writes the
        /// forked nodes and lists each unforked Buf with its place, for copy() to write on any
        /// thread (the ranges are disjoint). Returns where the next subtree's nodes begin.
        std::size_t layout(Node* out, std::size_t at, std::size_t next, std::vector<Placed>& unforked) const {
            if (kids[0]) {
                out[at] = nodes[0];
                out[at].index = static_cast<std::uint32_t>(next);
                return kids[1]->layout(out, next + 1, kids[0]->layout(out, next, next + 2, unforked), unforked);
            }
            unforked.push_back({this, at, next});
            return next + nodes.size() - 1;
        }
        /// Writes an unforked Buf's nodes: its root at `at`, the rest from `next` on.
        void copy(Node* out, std::size_t at, std::size_t next) const {
            auto place = [&](std::size_t j) { return j == 0 ? at : next + j - 1; };
            for (std::size_t j = 0; j < nodes.size(); ++j) {
                Node nd = nodes[j];
                if (!nd.is_leaf()) nd.index = static_cast<std::uint32_t>(place(nd.index));
                out[place(j)] = nd;
            }
        }
    };

    /// A subtree waiting for a thread (detail::TaskQueue): refs[b, e) into task.buf's root.
    struct Task {
        Buf* buf;
        std::uint32_t b, e;
        int depth;
        AABB box, cbox;
    };
    struct Impl {
        detail::RawArray<Ref> refs;  ///< every record written by build() before any pass reads it
        Config cfg;
        unsigned threads;
        /// The build's team while no pool drains on it (null on one thread, and inside the pool's
        /// tasks, whose large passes start teams of their own).
        detail::WorkTeam* team;
        /// Subtrees for other threads (a node of at least parallel_threshold primitives at a
        /// Buf's root hands its right child here and goes on with its left; the tree's root, split
        /// before the drain, hands both); null on one thread.
        detail::TaskQueue<Task>* pool;

        /// Whether a Buf's root over `prims` primitives hands its children on (children()).
        bool forks(std::size_t prims) const noexcept { return pool && prims >= cfg.parallel_threshold; }

        static constexpr std::size_t kParallelPass = 65536;

        /// The threads a pass over n records runs on: the build's team from kMinParallelPass on;
        /// inside the pool's tasks, from kParallelPass on, a team of its own of this thread and
        /// the members the pool can lend it (TaskQueue::borrow: those no subtree occupies, as the
        /// first subtrees leave them on many cores), given back when the pass ends. A team of
        /// `threads` there ran beside the other busy members: on two threads the 1M-triangle
        /// torus's BlockBvh8::build took 7 % longer than with no team at all in the tasks
        /// (median of 12 paired builds).
        struct PassThreads {
            detail::TaskQueue<Task>* pool = nullptr;  ///< the pool that lent members, if any
            unsigned lent = 0;                         ///< members borrowed from it
            unsigned count = 1;                        ///< threads the pass runs on
            PassThreads(const Impl& impl, std::size_t n) {
                if (impl.threads <= 1) return;
                if (impl.team) {
                    count = n >= detail::kMinParallelPass ? impl.threads : 1u;
                } else if (n >= kParallelPass && impl.pool) {
                    pool = impl.pool;
                    lent = pool->borrow(impl.threads - 1);
                    count = 1 + lent;
                }
            }
            ~PassThreads() {
                if (lent) pool->give_back(lent);
            }
            PassThreads(const PassThreads&) = delete;
            PassThreads& operator=(const PassThreads&) = delete;
        };

        void bounds(std::uint32_t b, std::uint32_t e, AABB& box, AABB& cbox) const {
            auto pass = [&](std::size_t lo, std::size_t hi, AABB& bx, AABB& cb) {
                detail::GrowBox gb, gc;
                for (std::size_t i = lo; i < hi; ++i) {
                    refs[i].grow_box(gb);
                    refs[i].grow_center(gc);
                }
                bx.grow(gb.aabb());
                cb.grow(gc.aabb());
            };
            const std::size_t n = e - b;
            const PassThreads pt(*this, n);
            if (pt.count <= 1) {
                pass(b, e, box, cbox);
                return;
            }
            constexpr std::size_t kChunks = 16;
            std::array<AABB, kChunks> bx{}, cb{};
            detail::run_chunks(team, pt.count, n, kChunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
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
            /// index() on the three axes at once (c: 4 readable floats): the same f per lane,
            /// then max(f, 0) and min(f, nb − 1) before truncating, which is index()'s clamp.
            RAYKIT_INLINE void index3(const float* c, std::uint32_t* k) const {
#if RAYKIT_ISA_X86
                const __m128 f = _mm_mul_ps(_mm_sub_ps(_mm_loadu_ps(c), _mm_setr_ps(lo.x, lo.y, lo.z, 0.0f)),
                                            _mm_setr_ps(scale.x, scale.y, scale.z, 0.0f));
                const __m128 g = _mm_min_ps(_mm_max_ps(f, _mm_setzero_ps()), _mm_set1_ps(float(nb - 1)));
                alignas(16) std::int32_t out[4];
                _mm_store_si128(reinterpret_cast<__m128i*>(out), _mm_cvttps_epi32(g));
                for (int a = 0; a < 3; ++a) k[a] = std::uint32_t(out[a]);
#else
                const vec3 v(c[0], c[1], c[2]);
                for (int a = 0; a < 3; ++a) k[a] = std::uint32_t(index(v, a));
#endif
            }
        };

        void bin(std::uint32_t b, std::uint32_t e, const Binner& bn, std::vector<Bin>& out) const {
            const std::size_t nb = bn.nb;
            auto pass = [&](std::size_t lo, std::size_t hi, Bin* dst) {
                for (std::size_t i = lo; i < hi; ++i) {
                    const Ref& r = refs[i];
                    std::uint32_t k[3];
                    bn.index3(&r.c.x, k);
                    detail::BinBox::Corners c;
                    detail::BinBox::corners(&r.box.min.x, &r.box.max.x, c);
                    Bin& bxn = dst[k[0]];
                    Bin& byn = dst[nb + k[1]];
                    Bin& bzn = dst[2 * nb + k[2]];
                    bxn.box.grow(c), ++bxn.count;
                    byn.box.grow(c), ++byn.count;
                    bzn.box.grow(c), ++bzn.count;
                }
            };
            out.assign(3 * nb, Bin{});
            const std::size_t n = e - b;
            const PassThreads pt(*this, n);
            if (pt.count <= 1) {
                pass(b, e, out.data());
                return;
            }
            constexpr std::size_t kChunks = 16;
            std::vector<Bin> part(kChunks * 3 * nb);
            detail::run_chunks(team, pt.count, n, kChunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
                pass(b + lo, b + hi, part.data() + c * 3 * nb);
            });
            for (std::size_t c = 0; c < kChunks; ++c)
                for (std::size_t k = 0; k < 3 * nb; ++k) {
                    out[k].box.grow(part[c * 3 * nb + k].box);
                    out[k].count += part[c * 3 * nb + k].count;
                }
        }

        static constexpr std::uint32_t kSweepMax = 16;

        struct SweepResult {
            int axis = -1;
            std::uint32_t split = 0;  ///< left child = the first `split` records
            float cost = kInf;        ///< SA(L)·|L| + SA(R)·|R|, half areas
        };

        /// A subtree of at most kSweepMax primitives, built by exact SAH sweeps: its records
        /// (copied once), their boxes, and per node each axis' order of its records (local
        /// indices) by (centroid, primitive index), a strict order, so where records sit never
        /// matters. The orders are ranked once, at the subtree's root; a child's are its
        /// parent's, filtered (an order restricted to a subset is the subset's order). Records are written to refs
        /// once, where a leaf ends up, in the order the node that made it left them. (Sorting the
        /// 40-byte records three times per node took 38 % of a bunny build; ranking each node's
        /// records again on three axes, then moving them, took 30 % of it after that: the
        /// same trees are now built 1.2-1.3x faster, bunny 1 thread 34.5 -> 26-28 ms.)
        struct Small {
            Ref rec[kSweepMax];
            detail::GrowBox box[kSweepMax];
        };
        using Order = std::uint8_t[3][kSweepMax];

        /// Exact SAH sweep over the n records in `o`: tries all n-1 splits of each axis' order.
        SweepResult sweep(const Small& sm, const Order& o, std::uint32_t n) const {
            SweepResult best;
            for (int a = 0; a < 3; ++a) {
                float rarea[kSweepMax];
                detail::GrowBox acc;
                for (std::uint32_t k = n - 1; k > 0; --k) {
                    acc.grow(sm.box[o[a][k]]);
                    rarea[k] = acc.half_area();
                }
                acc = detail::GrowBox{};
                for (std::uint32_t k = 1; k < n; ++k) {
                    acc.grow(sm.box[o[a][k - 1]]);
                    const float c = acc.half_area() * cfg.leaf.blocks(k) + rarea[k] * cfg.leaf.blocks(n - k);
                    if (c < best.cost) best = {a, k, c};
                }
            }
            return best;
        }

        /// Writes the records of `ids` (n local indices) to refs[b, b + n) in that order.
        void place(const Small& sm, const std::uint8_t* ids, std::uint32_t b, std::uint32_t n) {
            for (std::uint32_t k = 0; k < n; ++k) refs[b + k] = sm.rec[ids[k]];
        }

        /// The root of a small subtree (kSweepMax records at most, depth < kMedianDepth, more
        /// than min_leaf_size): copies the records and ranks their orders.
        void small_root(Buf& buf, std::uint32_t node, std::uint32_t b, std::uint32_t e, int depth, const AABB& box) {
            const std::uint32_t n = e - b;
            Small sm;
            Order o;
            for (std::uint32_t k = 0; k < n; ++k) {
                sm.rec[k] = refs[b + k];
                sm.rec[k].grow_box(sm.box[k]);
            }
            for (int a = 0; a < 3; ++a) {
                // (centroid, index) as one integer key whose order is sort_axis' (centroids
                // are finite: bvh/sanitize.hpp; −0 counts as +0, as == does), then each
                // record's rank by counting smaller keys: no data-dependent branch, where
                // an insertion sort's compares mispredicted about half the time
                std::uint64_t key[kSweepMax];
                for (std::uint32_t k = 0; k < kSweepMax; ++k) {
                    if (k >= n) {
                        key[k] = ~std::uint64_t(0);
                        continue;
                    }
                    const std::uint32_t bits = std::bit_cast<std::uint32_t>(sm.rec[k].c[a] + 0.0f);
                    const std::uint32_t ordered = bits & 0x80000000u ? ~bits : bits | 0x80000000u;
                    key[k] = std::uint64_t(ordered) << 32 | sm.rec[k].id;
                }
                for (std::uint32_t i = 0; i < n; ++i) {
                    std::uint32_t rank = 0;
                    for (std::uint32_t j = 0; j < kSweepMax; ++j) rank += key[j] < key[i];
                    o[a][rank] = std::uint8_t(i);
                }
            }
            small(sm, o, buf, node, b, e, depth, box, -1);
        }

        /// A node of a small subtree over the records of `o`; `cur` is the axis whose order its
        /// records are in (the parent's split axis; -1: as they are in refs).
        void small(const Small& sm, const Order& o, Buf& buf, std::uint32_t node, std::uint32_t b, std::uint32_t e,
                   int depth, const AABB& box, int cur) {
            const std::uint32_t n = e - b;
            if (cur >= 0 && (n <= std::max(1u, cfg.min_leaf_size) || depth >= kMedianDepth)) {
                place(sm, o[cur], b, n);  // as node() has them: a leaf, or a median split
                return this->node(buf, node, b, e, depth, box, records_bounds(sm, o[0], n).second);
            }
            const SweepResult sw = sweep(sm, o, n);
            const int axis = sw.axis >= 0 ? sw.axis : 2;  // the order the sweep leaves them in
            const float sa = box.half_area();
            const float split_cost = cfg.leaf.traversal_cost * sa + cfg.leaf.intersection_cost * sw.cost;
            if (n <= cfg.leaf.max_leaf_size && cfg.leaf.leaf_cost(sa, n) <= split_cost) {
                place(sm, o[axis], b, n);
                return make_leaf(buf, node, b, e, box);
            }
            if (sw.axis < 0) {  // no split of finite cost: node()'s median split, on refs
                place(sm, o[axis], b, n);
                const auto [bx, cb] = records_bounds(sm, o[axis], n);
                return split(buf, node, b, median(b, e, max_axis(cb.extent())), e, depth, box);
            }
            // the children's orders: the split axis' order cut in two, the others filtered
            Order lo, ro;
            bool left[kSweepMax];
            for (std::uint32_t k = 0; k < n; ++k) left[o[axis][k]] = k < sw.split;
            for (int a = 0; a < 3; ++a) {
                std::uint32_t nl = 0, nr = 0;
                for (std::uint32_t k = 0; k < n; ++k) {
                    const std::uint8_t id = o[a][k];
                    if (left[id]) lo[a][nl++] = id;
                    else ro[a][nr++] = id;
                }
            }
            const std::uint32_t mid = b + sw.split, nl = sw.split;
            const std::uint32_t first = buf.pair();
            Node& nd = buf.nodes[node];
            nd.box = box;
            nd.index = first;
            nd.count = 0;
            small(sm, lo, buf, first, b, mid, depth + 1, records_bounds(sm, lo[0], nl).first, axis);
            small(sm, ro, buf, first + 1, mid, e, depth + 1, records_bounds(sm, ro[0], n - nl).first, axis);
        }

        /// The bounds of the boxes and of the centroids of n records (bounds()' rule).
        static std::pair<AABB, AABB> records_bounds(const Small& sm, const std::uint8_t* ids, std::uint32_t n) {
            detail::GrowBox gb, gc;
            for (std::uint32_t k = 0; k < n; ++k) {
                gb.grow(sm.box[ids[k]]);
                sm.rec[ids[k]].grow_center(gc);
            }
            return {gb.aabb(), gc.aabb()};
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

        void make_leaf(Buf& buf, std::uint32_t node, std::uint32_t b, std::uint32_t e, const AABB& box) {
            Node& nd = buf.nodes[node];
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

        /// Builds the subtree of refs[b, e) into buf.nodes[node]; `box`/`cbox` are the
        /// bounds of the primitives' boxes and centroids (from the parent's
        /// partition pass).
        void node(Buf& buf, std::uint32_t node, std::uint32_t b, std::uint32_t e, int depth, const AABB& box,
                  const AABB& cbox) {
            const std::uint32_t n = e - b;
            if (n <= std::max(1u, cfg.min_leaf_size)) return make_leaf(buf, node, b, e, box);

            std::uint32_t mid = 0;
            const vec3 ext = cbox.extent();
            const int widest = max_axis(ext);
            AABB lbox, lcbox, rbox, rcbox;
            bool have_bounds = false;
            if (depth >= kMedianDepth) {
                mid = median(b, e, widest);
            } else if (n <= kSweepMax) {
                // small node: exact SAH over all n-1 splits of each axis' sorted order
                return small_root(buf, node, b, e, depth, box);
            } else if (!(ext[widest] > 0.0f)) {
                // all centroids coincide: nothing to bin
                if (n <= cfg.leaf.max_leaf_size) return make_leaf(buf, node, b, e, box);
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
                    detail::BinBox acc;
                    std::uint32_t cnt = 0;
                    for (std::size_t k = nb - 1; k > 0; --k) {
                        acc.grow(ab[k].box);
                        cnt += ab[k].count;
                        sc.rarea[k] = acc.half_area();
                        sc.rcount[k] = cnt;
                    }
                    acc = detail::BinBox{};
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
                    return make_leaf(buf, node, b, e, box);
                if (best_axis < 0) {
                    mid = median(b, e, widest);
                } else {
                    detail::GrowBox gl, glc, gr, grc;
                    mid = partition(b, e, bn, best_axis, best_split, gl, glc, gr, grc);
                    lbox = gl.aabb();
                    lcbox = glc.aabb();
                    rbox = gr.aabb();
                    rcbox = grc.aabb();
                    have_bounds = true;
                    if (mid == b || mid == e) {
                        mid = median(b, e, widest);
                        have_bounds = false;
                    }
                }
            }
            if (!have_bounds) return split(buf, node, b, mid, e, depth, box);
            children(buf, node, b, mid, e, depth, box, lbox, lcbox, rbox, rcbox);
        }

        /// Moves the records of refs[b, e) whose bin on `axis` is below `split` to the front;
        /// returns where the rest begin, and grows gl/glc (gr/grc) by the boxes and centroids of
        /// the front (back) ones. Blocks of kBlock records from both ends are classified
        /// without a branch (the offsets of the misplaced ones listed, as in Edelkamp and
        /// Weiß's BlockQuicksort) and misplaced pairs swapped; the last 2·kBlock or fewer go one
        /// by one. A record's side was a branch that mispredicted about half the time: the
        /// same trees (84 hashed configurations) are built 7-14 % faster, binned SAH alone on
        /// one thread bunny 20.15 -> 17.27 ms and 100k torus 25.51 -> 23.77, on two bunny
        /// 10.93 -> 9.46 (medians of 6 interleaved processes, each a median of 21 builds).
        /// A finished block is grown into its side's bounds at once, while it is in L1; the
        /// bounds used to be a second pass over the records (40 MB at the 1M-triangle torus's
        /// root): its BlockBvh8::build on two threads 1.03x as fast (median of 12 paired builds).
        RAYKIT_INLINE std::uint32_t partition(std::uint32_t b, std::uint32_t e, const Binner& bn, int axis, std::size_t split,
                                detail::GrowBox& gl, detail::GrowBox& glc, detail::GrowBox& gr, detail::GrowBox& grc) {
            constexpr std::uint32_t kBlock = 64;
            // index()'s bin, clamped before the truncation as index3 does (no branch)
            const auto a = static_cast<std::size_t>(axis);
            const float lo = bn.lo[axis], scale = bn.scale[axis], last = static_cast<float>(bn.nb - 1);
            const auto front = [&](const Ref& r) {
                float f = ((&r.c.x)[a] - lo) * scale;
                f = f > 0.0f ? f : 0.0f;
                f = f < last ? f : last;
                return static_cast<std::size_t>(f) < split;
            };
            std::uint32_t i = b, j = e;  // [b, i) front, [j, e) back
            std::uint8_t wrong_l[kBlock], wrong_r[kBlock];  // misplaced offsets in the blocks at i and below j
            std::uint32_t nl = 0, nr = 0, fl = 0, fr = 0;
            while (j - i >= 2 * kBlock) {
                if (nl == 0) {
                    fl = 0;
                    for (std::uint32_t k = 0; k < kBlock; ++k) {
                        wrong_l[nl] = static_cast<std::uint8_t>(k);
                        nl += !front(refs[i + k]);
                    }
                }
                if (nr == 0) {
                    fr = 0;
                    for (std::uint32_t k = 0; k < kBlock; ++k) {
                        wrong_r[nr] = static_cast<std::uint8_t>(k);
                        nr += front(refs[j - 1 - k]);
                    }
                }
                const std::uint32_t m = std::min(nl, nr);
                for (std::uint32_t k = 0; k < m; ++k) std::swap(refs[i + wrong_l[fl + k]], refs[j - 1 - wrong_r[fr + k]]);
                nl -= m, nr -= m, fl += m, fr += m;
                // a finished block is grown into its side's bounds while it is in L1
                if (nl == 0) {
                    for (std::uint32_t k = i; k < i + kBlock; ++k) refs[k].grow_box(gl), refs[k].grow_center(glc);
                    i += kBlock;
                }
                if (nr == 0) {
                    for (std::uint32_t k = j - kBlock; k < j; ++k) refs[k].grow_box(gr), refs[k].grow_center(grc);
                    j -= kBlock;
                }
            }
            while (i < j) {  // the rest (a block with misplaced records left in it included)
                const Ref& r = refs[i];
                if (front(r)) {
                    r.grow_box(gl);
                    r.grow_center(glc);
                    ++i;
                } else {
                    --j;
                    r.grow_box(gr);
                    r.grow_center(grc);
                    std::swap(refs[i], refs[j]);
                }
            }
            return i;
        }

        /// An inner node split at mid, the children's bounds from their records.
        void split(Buf& buf, std::uint32_t node, std::uint32_t b, std::uint32_t mid, std::uint32_t e, int depth,
                   const AABB& box) {
            AABB lbox, lcbox, rbox, rcbox;
            bounds(b, mid, lbox, lcbox);
            bounds(mid, e, rbox, rcbox);
            children(buf, node, b, mid, e, depth, box, lbox, lcbox, rbox, rcbox);
        }

        /// Writes the inner node and builds its two children (the right one in the pool when
        /// the node is large; both when it is the root, before the drain).
        void children(Buf& buf, std::uint32_t node, std::uint32_t b, std::uint32_t mid, std::uint32_t e, int depth,
                      const AABB& box, const AABB& lbox, const AABB& lcbox, const AABB& rbox, const AABB& rcbox) {
            // only a Buf's root forks (so did its parent, by the same rule: a larger node)
            const bool fork = node == 0 && forks(e - b);
            const std::uint32_t first = fork ? 0 : buf.pair();
            Node& nd = buf.nodes[node];
            nd.box = box;
            nd.index = first;  // when forking, layout() sets it
            nd.count = 0;
            if (!fork) {
                this->node(buf, first, b, mid, depth + 1, lbox, lcbox);
                this->node(buf, first + 1, mid, e, depth + 1, rbox, rcbox);
                return;
            }
            buf.kids[0] = std::make_unique<Buf>(mid - b, forks(mid - b));
            buf.kids[1] = std::make_unique<Buf>(e - mid, forks(e - mid));
            pool->push({buf.kids[1].get(), mid, e, depth + 1, rbox, rcbox}, e - mid);
            if (team) return pool->push({buf.kids[0].get(), b, mid, depth + 1, lbox, lcbox}, mid - b);  // the root, before the drain
            this->node(*buf.kids[0], 0, b, mid, depth + 1, lbox, lcbox);
        }
    };
};

}  // namespace raykit
