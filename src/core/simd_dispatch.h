/// @file simd_dispatch.h
/// withSimd(f): runs f compiled for the level simdLevel() chooses (private to the core). Each
/// level's entry is f inlined whole (gnu::flatten) into a function compiled for that level
/// (gnu::target), so that the kernel and what it inlines use that level's instructions: the
/// vector types (lanes.h, the sliding window's accumulators) its registers, and FMA throughout
/// (Eigen chooses its packets by the build's macros, so its own vectors stay 128-bit); a call f
/// makes that is not inlined runs the build's own code. The region pass's per-region kernels,
/// where this fell furthest behind a build for the level, are whole units per level instead
/// (region_kernels.h).
#pragma once

#include "deformable_flsm/core/simd.h"

#include <type_traits>

namespace deformable_flsm {
namespace detail {

// Entries only in a build for the baseline (no AVX): a build for a wider target (-march=native,
// -march=znver2, ...) runs its own code, since GCC does not inline a kernel compiled for one
// -march into a function for another (the entry would run the build's code under a wider name).
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__) && !defined(__AVX__)
#define FLSM_SIMD_V4_ENTRY 1
#define FLSM_SIMD_V3_ENTRY 1
#endif
#ifndef FLSM_SIMD_V4_ENTRY
#define FLSM_SIMD_V4_ENTRY 0
#endif
#ifndef FLSM_SIMD_V3_ENTRY
#define FLSM_SIMD_V3_ENTRY 0
#endif

#if FLSM_SIMD_V4_ENTRY
template <class F>
[[gnu::target("arch=x86-64-v4"), gnu::flatten]] void runWideAtV4(F& f) {
  f(std::integral_constant<int, 4>{});
}
#endif
#if FLSM_SIMD_V3_ENTRY
template <class F>
[[gnu::target("arch=x86-64-v3"), gnu::flatten]] void runWideAtV3(F& f) {
  f(std::integral_constant<int, 4>{});
}
#endif

/// f(std::integral_constant<int, W>) at simdLevel(), W the vector width of the sliding window's
/// accumulators there: 4 at a level with AVX, else the build's own (`built`, 2 or 4). One relaxed
/// atomic load and a branch per call.
template <int built, class F>
inline void withSimdWidth(F&& f) {
  const SimdLevel level = simdLevel();
#if FLSM_SIMD_V4_ENTRY
  if (level == SimdLevel::X86_64_V4) return runWideAtV4(f);
#endif
#if FLSM_SIMD_V3_ENTRY
  if (level == SimdLevel::X86_64_V3) return runWideAtV3(f);
#endif
  (void)level;
  f(std::integral_constant<int, built>{});
}

/// f() at simdLevel() (withSimdWidth() for a kernel without a width).
template <class F>
inline void withSimd(F&& f) {
  withSimdWidth<0>([&f](auto) { f(); });
}

}  // namespace detail
}  // namespace deformable_flsm
