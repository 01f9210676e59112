// raykit/util/radix_sort.hpp — stable parallel LSD radix sorts.
//
// The bottom-up builders sort integer keys once per build or once per level
// (Morton codes with primitive ids, float keys along an axis). These sorts take
// 11 bits per pass with per-chunk histograms, so each pass reads the keys twice
// and writes them once, and skip a pass whose digit is the same for every key.
// A stable sort has exactly one result, so the chunk count may follow the
// thread count without changing any tree. orderable_bits turns a float into
// such a key.
#pragma once

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "raykit/config.hpp"
#include "raykit/util/parallel.hpp"
#include "raykit/util/raw_array.hpp"

namespace raykit::detail {

/// Float whose unsigned bit pattern orders like the float (no NaN).
inline std::uint32_t orderable_bits(float f) noexcept {
    const std::uint32_t u = std::bit_cast<std::uint32_t>(f == 0.0f ? 0.0f : f);  // -0 == +0
    return (u & 0x80000000u) ? ~u : (u | 0x80000000u);
}

/// Chunk count for a radix-sort pass. A stable sort has one result, so the
/// chunking may follow the thread count.
inline std::size_t sort_chunks(std::size_t m, unsigned threads) noexcept {
    return threads <= 1 || m < kMinParallelPass ? 1 : std::min<std::size_t>(64, 2 * std::size_t(threads));
}

/// Bits per radix-sort pass, and the bins they make.
inline constexpr int kRadixDigit = 11;
inline constexpr std::size_t kRadixBins = std::size_t(1) << kRadixDigit;

/// One pass's histogram: digit(i) of every element i < m counted per chunk
/// into hist (chunks x kRadixBins), then turned into each chunk's first
/// output slot per digit (digits in order, chunks in order within a digit,
/// so the pass is stable). Returns false, with hist left as counts, when
/// every element has element 0's digit: the pass would move nothing.
template <class Digit>
bool radix_offsets(std::size_t m, std::size_t chunks, WorkTeam& team, std::vector<std::uint32_t>& hist,
                   const Digit& digit) {
    team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
        std::uint32_t* h = hist.data() + c * kRadixBins;
        std::fill(h, h + kRadixBins, 0u);
        for (std::size_t i = lo; i < hi; ++i) ++h[digit(i)];
    });
    const std::size_t d0 = digit(0);
    std::size_t same = 0;
    for (std::size_t c = 0; c < chunks; ++c) same += hist[c * kRadixBins + d0];
    if (same == m) return false;
    std::uint32_t sum = 0;
    for (std::size_t b = 0; b < kRadixBins; ++b)
        for (std::size_t c = 0; c < chunks; ++c) {
            const std::uint32_t h = hist[c * kRadixBins + b];
            hist[c * kRadixBins + b] = sum;
            sum += h;
        }
    return true;
}

/// Stable LSD radix sort of (keys, vals) by the low `bits` bits of the keys,
/// 11 bits per pass, on a build's team; passes where every key has the same
/// digit are skipped.
template <class Key>
void radix_sort(RawArray<Key>& keys, RawArray<std::uint32_t>& vals, int bits, WorkTeam& team) {
    const std::size_t chunks = sort_chunks(keys.size(), team.size());
    const std::size_t m = keys.size();
    if (m < 2) return;
    RawArray<Key> k2(m);
    RawArray<std::uint32_t> v2(m);
    std::vector<std::uint32_t> hist(chunks * kRadixBins);
    for (int shift = 0; shift < bits; shift += kRadixDigit) {
        auto digit = [&](std::size_t i) { return std::size_t(keys[i] >> shift) & (kRadixBins - 1); };
        if (!radix_offsets(m, chunks, team, hist, digit)) continue;
        team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kRadixBins;
            for (std::size_t i = lo; i < hi; ++i) {
                const std::uint32_t pos = h[digit(i)]++;
                k2[pos] = keys[i];
                v2[pos] = vals[i];
            }
        });
        keys.swap(k2);
        vals.swap(v2);
    }
}

/// Stable LSD radix sort of 64-bit words by their bits [lo_bit, hi_bit)
/// (typically a 32-bit key above a 32-bit payload), 11 bits per pass;
/// passes where every word has the same digit are skipped. `scratch` may be
/// reused between calls. Runs on a build's team.
inline void radix_sort_words(RawArray<std::uint64_t>& a, int lo_bit, int hi_bit, WorkTeam& team,
                             RawArray<std::uint64_t>& scratch) {
    const std::size_t chunks = sort_chunks(a.size(), team.size());
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
    std::vector<std::uint32_t> hist(chunks * kRadixBins);
    for (int shift = lo_bit; shift < hi_bit; shift += kRadixDigit) {
        if (!radix_offsets(m, chunks, team, hist, [&](std::size_t i) { return (a[i] >> shift) & (kRadixBins - 1); }))
            continue;
        team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kRadixBins;
            const std::uint64_t* RAYKIT_RESTRICT src = a.data();
            std::uint64_t* RAYKIT_RESTRICT dst = scratch.data();
            for (std::size_t i = lo; i < hi; ++i) dst[h[(src[i] >> shift) & (kRadixBins - 1)]++] = src[i];
        });
        a.swap(scratch);
    }
}

/// radix_sort_words on a team of its own: up to `threads` threads when the
/// array is large enough to be split.
inline void radix_sort_words(RawArray<std::uint64_t>& a, int lo_bit, int hi_bit, unsigned threads,
                             RawArray<std::uint64_t>& scratch) {
    WorkTeam team(sort_chunks(a.size(), threads) > 1 ? threads : 1u);
    radix_sort_words(a, lo_bit, hi_bit, team, scratch);
}

}  // namespace raykit::detail
