/// @file simd.h
/// The instruction set the core's hot kernels run on, chosen at run time for the CPU the binary
/// lands on: a package built for the x86-64 baseline (as a binary package is, and as a plain
/// `catkin_make` builds it) runs its region pass, rotation extraction and per-particle update
/// with AVX2 and FMA (x86-64-v3) or AVX-512 (x86-64-v4) where the CPU has them, as a build with
/// `-march=native` does. A build for any wider target (`-march=native`) uses its own code.
///
/// The environment variable FLSM_SIMD (`baseline`, `x86-64-v3`, `x86-64-v4`) lowers the level at
/// start-up (never above what the CPU runs); setSimdLevel() does the same from code.
#pragma once

#include <string>

namespace deformable_flsm {

/// x86-64 microarchitecture levels (the psABI's): the baseline (SSE2), v3 (AVX2, FMA, BMI2, ...)
/// and v4 (AVX-512 F, BW, CD, DQ, VL).
enum class SimdLevel { Baseline = 0, X86_64_V3 = 3, X86_64_V4 = 4 };

/// "baseline", "x86-64-v3" or "x86-64-v4".
const char* toString(SimdLevel level);
/// The inverse of toString(); false (and `level` untouched) for any other text.
bool parseSimdLevel(const char* text, SimdLevel& level);

/// The highest level this CPU runs (read once; the baseline off x86-64).
SimdLevel cpuSimdLevel();
/// The level this build's own code targets (its compiler flags): what runs where the CPU has no
/// more, and where the kernels are not dispatched.
SimdLevel builtSimdLevel();
/// The level the kernels run at: cpuSimdLevel() (capped at the highest the build has code for:
/// a build for the baseline has x86-64-v3 and v4 besides its own, any other build only its own),
/// lowered by FLSM_SIMD when that is set and valid (an invalid value is ignored and
/// simdLevelNote() says so), or by setSimdLevel(); never below builtSimdLevel().
SimdLevel simdLevel();
/// Sets the level the kernels run at, capped at cpuSimdLevel() and at the highest level the build
/// has code for; returns simdLevel() after it. For tests and benchmarks: set it before stepping,
/// not while another thread steps.
SimdLevel setSimdLevel(SimdLevel level);
/// One line for a start-up log: the level in use, the CPU's and the build's, and what FLSM_SIMD
/// asked.
std::string simdLevelNote();

namespace detail {
/// a * a - c computed at simdLevel(): rounded twice at a level without FMA, once with it (for
/// tests: a = 1 + 2^-30, c = 1 + 2^-29 gives 0 without FMA and 2^-60 with it).
double fusedMultiplyAddProbe(double a, double c);
/// The same, computed by the region kernels' unit for simdLevel() (compiled whole per level).
double regionKernelsFusedMultiplyAddProbe(double a, double c);
}  // namespace detail

}  // namespace deformable_flsm
