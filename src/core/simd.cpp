#include "deformable_flsm/core/simd.h"

#include "region_kernels.h"
#include "simd_dispatch.h"

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <cstring>
#include <string>

namespace deformable_flsm {

namespace {

SimdLevel detectCpu() {
#if defined(__x86_64__) && defined(__GNUC__) && !defined(__clang__)
  __builtin_cpu_init();
  if (__builtin_cpu_supports("x86-64-v4")) return SimdLevel::X86_64_V4;
  if (__builtin_cpu_supports("x86-64-v3")) return SimdLevel::X86_64_V3;
#endif
  return SimdLevel::Baseline;
}

SimdLevel lower(SimdLevel a, SimdLevel b) { return static_cast<int>(a) < static_cast<int>(b) ? a : b; }

/// The highest level this build has code for: its own, or an entry of simd_dispatch.h above it.
SimdLevel reachable() {
  if (FLSM_SIMD_V4_ENTRY) return SimdLevel::X86_64_V4;
  if (FLSM_SIMD_V3_ENTRY) return SimdLevel::X86_64_V3;
  return builtSimdLevel();
}

struct Choice {
  SimdLevel cpu = detectCpu();
  /// the CPU's level, capped at what the build has code for
  SimdLevel top = lower(cpu, reachable());
  std::atomic<int> level{static_cast<int>(top)};
  /// what FLSM_SIMD asked, or that it was refused ("" when it is not set)
  std::string why;

  Choice() {
    const char* asked = std::getenv("FLSM_SIMD");
    SimdLevel parsed = cpu;
    if (asked != nullptr && *asked != '\0') {
      if (!parseSimdLevel(asked, parsed)) {
        why = std::string("; FLSM_SIMD '") + asked + "' ignored (baseline, x86-64-v3 or x86-64-v4)";
      } else {
        level = static_cast<int>(lower(parsed, top));
        why = std::string("; FLSM_SIMD=") + asked;
      }
    }
  }
};

Choice& choice() {
  static Choice c;
  return c;
}

}  // namespace

const char* toString(SimdLevel level) {
  switch (level) {
    case SimdLevel::X86_64_V4: return "x86-64-v4";
    case SimdLevel::X86_64_V3: return "x86-64-v3";
    case SimdLevel::Baseline: break;
  }
  return "baseline";
}

bool parseSimdLevel(const char* text, SimdLevel& level) {
  for (SimdLevel l : {SimdLevel::Baseline, SimdLevel::X86_64_V3, SimdLevel::X86_64_V4}) {
    if (text != nullptr && std::strcmp(text, toString(l)) == 0) {
      level = l;
      return true;
    }
  }
  return false;
}

SimdLevel cpuSimdLevel() { return choice().cpu; }

SimdLevel builtSimdLevel() {
#if defined(__AVX512F__) && defined(__AVX512BW__) && defined(__AVX512DQ__) && defined(__AVX512VL__)
  return SimdLevel::X86_64_V4;
#elif defined(__AVX2__) && defined(__FMA__)
  return SimdLevel::X86_64_V3;
#else
  return SimdLevel::Baseline;
#endif
}

SimdLevel simdLevel() {
  // the build's own code is never below its own level
  const int asked = choice().level.load(std::memory_order_relaxed);
  return static_cast<SimdLevel>(std::max(asked, static_cast<int>(builtSimdLevel())));
}

SimdLevel setSimdLevel(SimdLevel level) {
  choice().level.store(static_cast<int>(lower(level, choice().top)), std::memory_order_relaxed);
  return simdLevel();
}

std::string simdLevelNote() {
  const Choice& c = choice();
  return std::string("SIMD: ") + toString(simdLevel()) + " (the CPU runs " + toString(c.cpu) +
         ", the build targets " + toString(builtSimdLevel()) + ")" + c.why;
}

namespace detail {

// The per-level copies of region_kernels.cpp exist where simd_dispatch.h has wider entries:
// CMakeLists.txt compiles them under the same condition and says so.
#if (FLSM_SIMD_V3_ENTRY || FLSM_SIMD_V4_ENTRY) && !defined(FLSM_LEVEL_KERNELS)
#error "a build for the x86-64 baseline needs region_kernels.cpp compiled per level (CMakeLists.txt)"
#endif

RegionKernels regionKernels() {
  const SimdLevel level = simdLevel();
#if FLSM_SIMD_V4_ENTRY
  if (level == SimdLevel::X86_64_V4) return {rotationBatchV4, regionBatchV4, fusedMultiplyAddProbeV4};
#endif
#if FLSM_SIMD_V3_ENTRY
  if (level == SimdLevel::X86_64_V3) return {rotationBatchV3, regionBatchV3, fusedMultiplyAddProbeV3};
#endif
  (void)level;
  return {rotationBatchOwn, regionBatchOwn, fusedMultiplyAddProbeOwn};
}

double fusedMultiplyAddProbe(double a, double c) {
  double r = 0.0;
  withSimd([&] { r = a * a - c; });
  return r;
}

double regionKernelsFusedMultiplyAddProbe(double a, double c) { return regionKernels().fusedMultiplyAddProbe(a, c); }

}  // namespace detail

}  // namespace deformable_flsm
