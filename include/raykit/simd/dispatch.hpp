// raykit/simd/dispatch.hpp — the traversals compiled once per instruction-set level, and the
// public walks that call the level the CPU runs (raykit/simd/isa.hpp says why).
//
// Each traversal header (intersect/slab.hpp, intersect/triangle4.hpp, bvh/traverse.hpp,
// bvh/traverse_wide.hpp, bvh/traverse_packet.hpp, scene/trace.hpp) has a part included once
// (types, declarations) and a part below RAYKIT_ISA_PASS that this file includes once per level,
// inside namespace raykit::isa_<level> and a target pragma (GCC's `target`, clang's attribute
// push), with RAYKIT_ISA_SSE2 / SSE41 / AVX / FMA / AVX512 saying what the level has. The
// compiler's own flags decide the base level; levels above it that x86-64 CPUs may have get
// their own copy. Each public walk (raykit::closest_hit, any_hit, closest_hit_within, the two
// packet walks, traverse) switches on active_isa() and calls its level's copy: one load and
// a predictable branch per call. Nothing but these headers' own code is compiled under a
// target pragma (every other header they need is included before), so no inline function of
// the standard library or of GLM is ever emitted with instructions the CPU may lack.
//
// Not Highway: its dynamic dispatch (HWY_EXPORT) takes plain functions, and these walks are
// templates over the user's leaf filter; and the box tests rely on MAXPS/MINPS returning their
// second operand on NaN (intersect/slab.hpp), which the hand-written intrinsics keep.
#ifndef RAYKIT_SIMD_DISPATCH_HPP
#define RAYKIT_SIMD_DISPATCH_HPP

#include "raykit/simd/isa.hpp"
// the once parts, in dependency order (their own #include of this file is skipped: guarded)
#include "raykit/intersect/slab.hpp"
#include "raykit/intersect/triangle4.hpp"
#include "raykit/bvh/traverse.hpp"
#include "raykit/bvh/traverse_wide.hpp"
#include "raykit/bvh/traverse_packet.hpp"
#include "raykit/scene/trace.hpp"

#define RAYKIT_ISA_PASS 1

// ---- base: what the compiler's flags give ----
#define RAYKIT_ISA_NS isa_base
#if !defined(RAYKIT_NO_SIMD) && (defined(__SSE2__) || defined(_M_X64))
#define RAYKIT_ISA_SSE2 1
#else
#define RAYKIT_ISA_SSE2 0
#endif
#if !defined(RAYKIT_NO_SIMD) && defined(__SSE4_1__)
#define RAYKIT_ISA_SSE41 1
#else
#define RAYKIT_ISA_SSE41 0
#endif
#if !defined(RAYKIT_NO_SIMD) && defined(__AVX__)
#define RAYKIT_ISA_AVX 1
#else
#define RAYKIT_ISA_AVX 0
#endif
#if !defined(RAYKIT_NO_SIMD) && defined(__FMA__)
#define RAYKIT_ISA_FMA 1
#else
#define RAYKIT_ISA_FMA 0
#endif
#if !defined(RAYKIT_NO_SIMD) && defined(__AVX512F__)
#define RAYKIT_ISA_AVX512 1
#else
#define RAYKIT_ISA_AVX512 0
#endif
#include "raykit/simd/level.inc"

// ---- avx2 (x86-64-v3) and avx512 (AVX-512 F/VL/BW/DQ over it), each under its target ----
#define RAYKIT_ISA_PRAGMA(...) _Pragma(#__VA_ARGS__)
#if defined(__clang__)
#define RAYKIT_ISA_BEGIN(features) RAYKIT_ISA_PRAGMA(clang attribute push(__attribute__((target(features))), apply_to = function))
#define RAYKIT_ISA_END RAYKIT_ISA_PRAGMA(clang attribute pop)
#else
#define RAYKIT_ISA_BEGIN(features) RAYKIT_ISA_PRAGMA(GCC push_options) RAYKIT_ISA_PRAGMA(GCC target(features))
#define RAYKIT_ISA_END RAYKIT_ISA_PRAGMA(GCC pop_options)
#endif
#if RAYKIT_ISA_BUILD_AVX2
RAYKIT_ISA_BEGIN("sse4.1,sse4.2,popcnt,avx,avx2,fma,bmi,bmi2")
#define RAYKIT_ISA_NS isa_avx2
#define RAYKIT_ISA_SSE2 1
#define RAYKIT_ISA_SSE41 1
#define RAYKIT_ISA_AVX 1
#define RAYKIT_ISA_FMA 1
#define RAYKIT_ISA_AVX512 0
#include "raykit/simd/level.inc"
RAYKIT_ISA_END
#endif
#if RAYKIT_ISA_BUILD_AVX512
RAYKIT_ISA_BEGIN("sse4.1,sse4.2,popcnt,avx,avx2,fma,bmi,bmi2,avx512f,avx512vl,avx512bw,avx512dq")
#define RAYKIT_ISA_NS isa_avx512
#define RAYKIT_ISA_SSE2 1
#define RAYKIT_ISA_SSE41 1
#define RAYKIT_ISA_AVX 1
#define RAYKIT_ISA_FMA 1
#define RAYKIT_ISA_AVX512 1
#include "raykit/simd/level.inc"
RAYKIT_ISA_END
#endif
#undef RAYKIT_ISA_PRAGMA
#undef RAYKIT_ISA_BEGIN
#undef RAYKIT_ISA_END

#undef RAYKIT_ISA_PASS

/// `return <level namespace>::CALL;` for the level active_isa() names.
#if RAYKIT_ISA_BUILD_AVX512
#define RAYKIT_ISA_CASE_AVX512(...) \
    case ::raykit::Isa::avx512:     \
        return ::raykit::isa_avx512::__VA_ARGS__;
#else
#define RAYKIT_ISA_CASE_AVX512(...)
#endif
#if RAYKIT_ISA_BUILD_AVX2
#define RAYKIT_ISA_CASE_AVX2(...) \
    case ::raykit::Isa::avx2:     \
        return ::raykit::isa_avx2::__VA_ARGS__;
#else
#define RAYKIT_ISA_CASE_AVX2(...)
#endif
#if RAYKIT_ISA_BUILD_AVX2 || RAYKIT_ISA_BUILD_AVX512
#define RAYKIT_ISA_DISPATCH(...)                    \
    switch (::raykit::active_isa()) {               \
        RAYKIT_ISA_CASE_AVX512(__VA_ARGS__)         \
        RAYKIT_ISA_CASE_AVX2(__VA_ARGS__)           \
        default:                                    \
            return ::raykit::isa_base::__VA_ARGS__; \
    }
#else
#define RAYKIT_ISA_DISPATCH(...) return ::raykit::isa_base::__VA_ARGS__;
#endif

namespace raykit {

// The per-ray state types, as the base level has them (tests compare them with their scalar forms).
using isa_base::SlabRay;
using isa_base::Watertight4;
using isa_base::WideSlabRay;

/// Ordered single-ray walk of a Bvh or WideBvhT (bvh/traverse.hpp, bvh/traverse_wide.hpp).
template <class Mode = ClosestHit, class Tree, class LeafFn, class Stats = std::nullptr_t>
bool traverse(const Tree& tree, const Ray& ray, float& tmax, LeafFn&& leaf, Stats stats = nullptr) {
    RAYKIT_ISA_DISPATCH(traverse<Mode>(tree, ray, tmax, leaf, stats))
}

template <class Tree, class Leaves, class Keep, class Stats>
Hit closest_hit_within(const Tree& tree, const Leaves& leaves, const Ray& ray, float tmax, const Keep& keep,
                       Stats stats) {
    RAYKIT_ISA_DISPATCH(closest_hit_within(tree, leaves, ray, tmax, keep, stats))
}

template <class Tree, class Leaves, class Keep, class Stats>
Hit closest_hit(const Tree& tree, const Leaves& leaves, const Ray& ray, const Keep& keep, Stats stats) {
    RAYKIT_ISA_DISPATCH(closest_hit_within(tree, leaves, ray, ray.tmax, keep, stats))
}

template <class Tree, class Leaves, class Keep, class Stats>
bool any_hit(const Tree& tree, const Leaves& leaves, const Ray& ray, const Keep& keep, Stats stats) {
    RAYKIT_ISA_DISPATCH(any_hit(tree, leaves, ray, keep, stats))
}

template <class Tree, class Leaves, class Keep>
void closest_hit_packet(const Tree& tree, const Leaves& leaves, const Ray* rays, const float* tmax, unsigned n,
                        Hit* hits, const Keep& keep) {
    RAYKIT_ISA_DISPATCH(closest_hit_packet(tree, leaves, rays, tmax, n, hits, keep))
}

template <class Tree, class Leaves, class Keep>
unsigned any_hit_packet(const Tree& tree, const Leaves& leaves, const Ray* rays, unsigned n, const Keep& keep) {
    RAYKIT_ISA_DISPATCH(any_hit_packet(tree, leaves, rays, n, keep))
}

}  // namespace raykit

#endif  // RAYKIT_SIMD_DISPATCH_HPP
