// raykit/bvh/collapse.hpp — the shared back end of the bottom-up builders
// (PairwiseBuilder, SortAxisBuilder, PlocBuilder) and the helpers they share.
//
// A bottom-up builder records only the merge topology, as a detail::MergeTree:
// node ids 0..n-1 are the primitives, and every merge appends one inner node
// (id n + k) with two child ids; every node but the last root is merged
// exactly once. Merges come in batches (a level, an iteration): a batch's
// nodes have children only among the primitives and earlier batches.
// detail::finish_bottom_up then turns that into a Bvh:
//
//   1. Depth limit (detail::limit_depth). Subtrees that would end deeper than
//      RAYKIT_BVH_MAX_DEPTH are rebuilt with median splits (proof at the
//      function). A node of batch b has height ≤ b + 1, so this only runs
//      when there are more batches than RAYKIT_BVH_MAX_DEPTH and the tree is
//      actually too deep (PLOC on chain-like inputs; pairwise and
//      sort-by-axis halve the element count per level and never need it).
//   2. Leaf collapse, bottom-up over the real primitive boxes: a subtree of
//      n ≤ max_leaf_size primitives becomes one leaf when
//        Ci·SA·n ≤ Ct·SA + cost(left) + cost(right)
//      (its SAH cost, with the children's best costs; SA = half area).
//      Collapsing only removes levels, so the depth bound still holds.
//   3. Output in depth-first pre-order with children side by side: exactly
//      the layout detail::compact_preorder produces, written directly, batch
//      by batch from the root down (after a depth cut: recursively). A
//      leaf's primitives are contiguous in prim_ids, in the merge tree's
//      left-to-right order.
// Steps 2 and 3 split large batches among threads; every node's result
// depends only on the tree, so the output is the same for any thread count.
//
// Also here (raykit::detail): centroid sanitizing, "working" boxes (finite,
// non-empty stand-ins for empty or non-finite primitive boxes, used for
// decisions only; the output boxes are always the real ones), Morton codes,
// stable parallel LSD radix sorts, and WorkTeam, the threads a bottom-up
// build keeps for its many short passes. The optional post-pass that may run
// between the builder and this back end is in bvh/optimize.hpp.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <cstring>
#include <exception>
#include <limits>
#include <new>
#include <span>
#include <thread>
#include <type_traits>
#include <utility>
#include <vector>

#include "raykit/bvh/depth.hpp"
#include "raykit/bvh/node.hpp"
#include "raykit/bvh/sah.hpp"
#include "raykit/util/parallel.hpp"

namespace raykit {

/// Leaf-collapse settings shared by the bottom-up builders (each builder's
/// Config carries the same fields with the same defaults).
struct LeafCollapseConfig {
    unsigned max_leaf_size = 8;       ///< subtrees of more primitives are never collapsed (0 acts as 1)
    float traversal_cost = 1.0f;      ///< Ct, cost of visiting an inner node
    float intersection_cost = 1.0f;   ///< Ci, cost of one ray/triangle test (of one block, below)
    /// Primitives tested together: n of them cost Ci·ceil(n / leaf_block).
    /// 1 for one-at-a-time tests, 4 for 4-triangle SIMD blocks (scene/block_bvh.hpp).
    unsigned leaf_block = 1;

    /// The SAH weight of n primitives in one leaf (bvh/sah.hpp).
    float blocks(std::uint32_t n) const noexcept { return leaf_block_weight(n, leaf_block); }
};

namespace detail {

inline constexpr float kFloatMax = std::numeric_limits<float>::max();

/// Array storage that is not initialised: large scratch arrays are first
/// touched (and page-faulted) by the threads that fill them instead of by
/// one thread zeroing them. For trivially copyable, implicit-lifetime
/// element types; every element is written before it is read.
template <class T>
class RawArray {
    static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);

public:
    RawArray() = default;
    explicit RawArray(std::size_t n) { resize(n); }
    RawArray(const RawArray& o) : RawArray(o.n_) {
        if (n_) std::memcpy(static_cast<void*>(p_), o.p_, n_ * sizeof(T));
    }
    RawArray(RawArray&& o) noexcept { swap(o); }
    RawArray& operator=(RawArray o) noexcept {
        swap(o);
        return *this;
    }
    ~RawArray() { release(); }
    void swap(RawArray& o) noexcept {
        std::swap(p_, o.p_);
        std::swap(n_, o.n_);
        std::swap(cap_, o.cap_);
    }

    /// Keeps the first min(size, n) elements; new ones are uninitialised.
    void resize(std::size_t n) {
        if (n > cap_) reserve(std::max(n, cap_ + cap_ / 2));
        n_ = n;
    }
    void reserve(std::size_t cap) {
        if (cap <= cap_) return;
        T* q = static_cast<T*>(::operator new(cap * sizeof(T), std::align_val_t(alignof(T))));
        if (n_) std::memcpy(static_cast<void*>(q), p_, n_ * sizeof(T));
        release();
        p_ = q;
        cap_ = cap;
    }
    void push_back(const T& v) {
        if (n_ == cap_) reserve(std::max<std::size_t>(16, cap_ * 2));
        p_[n_++] = v;
    }
    void clear() noexcept { n_ = 0; }

    T* data() noexcept { return p_; }
    const T* data() const noexcept { return p_; }
    std::size_t size() const noexcept { return n_; }
    bool empty() const noexcept { return n_ == 0; }
    T& operator[](std::size_t i) noexcept { return p_[i]; }
    const T& operator[](std::size_t i) const noexcept { return p_[i]; }
    T& back() noexcept { return p_[n_ - 1]; }
    const T& back() const noexcept { return p_[n_ - 1]; }
    T* begin() noexcept { return p_; }
    T* end() noexcept { return p_ + n_; }
    const T* begin() const noexcept { return p_; }
    const T* end() const noexcept { return p_ + n_; }
    operator std::span<const T>() const noexcept { return {p_, n_}; }  // NOLINT implicit

private:
    void release() noexcept {
        if (p_) ::operator delete(static_cast<void*>(p_), std::align_val_t(alignof(T)));
        p_ = nullptr;
        cap_ = 0;
    }
    T* p_ = nullptr;
    std::size_t n_ = 0, cap_ = 0;
};

/// A fixed set of threads kept for one build, for builders with many short
/// parallel passes: starting and joining a std::thread costs ~50 µs, waking
/// a waiting member a few µs. Work is split exactly as parallel_chunks
/// splits it (chunk c of [0, n) on member c % size()), so results never
/// depend on the member count. Members spin briefly, then sleep on an
/// atomic wait. Not reentrant: one pass at a time, from the owning thread.
class WorkTeam {
public:
    explicit WorkTeam(unsigned threads) : size_(std::max(1u, threads)), errors_(size_) {
        helpers_.reserve(size_ - 1);
        for (unsigned t = 1; t < size_; ++t) helpers_.emplace_back([this, t] { member_loop(t); });
    }
    WorkTeam(const WorkTeam&) = delete;
    WorkTeam& operator=(const WorkTeam&) = delete;
    ~WorkTeam() {
        if (helpers_.empty()) return;
        stop_ = true;
        gen_.fetch_add(1, std::memory_order_release);
        gen_.notify_all();
        for (std::thread& th : helpers_) th.join();
    }
    unsigned size() const noexcept { return size_; }

    /// fn(member) on every member at once (member 0 is the calling thread).
    template <class Fn>
    void each(Fn&& fn) {
        if (size_ == 1) {
            fn(0u);
            return;
        }
        using F = std::remove_reference_t<Fn>;
        ctx_ = const_cast<void*>(static_cast<const void*>(&fn));
        call_ = [](void* c, unsigned member) { (*static_cast<F*>(c))(member); };
        done_.store(0, std::memory_order_relaxed);
        gen_.fetch_add(1, std::memory_order_release);
        gen_.notify_all();
        try {
            fn(0u);
        } catch (...) {
            errors_[0] = std::current_exception();
        }
        const unsigned helpers = size_ - 1;
        for (int spin = 0;; ++spin) {
            const unsigned d = done_.load(std::memory_order_acquire);
            if (d == helpers) break;
            if (spin < kSpin) pause();
            else done_.wait(d, std::memory_order_acquire);
        }
        for (std::exception_ptr& e : errors_)
            if (e) {
                std::exception_ptr x = e;
                for (std::exception_ptr& f : errors_) f = nullptr;
                std::rethrow_exception(x);
            }
    }

    /// fn(c, lo, hi) for `chunks` contiguous chunks of [0, n) with the
    /// boundaries of parallel_chunks; one chunk (or one member) runs inline.
    template <class Fn>
    void chunks(std::size_t n, std::size_t chunks, Fn&& fn) {
        chunks = std::max<std::size_t>(1, std::min(chunks, n == 0 ? 1 : n));
        auto bounds = [&](std::size_t c) { return n * c / chunks; };
        if (chunks == 1 || size_ == 1) {
            for (std::size_t c = 0; c < chunks; ++c) fn(c, bounds(c), bounds(c + 1));
            return;
        }
        const std::size_t members = std::min<std::size_t>(size_, chunks);
        each([&](unsigned t) {
            for (std::size_t c = t; c < chunks && t < members; c += members) fn(c, bounds(c), bounds(c + 1));
        });
    }

private:
    static constexpr int kSpin = 4000;
    static void pause() noexcept {
#if defined(__x86_64__) || defined(__i386__)
        __builtin_ia32_pause();
#else
        std::this_thread::yield();
#endif
    }
    void member_loop(unsigned t) {
        std::uint32_t seen = 0;
        for (;;) {
            for (int spin = 0;; ++spin) {
                const std::uint32_t g = gen_.load(std::memory_order_acquire);
                if (g != seen) {
                    seen = g;
                    break;
                }
                if (spin < kSpin) pause();
                else gen_.wait(g, std::memory_order_acquire);
            }
            if (stop_) return;
            try {
                call_(ctx_, t);
            } catch (...) {
                errors_[t] = std::current_exception();
            }
            if (done_.fetch_add(1, std::memory_order_acq_rel) + 1 == size_ - 1) done_.notify_one();
        }
    }

    unsigned size_;
    std::vector<std::thread> helpers_;
    std::vector<std::exception_ptr> errors_;
    std::atomic<std::uint32_t> gen_{0};
    std::atomic<unsigned> done_{0};
    void (*call_)(void*, unsigned) = nullptr;
    void* ctx_ = nullptr;
    bool stop_ = false;  // written before a generation bump, read after it
};

/// Element count from which per-element passes run on several threads.
inline constexpr std::size_t kBottomUpParallelPass = 16384;

/// Chunk count for a parallel pass over m elements: depends on m only.
inline std::size_t pass_chunks(std::size_t m) noexcept {
    return m < kBottomUpParallelPass ? 1 : std::min<std::size_t>(64, m / (kBottomUpParallelPass / 4));
}

/// fn(i) for i in [0, m): on `threads` threads when m is large enough to
/// pay for starting them. For per-element work only (the result must not
/// depend on the split).
template <class Fn>
void par_for(std::size_t m, unsigned threads, Fn&& fn) {
    if (threads <= 1 || m < kBottomUpParallelPass) {
        for (std::size_t i = 0; i < m; ++i) fn(i);
        return;
    }
    parallel_chunks(m, threads, threads, [&](std::size_t, std::size_t lo, std::size_t hi) {
        for (std::size_t i = lo; i < hi; ++i) fn(i);
    });
}

/// Bounds of a set of points (finite ones only) and whether any was not
/// finite. Exact for any chunking.
inline AABB finite_point_bounds(std::span<const vec3> pts, unsigned threads, bool* any_bad = nullptr) {
    const std::size_t chunks = pass_chunks(pts.size());
    std::vector<AABB> part(chunks);
    std::vector<std::uint8_t> bad(chunks, 0);
    parallel_chunks(pts.size(), chunks, threads, [&](std::size_t c, std::size_t lo, std::size_t hi) {
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
/// finite ones, so that sorting, Morton codes and distances never see a NaN
/// (the same rule as BinnedSahBuilder).
struct SanitizedCenters {
    std::vector<vec3> copy;       ///< used only when an input centroid was not finite
    std::span<const vec3> view;   ///< the centroids to use
    AABB bounds;                  ///< bounds of the finite input centroids (empty if none)
    const vec3& operator[](std::size_t i) const noexcept { return view[i]; }
    std::size_t size() const noexcept { return view.size(); }
};

inline SanitizedCenters sanitize_centers(std::span<const vec3> centers, unsigned threads) {
    SanitizedCenters s;
    bool bad = false;
    s.bounds = finite_point_bounds(centers, threads, &bad);
    s.view = centers;
    if (bad) {
        s.copy.assign(centers.begin(), centers.end());
        const vec3 fill = s.bounds.is_empty() ? vec3(0.0f) : s.bounds.center();
        par_for(s.copy.size(), threads, [&](std::size_t i) {
            if (!is_finite(s.copy[i])) s.copy[i] = fill;
        });
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

/// Float whose unsigned bit pattern orders like the float (no NaN).
inline std::uint32_t orderable_bits(float f) noexcept {
    const std::uint32_t u = std::bit_cast<std::uint32_t>(f == 0.0f ? 0.0f : f);  // -0 == +0
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

/// Spreads the low 21 bits of x to every third bit.
inline std::uint64_t spread_bits21(std::uint64_t x) noexcept {
    x &= 0x1FFFFFull;
    x = (x | x << 32) & 0x1F00000000FFFFull;
    x = (x | x << 16) & 0x1F0000FF0000FFull;
    x = (x | x << 8) & 0x100F00F00F00F00Full;
    x = (x | x << 4) & 0x10C30C30C30C30C3ull;
    x = (x | x << 2) & 0x1249249249249249ull;
    return x;
}

/// Maps points into a cube of 2^21 cells per side around `bounds` (same
/// scale on every axis, so distances keep their proportions) and returns
/// 63-bit Morton codes.
struct MortonQuantizer {
    vec3 lo{0.0f};
    float scale = 0.0f;
    explicit MortonQuantizer(const AABB& bounds) {
        if (bounds.is_empty()) return;
        lo = bounds.min;
        const vec3 e = bounds.extent();
        const float m = std::max(e.x, std::max(e.y, e.z));
        scale = m > 0.0f && m < kInf ? 2097151.0f / m : 0.0f;
    }
    std::uint64_t operator()(const vec3& p) const noexcept {
        auto q = [&](int a) -> std::uint64_t {
            float f = (p[a] - lo[a]) * scale;
            f = f > 0.0f ? f : 0.0f;  // also maps NaN to 0
            f = f < 2097151.0f ? f : 2097151.0f;
            return static_cast<std::uint64_t>(f);
        };
        return spread_bits21(q(0)) << 2 | spread_bits21(q(1)) << 1 | spread_bits21(q(2));
    }
    /// 30-bit code (10 bits per axis, the same cube cut into 1024 cells per side).
    std::uint32_t code30(const vec3& p) const noexcept {
        auto q = [&](int a) -> std::uint32_t {
            float f = (p[a] - lo[a]) * (scale * (1.0f / 2048.0f));
            f = f > 0.0f ? f : 0.0f;
            f = f < 1023.0f ? f : 1023.0f;
            std::uint32_t x = static_cast<std::uint32_t>(f);
            x = (x | x << 16) & 0x030000FFu;
            x = (x | x << 8) & 0x0300F00Fu;
            x = (x | x << 4) & 0x030C30C3u;
            x = (x | x << 2) & 0x09249249u;
            return x;
        };
        return q(0) << 2 | q(1) << 1 | q(2);
    }
};

/// Chunk count for a radix-sort pass. A stable sort has one result, so the
/// chunking may follow the thread count.
inline std::size_t sort_chunks(std::size_t m, unsigned threads) noexcept {
    return threads <= 1 || m < kBottomUpParallelPass ? 1 : std::min<std::size_t>(64, 2 * std::size_t(threads));
}

/// Stable LSD radix sort of (keys, vals) by the low `bits` bits of the keys,
/// 11 bits per pass; passes where every key has the same digit are skipped.
/// `run(n, chunks, fn)` runs the chunked passes (parallel_chunks or a
/// WorkTeam, below).
template <class Key, class Run>
void radix_sort_with(RawArray<Key>& keys, RawArray<std::uint32_t>& vals, int bits, std::size_t chunks, Run&& run) {
    constexpr int kDigit = 11;
    constexpr std::size_t kBins = std::size_t(1) << kDigit;
    const std::size_t m = keys.size();
    if (m < 2) return;
    RawArray<Key> k2(m);
    RawArray<std::uint32_t> v2(m);
    std::vector<std::uint32_t> hist(chunks * kBins);
    for (int shift = 0; shift < bits; shift += kDigit) {
        run(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            std::fill(h, h + kBins, 0u);
            for (std::size_t i = lo; i < hi; ++i) ++h[(keys[i] >> shift) & (kBins - 1)];
        });
        // skip a pass that would not move anything
        const std::size_t d0 = (keys[0] >> shift) & (kBins - 1);
        std::size_t same = 0;
        for (std::size_t c = 0; c < chunks; ++c) same += hist[c * kBins + d0];
        if (same == m) continue;
        std::uint32_t sum = 0;
        for (std::size_t b = 0; b < kBins; ++b)
            for (std::size_t c = 0; c < chunks; ++c) {
                const std::uint32_t h = hist[c * kBins + b];
                hist[c * kBins + b] = sum;
                sum += h;
            }
        run(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            for (std::size_t i = lo; i < hi; ++i) {
                const std::uint32_t pos = h[(keys[i] >> shift) & (kBins - 1)]++;
                k2[pos] = keys[i];
                v2[pos] = vals[i];
            }
        });
        keys.swap(k2);
        vals.swap(v2);
    }
}

template <class Key>
void radix_sort(RawArray<Key>& keys, RawArray<std::uint32_t>& vals, int bits, unsigned threads) {
    radix_sort_with(keys, vals, bits, sort_chunks(keys.size(), threads),
                    [threads](std::size_t n, std::size_t chunks, auto&& fn) { parallel_chunks(n, chunks, threads, fn); });
}

template <class Key>
void radix_sort(RawArray<Key>& keys, RawArray<std::uint32_t>& vals, int bits, WorkTeam& team) {
    radix_sort_with(keys, vals, bits, sort_chunks(keys.size(), team.size()),
                    [&team](std::size_t n, std::size_t chunks, auto&& fn) { team.chunks(n, chunks, fn); });
}

/// Stable LSD radix sort of 64-bit words by their bits [lo_bit, hi_bit)
/// (typically a 32-bit key above a 32-bit payload), 11 bits per pass;
/// passes where every word has the same digit are skipped. `scratch` may be
/// reused between calls. `run(n, chunks, fn)` runs the chunked passes
/// (parallel_chunks or a WorkTeam).
template <class Run>
void radix_sort_words_with(RawArray<std::uint64_t>& a, int lo_bit, int hi_bit, std::size_t chunks, Run&& run,
                           RawArray<std::uint64_t>& scratch) {
    constexpr int kDigit = 11;
    constexpr std::size_t kBins = std::size_t(1) << kDigit;
    const std::size_t m = a.size();
    if (m < 2) return;
    if (m <= 512) {
        // Small: a comparison sort of the bits gives the same order.
        const std::uint64_t mask = (hi_bit >= 64 ? ~std::uint64_t(0) : (std::uint64_t(1) << hi_bit) - 1) &
                                   ~((std::uint64_t(1) << lo_bit) - 1);
        std::stable_sort(a.begin(), a.end(), [mask](std::uint64_t x, std::uint64_t y) { return (x & mask) < (y & mask); });
        return;
    }
    scratch.resize(m);
    std::vector<std::uint32_t> hist(chunks * kBins);
    for (int shift = lo_bit; shift < hi_bit; shift += kDigit) {
        run(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            std::fill(h, h + kBins, 0u);
            for (std::size_t i = lo; i < hi; ++i) ++h[(a[i] >> shift) & (kBins - 1)];
        });
        const std::size_t d0 = (a[0] >> shift) & (kBins - 1);
        std::size_t same = 0;
        for (std::size_t c = 0; c < chunks; ++c) same += hist[c * kBins + d0];
        if (same == m) continue;
        std::uint32_t sum = 0;
        for (std::size_t b = 0; b < kBins; ++b)
            for (std::size_t c = 0; c < chunks; ++c) {
                const std::uint32_t h = hist[c * kBins + b];
                hist[c * kBins + b] = sum;
                sum += h;
            }
        run(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            const std::uint64_t* RAYKIT_RESTRICT src = a.data();
            std::uint64_t* RAYKIT_RESTRICT dst = scratch.data();
            for (std::size_t i = lo; i < hi; ++i) dst[h[(src[i] >> shift) & (kBins - 1)]++] = src[i];
        });
        a.swap(scratch);
    }
}

inline void radix_sort_words(RawArray<std::uint64_t>& a, int lo_bit, int hi_bit, unsigned threads,
                             RawArray<std::uint64_t>& scratch) {
    radix_sort_words_with(
        a, lo_bit, hi_bit, sort_chunks(a.size(), threads),
        [threads](std::size_t n, std::size_t chunks, auto&& fn) { parallel_chunks(n, chunks, threads, fn); }, scratch);
}

inline void radix_sort_words(RawArray<std::uint64_t>& a, int lo_bit, int hi_bit, WorkTeam& team,
                             RawArray<std::uint64_t>& scratch) {
    radix_sort_words_with(
        a, lo_bit, hi_bit, sort_chunks(a.size(), team.size()),
        [&team](std::size_t n, std::size_t chunks, auto&& fn) { team.chunks(n, chunks, fn); }, scratch);
}

/// What a parent needs from a finished subtree for the leaf collapse.
struct SubtreeCost {
    std::uint32_t count;  ///< primitives below
    std::uint32_t out;    ///< output nodes below (1: the subtree becomes one leaf)
    float cost;           ///< best SAH cost (a leaf's, or a split's with the children's best)
};

/// Per inner node: box, children and collapse data (bottom-up), then its
/// place in the output (top-down).
struct MergeInfo {
    AABB box;
    std::uint32_t kid[2];
    SubtreeCost sub;
    std::uint32_t slot, desc, first;  // output slot (kInside: within a leaf), its children's slot, first prim_ids slot
};

/// The collapse rule for a primitive (a one-primitive leaf)...
inline SubtreeCost primitive_cost(const AABB& real_box, const LeafCollapseConfig& cfg) noexcept {
    return {1, 1, cfg.intersection_cost * real_box.half_area()};
}
/// ... and for an inner node with box `box` over subtrees a and b: a leaf
/// when it holds at most max_leaf_size primitives and Ci·SA·n ≤ Ct·SA +
/// cost(a) + cost(b).
inline SubtreeCost node_cost(const AABB& box, const SubtreeCost& a, const SubtreeCost& b,
                             const LeafCollapseConfig& cfg) noexcept {
    const float sa = box.half_area();
    const std::uint32_t cnt = a.count + b.count;
    const float split = cfg.traversal_cost * sa + (a.cost + b.cost);
    const float leaf = cfg.intersection_cost * sa * cfg.blocks(cnt);
    if (cnt <= std::max(1u, cfg.max_leaf_size) && leaf <= split) return {cnt, 1, leaf};
    return {cnt, 1 + a.out + b.out, split};
}

/// Topology of a bottom-up build: ids < prims are primitives, id prims + k
/// is the inner node with children info[k].kid.
struct MergeTree {
    std::uint32_t prims = 0;
    /// One record per inner node. Builders set kid; they may also fill box
    /// (the real bounds) and sub and then set info_ready, else
    /// finish_bottom_up computes those.
    RawArray<MergeInfo> info;
    bool info_ready = false;
    /// Exclusive ends (indices into info) of the batches; the nodes of one
    /// batch only have children among the primitives and earlier batches.
    std::vector<std::uint32_t> batch_end;
    std::uint32_t root = 0;

    std::size_t size() const noexcept { return info.size(); }
    void set(std::size_t k, std::uint32_t a, std::uint32_t b) noexcept {
        info[k].kid[0] = a;
        info[k].kid[1] = b;
    }
    /// Appends an inner node over a and b; returns its id.
    std::uint32_t add(std::uint32_t a, std::uint32_t b) {
        MergeInfo in{};
        in.kid[0] = a;
        in.kid[1] = b;
        info.push_back(in);
        return prims + static_cast<std::uint32_t>(info.size() - 1);
    }
    /// Marks the end of the current batch (no-op for an empty batch).
    void close_batch() {
        const auto k = static_cast<std::uint32_t>(info.size());
        if (batch_end.empty() ? k > 0 : batch_end.back() < k) batch_end.push_back(k);
    }
};

/// ⌈log2 c⌉ for c ≥ 1: the height of a median-split tree over c primitives.
inline int ceil_log2(std::uint64_t c) noexcept { return c <= 1 ? 0 : std::bit_width(c - 1); }

/// Depth-limit pass. Rebuilds, with median splits, subtrees that would end
/// deeper than RAYKIT_BVH_MAX_DEPTH (= D).
///
/// Proof that afterwards no leaf is deeper than D. Let h(v) be the height of
/// v's subtree, c(v) its primitive count, d(v) its depth, and call v
/// "rebuildable" when d(v) + ⌈log2 c(v)⌉ ≤ D: a median split halves the
/// count (⌈c/2⌉ ≤ the larger half), so a median-split tree over c primitives
/// has height exactly ⌈log2 c⌉, and rebuilding a rebuildable v keeps all its
/// leaves at depth ≤ D. The walk only ever visits rebuildable nodes: the root
/// is one, because c ≤ 2^31 (the builders reject more) and D ≥ 40 > 31. At a
/// visited v:
///   - if d(v) + h(v) ≤ D the subtree is kept as is: all its leaves are at
///     depth ≤ D;
///   - else, if each child is either such a kept subtree or rebuildable at
///     depth d(v) + 1, the walk goes on into both children (v stays an inner
///     node at depth ≤ D);
///   - else v itself is rebuilt, which is safe because v is rebuildable.
/// Every leaf of the result lies in a kept or a rebuilt subtree, so its depth
/// is ≤ D. The walk uses an explicit stack (the input may be O(n) deep).
/// Returns whether anything was rebuilt.
inline bool limit_depth(MergeTree& t, std::span<const vec3> centers) {
    constexpr int D = RAYKIT_BVH_MAX_DEPTH;
    const std::uint32_t n = t.prims;
    const std::size_t k0 = t.size();
    std::vector<std::uint32_t> height(k0), count(k0);
    auto h_of = [&](std::uint32_t id) -> std::uint32_t { return id < n ? 0u : height[id - n]; };
    auto c_of = [&](std::uint32_t id) -> std::uint32_t { return id < n ? 1u : count[id - n]; };
    for (std::size_t k = 0; k < k0; ++k) {
        const std::uint32_t a = t.info[k].kid[0], b = t.info[k].kid[1];
        height[k] = 1 + std::max(h_of(a), h_of(b));
        count[k] = c_of(a) + c_of(b);
    }
    if (int(h_of(t.root)) <= D) return false;

    std::vector<std::uint32_t> ids, stack;
    // median-split rebuild of the primitives ids[b, e); returns the new id
    auto median_build = [&](auto&& self, std::uint32_t b, std::uint32_t e) -> std::uint32_t {
        if (e - b == 1) return ids[b];
        AABB cb;
        for (std::uint32_t i = b; i < e; ++i) cb.grow(centers[ids[i]]);
        const std::uint32_t mid = median_partition(ids, b, e, centers, max_axis(cb.extent()));
        const std::uint32_t l = self(self, b, mid), r = self(self, mid, e);
        return t.add(l, r);
    };
    auto rebuild = [&](std::uint32_t v) -> std::uint32_t {
        ids.clear();
        stack.assign(1, v);
        while (!stack.empty()) {
            const std::uint32_t x = stack.back();
            stack.pop_back();
            if (x < n) {
                ids.push_back(x);
            } else {
                stack.push_back(t.info[x - n].kid[1]);
                stack.push_back(t.info[x - n].kid[0]);
            }
        }
        return median_build(median_build, 0, static_cast<std::uint32_t>(ids.size()));
    };

    struct Item {
        std::uint32_t id;
        int depth;
        std::uint32_t parent;  // inner index k of the parent (kNone: the root)
        int side;              // which child of the parent
    };
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    auto fits = [&](std::uint32_t id, int d) { return d + int(h_of(id)) <= D; };
    auto rebuildable = [&](std::uint32_t id, int d) { return d + ceil_log2(c_of(id)) <= D; };
    std::vector<Item> work{{t.root, 0, kNone, 0}};
    while (!work.empty()) {
        const Item it = work.back();
        work.pop_back();
        if (fits(it.id, it.depth)) continue;
        const std::uint32_t k = it.id - n;  // an inner node: primitives always fit
        const std::uint32_t a = t.info[k].kid[0], b = t.info[k].kid[1];
        const int cd = it.depth + 1;
        if ((fits(a, cd) || rebuildable(a, cd)) && (fits(b, cd) || rebuildable(b, cd))) {
            work.push_back({b, cd, k, 1});
            work.push_back({a, cd, k, 0});
        } else {
            const std::uint32_t nid = rebuild(it.id);
            if (it.parent == kNone) t.root = nid;
            else t.info[it.parent].kid[it.side] = nid;
        }
    }
    return true;
}

/// Calls node(k) for every inner node, batch after batch (children before
/// parents); large batches are split among threads.
template <class Fn>
void sweep_batches(const MergeTree& t, unsigned threads, Fn& node, WorkTeam* team = nullptr) {
    const std::size_t K = t.size();
    std::size_t begin = 0;
    for (const std::uint32_t end_u : t.batch_end) {
        const std::size_t end = std::min<std::size_t>(end_u, K);
        if (end <= begin) continue;
        const std::size_t m = end - begin;
        if (threads > 1 && m >= kBottomUpParallelPass) {
            auto part = [&](std::size_t, std::size_t lo, std::size_t hi) {
                for (std::size_t k = begin + lo; k < begin + hi; ++k) node(k);
            };
            if (team) team->chunks(m, pass_chunks(m), part);
            else parallel_chunks(m, pass_chunks(m), threads, part);
        } else {
            for (std::size_t k = begin; k < end; ++k) node(k);
        }
        begin = end;
    }
    for (std::size_t k = begin; k < K; ++k) node(k);
}

/// Turns a merge tree into the final Bvh (steps 2 and 3 above; step 1 first
/// when the batch count does not already bound the height).
inline Bvh finish_bottom_up(MergeTree& t, std::span<const AABB> boxes, std::span<const vec3> centers,
                            const LeafCollapseConfig& cfg, unsigned threads, WorkTeam* team = nullptr) {
    Bvh bvh;
    const std::uint32_t n = t.prims;
    if (n == 0) return bvh;
    if (n == 1) {
        bvh.nodes.push_back(Node{boxes[0], 0, 1});
        bvh.prim_ids.push_back(0);
        return bvh;
    }
    t.close_batch();
    const bool cut = t.batch_end.size() > std::size_t(RAYKIT_BVH_MAX_DEPTH) && limit_depth(t, centers);

    // bottom-up sweep: real boxes, primitive counts, best SAH cost, output
    // size, packed per node so that the top-down pass touches one record
    using Info = MergeInfo;
    RawArray<Info>& info = t.info;
    auto node = [&](std::size_t k) {
        const std::uint32_t a = info[k].kid[0], b = info[k].kid[1];
        Info in;
        in.kid[0] = a;
        in.kid[1] = b;
        SubtreeCost sa, sb;
        if (a < n) {
            in.box = boxes[a];
            sa = primitive_cost(boxes[a], cfg);
        } else {
            in.box = info[a - n].box;
            sa = info[a - n].sub;
        }
        if (b < n) {
            in.box.grow(boxes[b]);
            sb = primitive_cost(boxes[b], cfg);
        } else {
            in.box.grow(info[b - n].box);
            sb = info[b - n].sub;
        }
        in.sub = node_cost(in.box, sa, sb, cfg);
        info[k] = in;
    };
    int fork_depth = 0;
    if (threads > 1) {
        fork_depth = 1;
        while ((1u << (fork_depth - 1)) < threads) ++fork_depth;
        ++fork_depth;
    }
    if (cut) {
        // Nodes above the rebuilt subtrees now have children appended after
        // them, so the batch order no longer has children first: sweep the
        // reachable tree in post-order instead (its depth is now ≤ D).
        auto sweep = [&](auto&& self, std::uint32_t id, int depth) -> void {
            if (id < n) return;
            const std::uint32_t k = id - n;
            fork_join(
                depth < fork_depth, [&] { self(self, info[k].kid[0], depth + 1); },
                [&] { self(self, info[k].kid[1], depth + 1); });
            node(k);
        };
        sweep(sweep, t.root, 0);
    } else if (!t.info_ready) {
        sweep_batches(t, threads, node, team);
    }

    // top-down output, pre-order with children side by side
    const std::uint32_t root = t.root;
    const std::uint32_t total = root < n ? 1u : info[root - n].sub.out;
    bvh.nodes.resize(total);
    bvh.prim_ids.resize(n);
    Node* nodes = bvh.nodes.data();
    std::uint32_t* prim_ids = bvh.prim_ids.data();
    if (!cut) {
        // Batch by batch from the root down (parents are created after their
        // children, and the nodes of one batch are unrelated): each node
        // reads the place its parent gave it and places its children.
        // Records are read in order; the output is written scattered.
        constexpr std::uint32_t kInside = 0xFFFFFFFFu;
        Info& top = info[root - n];
        top.slot = 0;
        top.desc = 1;
        top.first = 0;
        auto down = [&](std::size_t k) {
            const Info& in = info[k];
            const std::uint32_t a = in.kid[0];
            const std::uint32_t out_a = a < n ? 1u : info[a - n].sub.out;
            const std::uint32_t cnt_a = a < n ? 1u : info[a - n].sub.count;
            std::uint32_t cslot[2] = {kInside, kInside}, cdesc[2] = {0, 0};
            if (in.slot != kInside) {
                if (in.sub.out == 1) {
                    nodes[in.slot] = Node{in.box, in.first, in.sub.count};
                } else {
                    nodes[in.slot] = Node{in.box, in.desc, 0};
                    cslot[0] = in.desc;
                    cslot[1] = in.desc + 1;
                    cdesc[0] = in.desc + 2;
                    cdesc[1] = in.desc + 2 + (out_a - 1);
                }
            }
            const std::uint32_t cfirst[2] = {in.first, in.first + cnt_a};
            for (int side = 0; side < 2; ++side) {
                const std::uint32_t c = in.kid[side];
                if (c < n) {
                    prim_ids[cfirst[side]] = c;
                    if (cslot[side] != kInside) nodes[cslot[side]] = Node{boxes[c], cfirst[side], 1};
                } else {
                    Info& ch = info[c - n];
                    ch.slot = cslot[side];
                    ch.desc = cdesc[side];
                    ch.first = cfirst[side];
                }
            }
        };
        for (std::size_t bi = t.batch_end.size(); bi-- > 0;) {
            const std::size_t end = t.batch_end[bi], begin = bi == 0 ? 0 : t.batch_end[bi - 1];
            const std::size_t m = end - begin;
            if (threads > 1 && m >= kBottomUpParallelPass) {
                auto part = [&](std::size_t, std::size_t lo, std::size_t hi) {
                    for (std::size_t k = begin + lo; k < begin + hi; ++k) down(k);
                };
                if (team) team->chunks(m, pass_chunks(m), part);
                else parallel_chunks(m, pass_chunks(m), threads, part);
            } else {
                for (std::size_t k = begin; k < end; ++k) down(k);
            }
        }
        return bvh;
    }
    // after a depth cut: recursive, the depth is now bounded
    auto emit = [&](auto&& self, std::uint32_t id, std::uint32_t slot, std::uint32_t desc, std::uint32_t first,
                    int depth) -> void {
        Node& o = nodes[slot];
        if (id < n) {
            o = Node{boxes[id], first, 1};
            prim_ids[first] = id;
            return;
        }
        const Info& in = info[id - n];
        if (in.sub.out == 1) {  // collapsed: gather the subtree's primitives left to right
            o = Node{in.box, first, in.sub.count};
            std::uint32_t at = first;
            std::uint32_t st[RAYKIT_BVH_MAX_DEPTH + 2];
            int sp = 0;
            st[sp++] = id;
            while (sp > 0) {
                const std::uint32_t x = st[--sp];
                if (x < n) {
                    prim_ids[at++] = x;
                } else {
                    st[sp++] = info[x - n].kid[1];
                    st[sp++] = info[x - n].kid[0];
                }
            }
            return;
        }
        o = Node{in.box, desc, 0};
        const std::uint32_t a = in.kid[0], b = in.kid[1];
        const std::uint32_t out_a = a < n ? 1u : info[a - n].sub.out;
        const std::uint32_t cnt_a = a < n ? 1u : info[a - n].sub.count;
        fork_join(
            depth < fork_depth && in.sub.count >= 8192,
            [&] { self(self, a, desc, desc + 2, first, depth + 1); },
            [&] { self(self, b, desc + 1, desc + 2 + (out_a - 1), first + cnt_a, depth + 1); });
    };
    emit(emit, root, 0, 1, 0, 0);
    return bvh;
}

}  // namespace detail
}  // namespace raykit
