// raykit/simd/isa.hpp — which vector instruction set the traversals run with, chosen at run time.
//
// raykit is header-only and its target adds no architecture flags, so a consumer built with
// plain -O2 compiles for baseline x86-64 (SSE2). The traversal code (slab and triangle tests,
// the wide and packet walks, the leaf stores: scene/trace.hpp) is therefore compiled
// once per level below that the compiler's own flags do not already cover, each copy in its own
// namespace under a target pragma, and every public walk calls the copy of the best level the
// running CPU has. Measured before this (bench_trace, bunny camera rays, one thread, AVX-512
// machine): BlockBvh8 at 19.3 ms with -O2 against 10.7 ms with -march=native.
//
// Levels follow the x86-64 micro-architecture levels: base (whatever the compiler targets),
// avx2 (x86-64-v3: AVX2, FMA, BMI1/2), avx512 (AVX-512 F/VL/BW/DQ on top, as x86-64-v4).
// Every level returns the same answers bit for bit (the one FMA rule is config.hpp's
// RAYKIT_FMA); tests/test_dispatch.cpp runs each level the CPU has on the same rays.
#pragma once

#include <atomic>

#include "raykit/config.hpp"

#if (defined(__x86_64__) || defined(__i386__)) && (defined(__GNUC__) || defined(__clang__)) && !defined(RAYKIT_NO_SIMD)
#include <immintrin.h>
#define RAYKIT_ISA_X86 1
#else
#define RAYKIT_ISA_X86 0
#endif

/// The compiler's own flags already give level avx2 / avx512 (then no copy below it is made).
#if RAYKIT_ISA_X86 && defined(__AVX2__) && defined(__FMA__) && defined(__BMI2__)
#define RAYKIT_ISA_FLAGS_AVX2 1
#else
#define RAYKIT_ISA_FLAGS_AVX2 0
#endif
#if RAYKIT_ISA_FLAGS_AVX2 && defined(__AVX512F__) && defined(__AVX512VL__) && defined(__AVX512BW__) && \
    defined(__AVX512DQ__)
#define RAYKIT_ISA_FLAGS_AVX512 1
#else
#define RAYKIT_ISA_FLAGS_AVX512 0
#endif
/// Copies compiled beside the base one: the levels above what the flags give.
#define RAYKIT_ISA_BUILD_AVX2 (RAYKIT_ISA_X86 && !RAYKIT_ISA_FLAGS_AVX2)
#define RAYKIT_ISA_BUILD_AVX512 (RAYKIT_ISA_X86 && !RAYKIT_ISA_FLAGS_AVX512)

namespace raykit {

/// A level of vector instructions (ordered: each includes the ones before it).
enum class Isa : int { base = 0, avx2 = 1, avx512 = 2 };

/// Readable name of a level.
constexpr const char* isa_name(Isa i) noexcept {
    return i == Isa::avx512 ? "avx512" : i == Isa::avx2 ? "avx2" : "base";
}

/// The level the compiler's flags give: what the base copy is compiled for.
constexpr Isa compiled_isa() noexcept {
    return RAYKIT_ISA_FLAGS_AVX512 ? Isa::avx512 : RAYKIT_ISA_FLAGS_AVX2 ? Isa::avx2 : Isa::base;
}

/// The best level this CPU (and its operating system: the checks include XSAVE state) runs.
inline Isa cpu_isa() noexcept {
#if RAYKIT_ISA_X86
    static const Isa level = [] {
        __builtin_cpu_init();
        const bool v3 = __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
                        __builtin_cpu_supports("bmi") && __builtin_cpu_supports("bmi2") &&
                        __builtin_cpu_supports("popcnt");
        const bool v4 = v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") &&
                        __builtin_cpu_supports("avx512bw") && __builtin_cpu_supports("avx512dq");
        return v4 ? Isa::avx512 : v3 ? Isa::avx2 : Isa::base;
    }();
    return level < compiled_isa() ? compiled_isa() : level;
#else
    return Isa::base;
#endif
}

namespace detail {
inline std::atomic<int>& isa_cap() noexcept {
    static std::atomic<int> cap{int(Isa::avx512)};
    return cap;
}
}  // namespace detail

/// Caps the level the walks use (tests and benchmarks compare levels); never below what the
/// compiler's flags give, since no copy below that exists.
inline void set_max_isa(Isa i) noexcept { detail::isa_cap().store(int(i), std::memory_order_relaxed); }

/// The level the walks use now: the CPU's, within set_max_isa's cap and at least compiled_isa().
inline Isa active_isa() noexcept {
    const int cap = detail::isa_cap().load(std::memory_order_relaxed);
    const int cpu = int(cpu_isa());
    const int level = cpu < cap ? cpu : cap;
    return level < int(compiled_isa()) ? compiled_isa() : Isa(level);
}

}  // namespace raykit
