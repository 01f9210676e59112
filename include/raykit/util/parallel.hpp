// raykit/util/parallel.hpp — raykit's one executor: a team of threads, and the
// fork/join helpers that run on it.
//
// Builders split work into a fixed number of chunks that depends only on the
// input size (or, for a stable sort, on anything: it has one result), so
// results are the same whatever the machine and whatever thread count was asked
// for. Chunk c of [0, n) covers [n·c/chunks, n·(c+1)/chunks) and runs on member
// c mod members, whichever entry point runs it.
//
// detail::WorkTeam is the only code in raykit that starts threads. A build
// keeps one for its passes: starting and joining a std::thread costs ~50 µs,
// waking a waiting member about 1 µs, and a PLOC or sort-by-axis build runs
// hundreds of passes, a binned SAH build nine and its pool. parallel_chunks, parallel_for and
// fork_join start a team for one call (they block instead of spinning while
// they wait). detail::run_chunks picks a build's team when it has one.
//
// One thread-count rule, resolve_threads: `threads == 0` means
// std::thread::hardware_concurrency(), and counts are bounded by kMaxThreads
// (1024). Entry points that take a count from a caller (BuildOptions and every
// builder's Config) reject a larger one with std::invalid_argument
// (check_threads); the executor clamps to it, so no path can start more threads
// than that or compute a fork depth past 1u << 10. Without the bound,
// --threads 4294967295 made the binned SAH's fork-depth loop shift a 32-bit 1
// by 32 (undefined; it hung), and a parallel_for over a million rays would have
// asked for a million threads.
#pragma once

#include <algorithm>
#include <atomic>
#include <condition_variable>
#include <cstddef>
#include <cstdint>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>
#include <utility>
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

namespace detail {

/// A fixed set of threads (resolve_threads(threads) members; member 0 is the
/// owning thread), for one build or one call. Not reentrant: one pass at a
/// time, from the owning thread. A `spin` team's waiting threads spin
/// briefly before they sleep on an atomic wait (for many short passes); a
/// one-call team sleeps at once. The first exception of a pass (lowest
/// member first) is rethrown on the owning thread.
class WorkTeam {
public:
    explicit WorkTeam(unsigned threads, bool spin = true)
        : size_(resolve_threads(threads)), spin_(spin ? kSpin : 0), errors_(size_) {
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
    /// Member count, 1..kMaxThreads.
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
            if (spin < spin_) pause();
            else done_.wait(d, std::memory_order_acquire);
        }
        for (std::exception_ptr& e : errors_)
            if (e) {
                std::exception_ptr x = e;
                for (std::exception_ptr& f : errors_) f = nullptr;
                std::rethrow_exception(x);
            }
    }

    /// fn(c, lo, hi) for `chunks` contiguous chunks of [0, n) (boundaries
    /// depend on n and chunks only); one chunk or one member runs inline.
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
                if (spin < spin_) pause();
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
    int spin_;
    std::vector<std::thread> helpers_;
    std::vector<std::exception_ptr> errors_;
    std::atomic<std::uint32_t> gen_{0};
    std::atomic<unsigned> done_{0};
    void (*call_)(void*, unsigned) = nullptr;
    void* ctx_ = nullptr;
    bool stop_ = false;  // written before a generation bump, read after it
};

}  // namespace detail

/// Calls fn(chunk_index, begin, end) for `chunks` contiguous chunks of [0, n),
/// using up to `threads` threads (a one-call WorkTeam). Chunk boundaries depend
/// on n and chunks only. The first exception thrown by any chunk is rethrown
/// on the calling thread.
template <class Fn>
void parallel_chunks(std::size_t n, std::size_t chunks, unsigned threads, Fn&& fn) {
    chunks = std::max<std::size_t>(1, std::min(chunks, n == 0 ? 1 : n));
    threads = static_cast<unsigned>(std::min<std::size_t>(resolve_threads(threads), chunks));
    detail::WorkTeam(threads, false).chunks(n, chunks, fn);
}

/// fn(i) for i in [0, n), in `threads` equal chunks (one per thread) when n
/// reaches `min_parallel`, else on the calling thread. For per-element work
/// whose result does not depend on the split.
template <class Fn>
void parallel_for(std::size_t n, unsigned threads, Fn&& fn, std::size_t min_parallel = 1024) {
    threads = resolve_threads(threads);
    if (n < min_parallel) threads = 1;
    parallel_chunks(n, threads, threads, [&](std::size_t, std::size_t b, std::size_t e) {
        for (std::size_t i = b; i < e; ++i) fn(i);
    });
}

/// Runs a() and b() concurrently when `fork` is true, else one after the other.
/// An exception from a() is rethrown before one from b().
template <class A, class B>
void fork_join(bool fork, A&& a, B&& b) {
    if (!fork) {
        a();
        b();
        return;
    }
    detail::WorkTeam(2, false).each([&](unsigned member) {
        if (member == 0) a();
        else b();
    });
}

namespace detail {

/// Tasks that spawn tasks, of sizes known only as they are made (a top-down build's subtrees),
/// run by a team: push() adds a task, drain() runs every task on a build's WorkTeam until none
/// waits and none runs, an idle member taking the largest waiting one.
/// (Forking two new threads per node down to a fixed depth left the bunny's four subtrees of
/// 11-24k primitives to the OS scheduler, and the last ran alone; drained this way the binned
/// SAH build is 4-10 % faster on two threads.) The first exception is rethrown by drain().
template <class Task>
class TaskQueue {
public:
    /// Adds a task; `size` orders the waiting tasks (largest runs first).
    void push(const Task& task, std::size_t size) {
        {
            const std::lock_guard lock(m_);
            tasks_.push_back({task, size});
        }
        cv_.notify_one();
    }
    /// Runs run(task) for every task pushed before or during the call, on every member of
    /// `team` (a build's; the tasks may not use it).
    template <class Run>
    void drain(WorkTeam& team, Run&& run) {
        members_ = team.size();
        team.each([&](unsigned) { work(run); });
        if (error_) std::rethrow_exception(std::exchange(error_, nullptr));
    }
    /// Lends a task up to `want` of the draining team's members that neither run a task, nor
    /// will take a waiting one, nor are lent already (the task then runs a pass on that many
    /// more threads of its own while they wait); returns how many. give_back() returns them.
    unsigned borrow(unsigned want) {
        const std::lock_guard lock(m_);
        const std::size_t busy = running_ + tasks_.size() + lent_;
        const unsigned k = busy < members_ ? std::min(want, members_ - static_cast<unsigned>(busy)) : 0u;
        lent_ += k;
        return k;
    }
    /// Returns k members that borrow() lent.
    void give_back(unsigned k) {
        const std::lock_guard lock(m_);
        lent_ -= k;
    }

private:
    template <class Run>
    void work(Run& run) {
        std::unique_lock lock(m_);
        for (;;) {
            cv_.wait(lock, [&] { return !tasks_.empty() || running_ == 0; });
            if (tasks_.empty()) return;
            const auto it = std::max_element(tasks_.begin(), tasks_.end(),
                                             [](const Sized& x, const Sized& y) { return x.size < y.size; });
            const Task t = it->task;
            tasks_.erase(it);
            ++running_;
            lock.unlock();
            try {
                run(t);
            } catch (...) {
                lock.lock();
                if (!error_) error_ = std::current_exception();
                lock.unlock();
            }
            lock.lock();
            if (--running_ == 0 && tasks_.empty()) cv_.notify_all();
        }
    }
    struct Sized {
        Task task;
        std::size_t size;
    };
    std::mutex m_;
    std::condition_variable cv_;
    std::vector<Sized> tasks_;
    unsigned running_ = 0;  // threads inside a task
    unsigned members_ = 0;  // the draining team's size
    unsigned lent_ = 0;     // members lent to tasks' passes (borrow)
    std::exception_ptr error_;
};

/// Element count from which a build's per-element passes run on several threads.
inline constexpr std::size_t kMinParallelPass = 16384;

/// Chunk count for a parallel pass over m elements: depends on m only.
inline std::size_t pass_chunks(std::size_t m) noexcept {
    return m < kMinParallelPass ? 1 : std::min<std::size_t>(64, m / (kMinParallelPass / 4));
}

/// fn(c, lo, hi) for the chunks of [0, n): on `team` when a build has one,
/// else on up to `threads` threads of their own.
template <class Fn>
void run_chunks(WorkTeam* team, unsigned threads, std::size_t n, std::size_t chunks, Fn&& fn) {
    if (team) team->chunks(n, chunks, fn);
    else parallel_chunks(n, chunks, threads, fn);
}

/// Element count from which a pass runs on a build's team when it has one: its members wait
/// spinning, so handing out chunks costs microseconds, not a thread start. The sort-by-axis
/// build's back end left its batches under kMinParallelPass to one thread: with this bound
/// the 70k-triangle torus builds 1.11x as fast on two threads (paired builds).
inline constexpr std::size_t kMinTeamPass = 2048;

/// Chunks for a pass over m independent elements on a team of `members`: pass_chunks from
/// kMinParallelPass elements, one per member from kMinTeamPass, else one.
inline std::size_t team_chunks(std::size_t m, unsigned members) noexcept {
    return m >= kMinParallelPass ? pass_chunks(m) : m >= kMinTeamPass ? std::size_t(members) : 1;
}

/// fn(k) for k in [begin, end), elements unrelated to each other: in chunks on `team` when
/// there are kMinTeamPass or more, else on threads of their own from kMinParallelPass, else
/// in order.
template <class Fn>
void for_range(std::size_t begin, std::size_t end, unsigned threads, WorkTeam* team, Fn&& fn) {
    const std::size_t m = end - begin;
    if (threads > 1 && m >= (team ? kMinTeamPass : kMinParallelPass)) {
        run_chunks(team, threads, m, team_chunks(m, threads), [&](std::size_t, std::size_t lo, std::size_t hi) {
            for (std::size_t k = begin + lo; k < begin + hi; ++k) fn(k);
        });
    } else {
        for (std::size_t k = begin; k < end; ++k) fn(k);
    }
}

}  // namespace detail
}  // namespace raykit
