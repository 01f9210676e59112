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
#define RAYKIT_RESTRICT __restrict__
#else
#define RAYKIT_INLINE inline
#define RAYKIT_LAMBDA_INLINE
#define RAYKIT_RESTRICT
#endif

/// 1 when the target has a fused multiply-add instruction (x86 FMA3, or any
/// target whose compiler says fmaf is fast, e.g. AArch64): raykit's
/// watertight test then fuses its two multiply-adds explicitly (std::fma),
/// else it rounds each product. Either way the choice is the code's, not the
/// optimizer's, so answers do not change with -O levels or -ffp-contract.
#if defined(__FMA__) || defined(__FP_FAST_FMAF) || defined(__ARM_FEATURE_FMA)
#define RAYKIT_FAST_FMA 1
#else
#define RAYKIT_FAST_FMA 0
#endif
