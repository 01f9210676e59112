// raykit/util/raw_array.hpp — a growable array that does not initialise its
// elements.
//
// The bottom-up builders and the radix sorts fill scratch arrays of millions of
// keys, ids and boxes, one chunk per thread. With std::vector one thread would
// zero (and page-fault) the whole array first; with RawArray each page is first
// touched by the thread that writes it. Every element is written before it is
// read, so nothing reads the missing initialisation. Large arrays come from
// BlockCache (block_cache.hpp), so a build reuses the pages the last one freed.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstring>
#include <new>
#include <span>
#include <type_traits>
#include <utility>

#include "raykit/util/block_cache.hpp"

namespace raykit::detail {

/// Array storage that is not initialised: large scratch arrays are first
/// touched (and page-faulted) by the threads that fill them instead of by
/// one thread zeroing them. For trivially copyable, implicit-lifetime
/// element types; every element is written before it is read.
template <class T>
class RawArray {
    static_assert(std::is_trivially_copyable_v<T> && std::is_trivially_destructible_v<T>);
    static_assert(alignof(T) <= 64);

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
        T* q = static_cast<T*>(BlockCache::get().allocate(cap * sizeof(T)));
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
        if (p_) BlockCache::get().deallocate(p_, cap_ * sizeof(T));
        p_ = nullptr;
        cap_ = 0;
    }
    T* p_ = nullptr;
    std::size_t n_ = 0, cap_ = 0;
};

}  // namespace raykit::detail
