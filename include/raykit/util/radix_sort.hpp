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

/// Stable LSD radix sort of (keys, vals) by the low `bits` bits of the keys,
/// 11 bits per pass, on a build's team; passes where every key has the same
/// digit are skipped.
template <class Key>
void radix_sort(RawArray<Key>& keys, RawArray<std::uint32_t>& vals, int bits, WorkTeam& team) {
    const std::size_t chunks = sort_chunks(keys.size(), team.size());
    constexpr int kDigit = 11;
    constexpr std::size_t kBins = std::size_t(1) << kDigit;
    const std::size_t m = keys.size();
    if (m < 2) return;
    RawArray<Key> k2(m);
    RawArray<std::uint32_t> v2(m);
    std::vector<std::uint32_t> hist(chunks * kBins);
    for (int shift = 0; shift < bits; shift += kDigit) {
        team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
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
        team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
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

/// Stable LSD radix sort of 64-bit words by their bits [lo_bit, hi_bit)
/// (typically a 32-bit key above a 32-bit payload), 11 bits per pass;
/// passes where every word has the same digit are skipped. `scratch` may be
/// reused between calls. Runs on a build's team.
inline void radix_sort_words(RawArray<std::uint64_t>& a, int lo_bit, int hi_bit, WorkTeam& team,
                             RawArray<std::uint64_t>& scratch) {
    const std::size_t chunks = sort_chunks(a.size(), team.size());
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
        team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
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
        team.chunks(m, chunks, [&](std::size_t c, std::size_t lo, std::size_t hi) {
            std::uint32_t* h = hist.data() + c * kBins;
            const std::uint64_t* RAYKIT_RESTRICT src = a.data();
            std::uint64_t* RAYKIT_RESTRICT dst = scratch.data();
            for (std::size_t i = lo; i < hi; ++i) dst[h[(src[i] >> shift) & (kBins - 1)]++] = src[i];
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
