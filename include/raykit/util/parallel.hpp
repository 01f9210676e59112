// raykit/util/parallel.hpp — minimal fork/join helpers on std::thread.
//
// raykit has no thread pool of its own: builders split work into a fixed number
// of chunks that depends only on the input size and the thread count asked for,
// so results are the same whatever the machine. `threads == 0` means
// std::thread::hardware_concurrency().
//
// Thread counts are bounded by kMaxThreads (1024). Entry points that take a
// count from a caller (BuildOptions and every builder's Config) reject a larger
// one with std::invalid_argument; these helpers clamp to it, so no path can
// start more threads than that or compute a fork depth past 1u << 10. Without
// the bound, --threads 4294967295 made the binned SAH's fork-depth loop shift
// a 32-bit 1 by 32 (undefined; it hung), and a parallel_for over a million
// rays would have asked for a million threads.
#pragma once

#include <algorithm>
#include <cstddef>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

namespace raykit {

/// Largest thread count raykit accepts (a 4-socket server has a few hundred).
inline constexpr unsigned kMaxThreads = 1024;

/// Throws std::invalid_argument naming `who` when `threads` exceeds kMaxThreads.
inline void check_threads(unsigned threads, const char* who) {
    if (threads > kMaxThreads)
        throw std::invalid_argument(std::string(who) + ": threads must be in 0.." + std::to_string(kMaxThreads) +
                                    " (0 = all hardware threads), not " + std::to_string(threads));
}

/// Resolves a user thread count (0 = all hardware threads) to 1..kMaxThreads.
inline unsigned resolve_threads(unsigned threads) noexcept {
    if (threads == 0) threads = std::thread::hardware_concurrency();
    return threads == 0 ? 1u : std::min(threads, kMaxThreads);
}

/// Calls fn(chunk_index, begin, end) for `chunks` contiguous chunks of [0, n),
/// using up to `threads` threads. Chunk boundaries depend on n and chunks only.
/// The first exception thrown by any chunk is rethrown on the calling thread.
template <class Fn>
void parallel_chunks(std::size_t n, std::size_t chunks, unsigned threads, Fn&& fn) {
    chunks = std::max<std::size_t>(1, std::min(chunks, n == 0 ? 1 : n));
    auto bounds = [&](std::size_t c) { return n * c / chunks; };
    threads = static_cast<unsigned>(std::min<std::size_t>(resolve_threads(threads), chunks));
    if (threads <= 1) {
        for (std::size_t c = 0; c < chunks; ++c) fn(c, bounds(c), bounds(c + 1));
        return;
    }
    std::vector<std::exception_ptr> errors(threads);
    std::vector<std::thread> pool;
    pool.reserve(threads - 1);
    auto worker = [&](unsigned t) {
        try {
            for (std::size_t c = t; c < chunks; c += threads) fn(c, bounds(c), bounds(c + 1));
        } catch (...) {
            errors[t] = std::current_exception();
        }
    };
    for (unsigned t = 1; t < threads; ++t) pool.emplace_back(worker, t);
    worker(0);
    for (auto& th : pool) th.join();
    for (auto& e : errors)
        if (e) std::rethrow_exception(e);
}

/// parallel_for over [0, n) in `threads` equal chunks (one per thread).
template <class Fn>
void parallel_for(std::size_t n, unsigned threads, Fn&& fn) {
    threads = resolve_threads(threads);
    if (n < 1024) threads = 1;
    parallel_chunks(n, threads, threads, [&](std::size_t, std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) fn(i);
    });
}

/// Runs a() and b() concurrently when `fork` is true, else one after the other.
template <class A, class B>
void fork_join(bool fork, A&& a, B&& b) {
    if (!fork) {
        a();
        b();
        return;
    }
    std::exception_ptr err;
    std::thread th([&] {
        try {
            b();
        } catch (...) {
            err = std::current_exception();
        }
    });
    try {
        a();
    } catch (...) {
        th.join();
        throw;
    }
    th.join();
    if (err) std::rethrow_exception(err);
}

}  // namespace raykit
