/// @file simd_dispatch.h
/// withSimd(f): runs f compiled for the level simdLevel() chooses (private to the core). Each
/// level's entry is f inlined whole (gnu::flatten) into a function compiled for that level
/// (gnu::target), so that the kernel and what it inlines (the lanes of lanes.h, Eigen's small
/// matrices) use that level's registers and FMA; a call f makes that is not inlined runs the
/// build's own code. Where the build already targets a level, no entry below it is made.
#pragma once

#include "deformable_flsm/core/simd.h"

#include <type_traits>

namespace deformable_flsm {
namespace detail {

#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
#if !(defined(__AVX512F__) && defined(__AVX512BW__) && defined(__AVX512DQ__) && defined(__AVX512VL__))
#define FLSM_SIMD_V4_ENTRY 1
#endif
#if !(defined(__AVX2__) && defined(__FMA__))
#define FLSM_SIMD_V3_ENTRY 1
#endif
#endif
#ifndef FLSM_SIMD_V4_ENTRY
#define FLSM_SIMD_V4_ENTRY 0
#endif
#ifndef FLSM_SIMD_V3_ENTRY
#define FLSM_SIMD_V3_ENTRY 0
#endif

#if FLSM_SIMD_V4_ENTRY
template <class F>
[[gnu::target("arch=x86-64-v4"), gnu::flatten]] void runAtV4(F& f) {
  f();
}
#endif
#if FLSM_SIMD_V3_ENTRY
template <class F>
[[gnu::target("arch=x86-64-v3"), gnu::flatten]] void runAtV3(F& f) {
  f();
}
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
/// accumulators there: 4 at a level with AVX, else the build's own (`built`, 2 or 4).
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

/// f() at simdLevel(): one relaxed atomic load and a branch per call.
template <class F>
inline void withSimd(F&& f) {
  const SimdLevel level = simdLevel();
#if FLSM_SIMD_V4_ENTRY
  if (level == SimdLevel::X86_64_V4) return runAtV4(f);
#endif
#if FLSM_SIMD_V3_ENTRY
  if (level == SimdLevel::X86_64_V3) return runAtV3(f);
#endif
  (void)level;
  f();
}

}  // namespace detail
}  // namespace deformable_flsm
