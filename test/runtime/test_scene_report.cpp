/// @file test_scene_report.cpp
/// Tests of runtime/scene_report.h: the start-up summary and warnings of a small built scene (the
/// unit cube on a 10-cell lattice) carry the figures worked out by hand for it.
#include "deformable_flsm/runtime/scene_report.h"
#include "deformable_flsm/core/simd.h"

#include "deformable_flsm/runtime/scene.h"

#include "../core/fixtures.h"

#include <gtest/gtest.h>

#include <cmath>

#include <string>
#include <vector>

namespace deformable_flsm {
namespace {

/// The unit cube at resolution 10 (1000 particles of 0.1 m, 1000 kg at 1000 kg/m^3), the modulus
/// of the default material (E = 14 kPa, nu = 0), its bottom layer (100 particles) pinned.
NodeParams cubeParams() {
  NodeParams p;
  p.resolution = 10;
  p.solver.gravity.setZero();
  p.pinned.push_back(Box{Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(2, 2, 0.1)});
  p.applyMaterial();
  return p;
}

/// The cube's scene, its timings replaced by round figures so that the text is known exactly.
SceneInfo cubeInfo(const NodeParams& p) {
  SceneInfo info = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0).info;
  info.voxelizeSeconds = 0.012;
  info.stepSeconds = 0.004;
  info.nsPerParticleSubstep = 1000.0;  // 4 ms over 1000 particles x 4 sub-steps
  info.cpuFraction = 0.24;             // 4 ms of a 1/60 s step at real-time factor 1
  info.simd = "SIMD: x86-64-v3 (the CPU runs x86-64-v3, the build targets baseline)";
  return info;
}

TEST(SceneReport, TheSummaryOfTheCubeHasItsFigures) {
  const NodeParams p = cubeParams();
  const SceneInfo info = cubeInfo(p);
  // alpha asked: 6 mu h^2 / (rho dx^2 w (w + 1)) = 6 * 7000 * (1/240)^2 / (1000 * 0.01 * 2) = 0.0365
  const std::vector<std::string> expected = {
      "lattice: 1000 particles from ~resolution (spacing 0.1 m, voxelized in 12 ms); "
      "~particle_budget not used",
      "regions: 1000 (one per particle), half-width w = 1 cells (0.1 m) (the default); object "
      "1.732 m across, 1000 kg",
      "thinnest section: 10 cells (1 m; 5 % of the particles lie in thinner ones)",
      "material: Young's modulus 1.4e+04 Pa, density 1000 kg/m^3 -> alpha 0.0365 per sub-step "
      "(as asked)",
      "step: 0.0167 s in 4 sub-steps (fast solver) measured at 4.00 ms = 1000 ns per "
      "particle-substep; at real-time factor 1 the solver takes 24% of a core; SIMD: x86-64-v3 (the CPU "
      "runs x86-64-v3, the build targets baseline)",
      "render mesh: 12 triangles, 8 vertices",
      "colliders: 1 (with the ground), particles collide as spheres of radius 0.05 m",
      "pinned: 100 particles (box 0: 100)",
  };
  EXPECT_EQ(sceneSummaryLines(info, p), expected);
  std::string joined = expected.front();
  for (std::size_t k = 1; k < expected.size(); ++k) joined += "\n" + expected[k];
  EXPECT_EQ(describeScene(info, p), joined);
  // within the solver's cap and the section, regions as asked: nothing to warn about
  EXPECT_EQ(saturationWarning(info, p), "");
  EXPECT_EQ(sectionWarning(info, p), "");
  EXPECT_EQ(regionClampWarning(info, p), "");
}

TEST(SceneReport, AnObjectOfSeveralHasNoStepLine) {
  const NodeParams p = cubeParams();
  SceneInfo info = cubeInfo(p);
  info.stepMeasured = false;
  const std::vector<std::string> lines = sceneSummaryLines(info, p);
  ASSERT_EQ(lines.size(), 7u);
  for (const std::string& line : lines) EXPECT_NE(line.rfind("step:", 0), 0u) << line;
  EXPECT_EQ(lines[4], "render mesh: 12 triangles, 8 vertices");
}

TEST(SceneReport, TheExplicitStepCappedWarnsWithTheSubstepsThatFixIt) {
  NodeParams p = cubeParams();
  p.youngsModulus = 1e9;  // asks alpha 6 * 5e8 * (1/240)^2 / 20 = 2604 per sub-step
  p.applyMaterial();
  const SceneInfo info = cubeInfo(p);
  ASSERT_GT(info.substepsForModulus, 4);
  const std::string material = sceneSummaryLines(info, p)[3];
  EXPECT_EQ(material.rfind("material: Young's modulus 1e+09 Pa, density 1000 kg/m^3 -> alpha ", 0), 0u)
      << material;
  EXPECT_NE(material.find(" per sub-step (saturated: softer than asked, see the warning)"), std::string::npos)
      << material;
  const std::string w = saturationWarning(info, p);
  EXPECT_EQ(w.rfind("~youngs_modulus 1e+09 Pa asks for alpha 2.6e+03 per sub-step, more than the ", 0), 0u) << w;
  EXPECT_NE(w.find("because the sub-step (0.00417 s) is too long. ~substeps " +
                   std::to_string(info.substepsForModulus) + " (instead of 4) would fix it"),
            std::string::npos)
      << w;
}

TEST(SceneReport, TheImplicitStepIsNotCappedSoDoesNotWarn) {
  NodeParams p = cubeParams();
  p.youngsModulus = 1e9;
  p.applyMaterial();
  p.solver.integrator = Integrator::Implicit;
  const SceneInfo info = cubeInfo(p);
  EXPECT_EQ(info.substepsForModulus, 0);
  EXPECT_EQ(saturationWarning(info, p), "");
  EXPECT_EQ(stiffContactWarning(info, p), "") << "alpha 2.6e3: below kStiffContactAlpha";
  const std::string material = sceneSummaryLines(info, p)[3];
  EXPECT_NE(material.find("alpha 2.6e+03 per sub-step (as asked)"), std::string::npos) << material;
}

// Above kStiffContactAlpha the implicit step's impacts may gain energy (bench_drop): the warning
// names the alpha and the fewest ~substeps that bring it below (alpha goes as 1 / substeps^2).
TEST(SceneReport, AStiffImplicitObjectWarnsWithTheSubstepsThatSettleItsContacts) {
  NodeParams p = cubeParams();
  p.youngsModulus = 1e10;  // alpha 2.6e4 per sub-step at 4 sub-steps
  p.applyMaterial();
  p.solver.integrator = Integrator::Implicit;
  const SceneInfo info = cubeInfo(p);
  ASSERT_GT(info.requestedAlpha, kStiffContactAlpha);
  const int n = static_cast<int>(std::ceil(4.0 * std::sqrt(info.requestedAlpha / kStiffContactAlpha)));
  EXPECT_LE(info.requestedAlpha * (4.0 / n) * (4.0 / n), kStiffContactAlpha);
  EXPECT_GT(info.requestedAlpha * (4.0 / (n - 1)) * (4.0 / (n - 1)), kStiffContactAlpha) << "the fewest";
  const std::string w = stiffContactWarning(info, p);
  EXPECT_EQ(w.rfind("~youngs_modulus 1e+10 Pa at a sub-step of 0.00417 s asks for alpha 2.6e+04 per sub-step", 0), 0u)
      << w;
  EXPECT_NE(w.find("~substeps " + std::to_string(n) + " (instead of 4) keeps alpha below it."), std::string::npos)
      << w;
  // the explicit step caps alpha instead (saturationWarning())
  p.solver.integrator = Integrator::Explicit;
  EXPECT_EQ(stiffContactWarning(cubeInfo(p), p), "");
}

TEST(SceneReport, ARegionRadiusBeyondTheLimitIsReportedClamped) {
  NodeParams p = cubeParams();
  p.regionRadius = 5.0;         // 50 cells of 0.1 m; the solver allows 10
  p.regionFromSection = false;  // the clamp, not the section, is reported here
  const SceneInfo info = cubeInfo(p);
  EXPECT_EQ(sceneSummaryLines(info, p)[1],
            "regions: 1000 (one per particle), half-width w = 10 cells (1 m) from ~region_radius, "
            "clamped; object 1.732 m across, 1000 kg");
  EXPECT_EQ(regionClampWarning(info, p),
            "~region_radius 5 m is 50 cells on this lattice (spacing 0.1 m), more than the 10 the "
            "solver allows: using 10 cells (1 m), the largest that fits. Set ~region_radius to at "
            "most 1 m, or use a coarser lattice (a larger ~spacing, a smaller ~resolution or "
            "~particle_budget), to silence this warning.");
  // 21 cells wide on a section of 10: bending stiffer than asked
  EXPECT_NE(sectionWarning(info, p).find("w = 10 cells (21 cells wide)"), std::string::npos);
}

// A measured step says which instruction set it ran at, chosen at run time for this CPU.
TEST(SceneReport, TheMeasuredStepNamesTheInstructionSet) {
  const NodeParams p = cubeParams();
  const SceneInfo info = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 1).info;
  EXPECT_EQ(info.simd, simdLevelNote());
  const std::vector<std::string> lines = sceneSummaryLines(info, p);
  const std::string step = lines[4];
  EXPECT_EQ(step.rfind("step: ", 0), 0u) << step;
  EXPECT_NE(step.find(std::string("SIMD: ") + toString(simdLevel())), std::string::npos) << step;
}

}  // namespace
}  // namespace deformable_flsm
