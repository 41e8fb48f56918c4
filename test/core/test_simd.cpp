// The instruction set chosen at run time (simd.h): the level's names, its bounds, and the same
// motion at every level the CPU runs (the kernels compiled for each level are the same
// arithmetic, reordered and fused differently: round-off apart).
#include "deformable_flsm/core/simd.h"
#include "deformable_flsm/core/solver.h"
#include "fixtures.h"
#include "support/params.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <vector>

using deformable_flsm::Integrator;
using deformable_flsm::Lattice;
using deformable_flsm::SimdLevel;
using deformable_flsm::Solver;
using deformable_flsm::SolverParams;

namespace {

constexpr SimdLevel kLevels[] = {SimdLevel::Baseline, SimdLevel::X86_64_V3, SimdLevel::X86_64_V4};

bool runs(SimdLevel level) { return static_cast<int>(level) <= static_cast<int>(deformable_flsm::cpuSimdLevel()); }

/// Restores the level the process started with.
struct LevelGuard {
  SimdLevel before = deformable_flsm::simdLevel();
  ~LevelGuard() { deformable_flsm::setSimdLevel(before); }
};

/// A 7 x 6 x 5 block (w = 2, nu 0.3: the rotation batch, the region and particle passes and the
/// Poisson term all work), deformed and spinning, stepped 40 times: the positions.
std::vector<Eigen::Vector3d> spinningBlock(Integrator integrator) {
  auto lattice = std::make_shared<const Lattice>(deformable_flsm::test::makeBox(7, 6, 5, 0.01), 1000.0, 2);
  SolverParams p = deformable_flsm::test::physicalParams(2e4, 0.3, 2, 1.0 / 60.0, 4, integrator);
  p.gravity.setZero();
  Solver s(lattice, p);
  deformable_flsm::test::deformAndSpin(s, Eigen::Vector3d(0.0, 0.0, 3.0), 7);
  for (int i = 0; i < 40; ++i) s.step();
  return s.positions();
}

}  // namespace

TEST(Simd, LevelsHaveNamesBothWays) {
  for (SimdLevel level : kLevels) {
    SimdLevel parsed = SimdLevel::Baseline;
    EXPECT_TRUE(deformable_flsm::parseSimdLevel(deformable_flsm::toString(level), parsed));
    EXPECT_EQ(parsed, level);
  }
  SimdLevel untouched = SimdLevel::X86_64_V3;
  EXPECT_FALSE(deformable_flsm::parseSimdLevel("avx512", untouched));
  EXPECT_FALSE(deformable_flsm::parseSimdLevel(nullptr, untouched));
  EXPECT_EQ(untouched, SimdLevel::X86_64_V3);
}

// Never above the CPU (the instructions would fault), never below the build (no code there).
TEST(Simd, TheLevelStaysWithinTheCpuAndTheBuild) {
  const LevelGuard guard;
  const int built = static_cast<int>(deformable_flsm::builtSimdLevel());
  // a build for the baseline has code up to v4 (x86-64, GCC), any other only its own
  const int cpu = static_cast<int>(deformable_flsm::cpuSimdLevel());
  const int top = std::min(cpu, built == 0 && deformable_flsm::setSimdLevel(SimdLevel::X86_64_V4) != SimdLevel::Baseline
                                    ? 4
                                    : built);
  for (SimdLevel level : kLevels) {
    const int set = static_cast<int>(deformable_flsm::setSimdLevel(level));
    EXPECT_EQ(set, std::max(built, std::min(static_cast<int>(level), top))) << deformable_flsm::toString(level);
    EXPECT_EQ(set, static_cast<int>(deformable_flsm::simdLevel()));
  }
  const std::string note = deformable_flsm::simdLevelNote();
  EXPECT_NE(note.find(deformable_flsm::toString(deformable_flsm::cpuSimdLevel())), std::string::npos) << note;
}

// Each level runs its own code: FMA rounds a * a - c once where the level has it (x86-64-v3 and
// v4), twice in a build for the baseline at its own level. A dispatch that ran the build's code
// at every level would fail here.
TEST(Simd, EachLevelRunsItsOwnInstructions) {
  const LevelGuard guard;
  const double a = 1.0 + std::ldexp(1.0, -30), c = 1.0 + std::ldexp(1.0, -29);
  for (SimdLevel level : kLevels) {
    if (!runs(level) || deformable_flsm::setSimdLevel(level) != level) continue;
    const double r = deformable_flsm::detail::fusedMultiplyAddProbe(a, c);
    const bool fused = level != SimdLevel::Baseline || deformable_flsm::builtSimdLevel() != SimdLevel::Baseline;
    std::printf("[ simd ] %s: a * a - c = %g (%s)\n", deformable_flsm::toString(level), r, fused ? "fused" : "rounded twice");
    EXPECT_EQ(r, fused ? std::ldexp(1.0, -60) : 0.0) << deformable_flsm::toString(level);
    // the region kernels' unit, compiled whole for the level
    const double k = deformable_flsm::detail::regionKernelsFusedMultiplyAddProbe(a, c);
    std::printf("[ simd ] %s, region kernels: a * a - c = %g\n", deformable_flsm::toString(level), k);
    EXPECT_EQ(k, fused ? std::ldexp(1.0, -60) : 0.0) << deformable_flsm::toString(level);
  }
}

// Every level the CPU runs moves the block as the CPU's own level does, within round-off grown
// over 40 steps (measured: under 1e-12 m), with both integrators.
TEST(Simd, EveryLevelMovesTheBlockAlike) {
  const LevelGuard guard;
  for (Integrator integrator : {Integrator::Explicit, Integrator::Implicit}) {
    deformable_flsm::setSimdLevel(deformable_flsm::cpuSimdLevel());
    const std::vector<Eigen::Vector3d> reference = spinningBlock(integrator);
    for (SimdLevel level : kLevels) {
      if (!runs(level)) continue;
      deformable_flsm::setSimdLevel(level);
      const std::vector<Eigen::Vector3d> x = spinningBlock(integrator);
      double worst = 0.0;
      for (std::size_t i = 0; i < x.size(); ++i) worst = std::max(worst, (x[i] - reference[i]).norm());
      std::printf("[ simd ] %s, %s: largest difference %.3g m\n", deformable_flsm::toString(deformable_flsm::simdLevel()),
                  integrator == Integrator::Explicit ? "explicit" : "implicit", worst);
      EXPECT_LT(worst, 1e-9) << deformable_flsm::toString(level);
    }
  }
}
