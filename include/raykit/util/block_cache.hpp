// raykit/util/block_cache.hpp — large allocations kept for the next build.
//
// A build allocates a few large arrays (records, nodes, blocks) and frees most of
// them when it returns, and the caller frees the last tree when it builds the next.
// glibc returns such memory to the system when the free space at the top of its
// heap passes twice the largest block it has mapped, which a two-thread
// BlockBvh8::build of the bunny does every time: each build then page-faulted
// ~1,500 fresh pages, about a quarter of its 16 ms (with the thresholds raised by
// GLIBC_TUNABLES it took 12.2 ms). One thread kept its pages. Embree's builds,
// which keep their own memory, fault none.
//
// So raykit's array allocators (nodes, blocks, builder scratch) take blocks of
// 256 KiB and more from this cache: sizes round up to one of eight classes per
// power of two (at most 1/8 wasted), a freed block waits for the next request of
// its class, and at most 256 MiB wait (the oldest go back to the system first;
// set_build_memory_limit() changes the bound). trim() gives them all back. Smaller
// requests go straight to operator new.
//
// The bound was 64 MiB. A 1M-triangle BlockBvh8::build frees 136 MiB of records, nodes
// and scratch, so each build then gave most of it back and faulted it in again: the
// kernel zeroing fresh huge pages was 10 % of the build's samples (perf), and with the
// bound raised the same build is 1.05-1.07x as fast on one thread and on two (medians
// of paired builds in one process). A 100k-triangle build frees 14 MiB.
//
// Blocks of 2 MiB and more are aligned to 2 MiB and, on Linux, advised as huge pages
// (madvise MADV_HUGEPAGE; where transparent huge pages are "madvise", as on this
// project's Debian 12 VMs, nothing else gets them). A random ray's walk touches a few
// nodes and blocks scattered over the whole tree: on the 1M-triangle torus (16 MB of
// nodes, 41 MB of blocks) 4 KiB pages made most of those touches TLB misses, and huge
// pages took random rays 9-14 % faster (closest 148-151 -> 134-138 ms, any 148-159 ->
// 125-136, one thread). Embree uses huge pages on Linux by default.
#pragma once

#include <bit>
#include <cstddef>
#include <cstdint>
#include <mutex>
#include <new>
#include <vector>

#if defined(__linux__)
#include <sys/mman.h>
#endif

#if defined(__SANITIZE_ADDRESS__)
#define RAYKIT_BLOCK_CACHE_ASAN 1
#elif defined(__has_feature)
#if __has_feature(address_sanitizer)
#define RAYKIT_BLOCK_CACHE_ASAN 1
#endif
#endif
#ifdef RAYKIT_BLOCK_CACHE_ASAN
#include <sanitizer/asan_interface.h>
#endif

namespace raykit {
namespace detail {

/// Bytes of a huge page: blocks this large and larger go on huge pages.
inline constexpr std::size_t kHugePageBytes = std::size_t(2) << 20;

/// Advises the whole huge pages inside [p, p + bytes) as huge pages (Linux MADV_HUGEPAGE) before
/// their first touch. Advice only: where it fails, or on other systems, nothing changes. The
/// block cache's large blocks and the device buffers of a CPU device (cl/buffer.hpp) use it.
inline void advise_huge_pages(void* p, std::size_t bytes) noexcept {
#if defined(__linux__) && defined(MADV_HUGEPAGE)
    const std::uintptr_t a = (reinterpret_cast<std::uintptr_t>(p) + kHugePageBytes - 1) & ~(kHugePageBytes - 1);
    const std::uintptr_t e = (reinterpret_cast<std::uintptr_t>(p) + bytes) & ~(kHugePageBytes - 1);
    if (e > a) (void)::madvise(reinterpret_cast<void*>(a), e - a, MADV_HUGEPAGE);
#else
    (void)p, (void)bytes;
#endif
}

/// Process-wide cache of large 64-byte-aligned blocks (see the header comment).
class BlockCache {
public:
    static constexpr std::size_t kMinBytes = std::size_t(256) << 10;  ///< smaller requests are not cached
    static constexpr std::size_t kDefaultLimit = std::size_t(256) << 20;  ///< most bytes kept waiting, unless set_limit
    static constexpr std::align_val_t kAlign{64};
    static constexpr std::size_t kHugeBytes = kHugePageBytes;  ///< blocks this large sit on huge pages

    /// The one cache (never destroyed: arrays in static objects may free into it at exit).
    static BlockCache& get() {
        static BlockCache* const c = new BlockCache;
        return *c;
    }

    /// The bytes actually reserved for a request of `bytes` (its size class).
    static constexpr std::size_t rounded(std::size_t bytes) noexcept {
        if (bytes < kMinBytes) return bytes;
        const std::size_t step = std::bit_floor(bytes) / 8;
        return (bytes + step - 1) / step * step;
    }

    /// A block of at least `bytes`, 64-byte aligned; deallocate() takes the same `bytes`.
    void* allocate(std::size_t bytes) {
        const std::size_t size = rounded(bytes);
        if (size >= kMinBytes) {
            const std::lock_guard lock(m_);
            for (std::size_t i = free_.size(); i-- > 0;)
                if (free_[i].size == size) {
                    void* p = free_[i].p;
                    poison(p, size, false);
                    free_.erase(free_.begin() + static_cast<std::ptrdiff_t>(i));
                    held_ -= size;
                    return p;
                }
        }
        return fresh(size);
    }
    void deallocate(void* p, std::size_t bytes) noexcept {
        const std::size_t size = rounded(bytes);
        const std::lock_guard lock(m_);
        if (size < kMinBytes || size > limit_) return release(p, size);
        shrink_to(limit_ - size);
        try {
            free_.push_back({p, size});
        } catch (...) {
            return release(p, size);
        }
        poison(p, size, true);
        held_ += size;
    }
    /// Gives every waiting block back to the system.
    void trim() noexcept {
        const std::lock_guard lock(m_);
        shrink_to(0);
    }
    /// Keeps at most `bytes` waiting from now on (the oldest blocks over it go back at once).
    void set_limit(std::size_t bytes) noexcept {
        const std::lock_guard lock(m_);
        limit_ = bytes;
        shrink_to(bytes);
    }
    /// The most bytes kept waiting.
    std::size_t limit() const {
        const std::lock_guard lock(m_);
        return limit_;
    }
    /// Bytes waiting in the cache.
    std::size_t held() const {
        const std::lock_guard lock(m_);
        return held_;
    }

private:
    BlockCache() = default;
    /// Gives the oldest waiting blocks back until at most `bytes` wait (m_ held).
    void shrink_to(std::size_t bytes) noexcept {
        std::size_t k = 0;
        for (; k < free_.size() && held_ > bytes; ++k) {
            poison(free_[k].p, free_[k].size, false);
            release(free_[k].p, free_[k].size);
            held_ -= free_[k].size;
        }
        free_.erase(free_.begin(), free_.begin() + static_cast<std::ptrdiff_t>(k));
    }
    /// The alignment a block of `size` (a size class) is allocated and freed with.
    static constexpr std::align_val_t alignment(std::size_t size) noexcept {
        return size >= kHugeBytes ? std::align_val_t{kHugeBytes} : kAlign;
    }
    /// New memory for a block of `size`, advised as huge pages before its first touch.
    static void* fresh(std::size_t size) {
        void* p = ::operator new(size, alignment(size));
        if (size >= kHugeBytes) advise_huge_pages(p, size);
        return p;
    }
    static void release(void* p, std::size_t size) noexcept { ::operator delete(p, alignment(size)); }
    /// Under AddressSanitizer a waiting block is poisoned, so a use after free is still caught.
    static void poison(void* p, std::size_t size, bool on) noexcept {
#ifdef RAYKIT_BLOCK_CACHE_ASAN
        if (on) __asan_poison_memory_region(p, size);
        else __asan_unpoison_memory_region(p, size);
#else
        (void)p, (void)size, (void)on;
#endif
    }
    struct Block {
        void* p;
        std::size_t size;
    };
    mutable std::mutex m_;
    std::vector<Block> free_;
    std::size_t held_ = 0;
    std::size_t limit_ = kDefaultLimit;
};

}  // namespace detail

/// Gives back to the system the memory raykit keeps for its next build (util/block_cache.hpp):
/// freed trees and builder scratch, at most build_memory_limit() bytes.
inline void trim_build_memory() noexcept { detail::BlockCache::get().trim(); }
/// Keeps at most `bytes` of freed build memory for the next build (default 256 MiB; 0 keeps none).
inline void set_build_memory_limit(std::size_t bytes) noexcept { detail::BlockCache::get().set_limit(bytes); }
/// The most bytes of freed build memory raykit keeps.
inline std::size_t build_memory_limit() { return detail::BlockCache::get().limit(); }

}  // namespace raykit
