// raykit/config.hpp — version and the few compile-time knobs of the library.
//
// Every macro raykit defines starts with RAYKIT_. Users may predefine the knobs
// marked "overridable" before including any raykit header.
#pragma once

#define RAYKIT_VERSION_MAJOR 0
#define RAYKIT_VERSION_MINOR 1
#define RAYKIT_VERSION_PATCH 0

/// Largest depth (root = depth 0) of any BVH a raykit builder emits. Builders
/// enforce it (see bvh/depth.hpp), so a traversal stack of RAYKIT_BVH_MAX_DEPTH
/// entries can never overflow. Overridable; must be at least 40 so that a median
/// split over 2^32 primitives still fits below the bound.
#ifndef RAYKIT_BVH_MAX_DEPTH
#define RAYKIT_BVH_MAX_DEPTH 64
#endif
static_assert(RAYKIT_BVH_MAX_DEPTH >= 40, "RAYKIT_BVH_MAX_DEPTH must be at least 40");

#if defined(__GNUC__) || defined(__clang__)
#define RAYKIT_INLINE inline __attribute__((always_inline))
#define RAYKIT_LAMBDA_INLINE __attribute__((always_inline))
#define RAYKIT_NOINLINE __attribute__((noinline))
#define RAYKIT_RESTRICT __restrict__
#else
#define RAYKIT_INLINE inline
#define RAYKIT_LAMBDA_INLINE
#define RAYKIT_NOINLINE
#define RAYKIT_RESTRICT
#endif

/// The one FMA rule: 1 (the default) makes raykit's watertight test fuse its two multiply-adds
/// (one rounding each) on every target, every instruction-set level the traversals dispatch to
/// (raykit/simd/isa.hpp) and the OpenCL device, so answers do not depend on the compiler's flags,
/// -O level, -ffp-contract or the CPU: one fused instruction where the CPU has FMA (every x86-64
/// CPU since 2013, AArch64, GPUs), std::fma's exact software form where it has none.
/// Overridable: 0 rounds each product on its own instead, for targets without FMA that would
/// rather be fast than agree (answers may then differ from the device's and other builds' in
/// the last bits of t, u, v).
#ifndef RAYKIT_FMA
#define RAYKIT_FMA 1
#endif
