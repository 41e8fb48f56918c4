// The material of the solver in physical mode (Young's modulus, Poisson's ratio) against the FEM
// oracle and analytic elasticity: a cantilever's deflection, regions chosen from the section, a
// column's settlement and a bar's uniaxial stretch, explicit and implicit. bench_material prints
// the full tables.
#include "deformable_flsm/core/section.h"
#include "deformable_flsm/core/solver.h"
#include "fixtures.h"
#include "solver_material_fixtures.h"
#include "support/fem_oracle.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

using deformable_flsm::FemMaterial;
using deformable_flsm::FemOracle;
using deformable_flsm::FemSolution;
using deformable_flsm::Integrator;
using deformable_flsm::Lattice;
using deformable_flsm::Solver;
using deformable_flsm::SolverParams;
using deformable_flsm::Voxelization;
using namespace deformable_flsm::solver_material_fixtures;
namespace analytic = deformable_flsm::analytic;

namespace {

void settle(Solver& s, double seconds) {
  for (int i = 0, n = static_cast<int>(std::ceil(seconds / kStep)); i < n; ++i) s.step();
}

struct Sag {
  double lattice = 0.0, oracle = 0.0;
  bool saturated = false;
};

/// A cantilever of section t = 0.1 m (`across` cells) and free length 0.8 m (L/t = 8), held by
/// its first two cell layers, sagging ~1 % of its length under a body load. The solver settles
/// with ambient damping at twice the first bending frequency (critical); the oracle is supported
/// where the lattice is, at the pinned particles. Mean deflection of the last cell layer (m).
/// `modulusScale` scales the solver's E only (the oracle keeps E): a wrong modulus must show.
Sag cantilever(int across, int w, int substeps, double nu, double modulusScale = 1.0) {
  const double t = 0.1, L = 0.8, h = t / across;
  const int along = static_cast<int>(std::lround(L / h));
  const Voxelization vox = box(along + 2, across, across, h, Eigen::Vector3d(-2 * h, 0, 0));
  const double E = modulusFor(h);
  const double g = 0.01 * L * E * t * t / (1.5 * kDensity * std::pow(L, 4));
  const double omega = analytic::cantileverFirstBendingFrequency(L, t, E, kDensity);
  SolverParams p = physical(modulusScale * E, nu, w, substeps);
  p.gravity = Eigen::Vector3d(0, 0, -g);
  p.ambientDamping = 2.0 * omega;
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, w);
  Solver s(lattice, p);
  s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.0, kBig, kBig), true);
  settle(s, 8.0 / omega);  // critically damped: (1 + 8) e^-8 = 0.3 % of the way left
  FemOracle fem(vox, FemMaterial{E, nu, kDensity}, std::max(2, 8 / across));
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(-0.5 * h + 1e-9, kBig, kBig));
  const FemSolution u = fem.solveStatic(p.gravity);
  Sag out;
  int count = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i)
    if (lattice->restPositions()[i].x() > L - h) {
      out.lattice += lattice->restPositions()[i].z() - s.positions()[i].z();
      out.oracle -= u.cellDisplacements[i].z();
      ++count;
    }
  out.lattice /= count;
  out.oracle /= count;
  out.saturated = s.stiffnessSaturated();
  return out;
}

/// A column of 4 x 4 x 16 cells (0.1 x 0.1 x 0.4 m) on a pinned base layer under its own weight:
/// mean top-layer settlement, solver and oracle (m).
Sag column(int w, double nu, double modulusScale = 1.0) {
  const int across = 4, up = 16;
  const double h = 0.025, H = up * h;
  const Voxelization vox = box(across, across, up + 1, h, Eigen::Vector3d(0, 0, -h));
  const double E = modulusFor(h);
  const double g = 0.004 * E / (kDensity * H);
  const double omega = 0.5 * M_PI * std::sqrt(E / kDensity) / H;
  SolverParams p = physical(modulusScale * E, nu, w, 4);
  p.gravity = Eigen::Vector3d(0, 0, -g);
  p.ambientDamping = 2.0 * omega;
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, w);
  Solver s(lattice, p);
  s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(kBig, kBig, 0.0), true);
  settle(s, 10.0 / omega);
  FemOracle fem(vox, FemMaterial{E, nu, kDensity}, 2);
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(kBig, kBig, -0.5 * h + 1e-9));
  const FemSolution u = fem.solveStatic(p.gravity);
  Sag out;
  int count = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i)
    if (lattice->restPositions()[i].z() > H - h) {
      out.lattice += lattice->restPositions()[i].z() - s.positions()[i].z();
      out.oracle -= u.cellDisplacements[i].z();
      ++count;
    }
  out.lattice /= count;
  out.oracle /= count;
  out.saturated = s.stiffnessSaturated();
  return out;
}

struct Strain {
  double axial = 0.0, lateral = 0.0, expectedAxial = 0.0;
  bool saturated = false;
};

/// A free bar of 16 x 4 x 4 cells (0.4 x 0.1 x 0.1 m) pulled by opposite forces on its end layers
/// (uniaxial stress sigma = eps E): the strains of its middle half.
/// `modulus` 0: E with alpha 0.3 at w 1 and 4 explicit sub-steps. The run lasts 12 / omega_1 and
/// at least `minSteps` steps (a stiff bar's 12 / omega_1 is a step or two).
Strain stretch(int w, double nu, int substeps, Integrator integrator = Integrator::Explicit, double modulus = 0.0,
               int minSteps = 0) {
  const int along = 16, across = 4;
  const double h = 0.025, t = across * h;
  const Voxelization vox = box(along, across, across, h, Eigen::Vector3d::Zero());
  const double E = modulus > 0.0 ? modulus : modulusFor(h);
  const double F = 0.002 * E * t * t;
  const double omega = M_PI * std::sqrt(E / kDensity) / (along * h);
  SolverParams p = physical(E, nu, w, substeps);
  p.integrator = integrator;
  p.gravity.setZero();
  p.ambientDamping = 2.0 * omega;
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, w);
  Solver s(lattice, p);
  pullEnds(s, along, F, 1e9);
  settle(s, std::max(12.0 / omega, minSteps * kStep));
  const int i1 = along / 4, i2 = 3 * along / 4;
  double a1 = 0, a2 = 0, lo = 0, hi = 0;
  int n1 = 0, n2 = 0, nlo = 0, nhi = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i) {
    const Eigen::Vector3i& c = lattice->cells()[i];
    const Eigen::Vector3d& x = s.positions()[i];
    if (c.x() == i1) a1 += x.x(), ++n1;
    if (c.x() == i2) a2 += x.x(), ++n2;
    if (c.x() >= i1 && c.x() <= i2) {
      if (c.y() == 0) lo += x.y(), ++nlo;
      if (c.y() == across - 1) hi += x.y(), ++nhi;
    }
  }
  Strain out;
  out.axial = (a2 / n2 - a1 / n1) / ((i2 - i1) * h) - 1.0;
  out.lateral = (hi / nhi - lo / nlo) / ((across - 1) * h) - 1.0;
  out.expectedAxial = F / (t * t * E);
  out.saturated = s.stiffnessSaturated();
  return out;
}

}  // namespace

// The cantilever's tip deflection with the modulus asked for: within 10 % of the oracle where the
// region is at most half the section (R / t <= 1/2), for nu = 0, 0.3 and 0.4 and at 4 and 16
// sub-steps (bench_material prints the full table, docs/method.md holds it; wider regions are
// stiffer in bending, see SolverParams::regionHalfWidth). Two cells across, every region is
// clipped by the sides: the surface term of the Poisson part keeps such a bar from thinning too
// easily. A modulus off by 2x is 2x off here.
TEST(PhysicalMaterial, CantileverDeflectionMatchesTheFemOracle) {
  struct Case {
    int across, w, substeps;
    double nu;
  };
  for (const Case& c : {Case{4, 1, 4, 0.0}, Case{2, 1, 16, 0.0}, Case{4, 2, 4, 0.3}, Case{2, 1, 4, 0.3},
                        Case{2, 1, 16, 0.4}}) {
    const Sag s = cantilever(c.across, c.w, c.substeps, c.nu);
    EXPECT_FALSE(s.saturated);
    EXPECT_NEAR(s.lattice / s.oracle, 1.0, 0.10)
        << c.across << " cells across, w " << c.w << ", " << c.substeps << " sub-steps, nu " << c.nu << ": "
        << 1e3 * s.lattice << " mm, oracle " << 1e3 * s.oracle << " mm";
  }
  const Sag half = cantilever(2, 1, 4, 0.0, 0.5);
  EXPECT_GT(half.lattice / half.oracle, 1.6) << "half the modulus must sag about twice as far";
}

// Regions chosen from the section (core/section.h): asked for w = 3, cantilevers 2 and 4 cells
// across get the widest regions no wider than their section (w = 1) and bend within 10 % of the
// FEM oracle. The asked w = 3 itself is too stiff there (bench_material: 0.47 and 0.71 of the
// oracle's deflection), which is checked too, so that the choice matters. (At 8 cells across the
// choice is w = 3 itself, within 10 % too; its oracle takes minutes and a gigabyte: not here.)
TEST(PhysicalMaterial, RegionsChosenFromTheSectionBendLikeTheOracle) {
  struct Case {
    int across, expectedW;
  };
  for (const Case& c : {Case{2, 1}, Case{4, 1}}) {
    const double t = 0.1, L = 0.8, h = t / c.across;
    const int along = static_cast<int>(std::lround(L / h));
    const Voxelization vox = box(along + 2, c.across, c.across, h, Eigen::Vector3d(-2 * h, 0, 0));
    const deformable_flsm::SectionThickness section = deformable_flsm::measureSectionThickness(vox);
    EXPECT_EQ(section.thinnest, c.across);
    const int w = deformable_flsm::regionHalfWidthForSection(section.thinnest, 3);
    EXPECT_EQ(w, c.expectedW) << c.across << " cells across";
    const Sag chosen = cantilever(c.across, w, 4, 0.0);
    EXPECT_FALSE(chosen.saturated);
    EXPECT_NEAR(chosen.lattice / chosen.oracle, 1.0, 0.10)
        << c.across << " cells across, w " << w << ": " << 1e3 * chosen.lattice << " mm, oracle "
        << 1e3 * chosen.oracle << " mm";
    const Sag asked = cantilever(c.across, 3, 4, 0.0);
    EXPECT_LT(asked.lattice / asked.oracle, 0.85)
        << c.across << " cells across, w 3: " << 1e3 * asked.lattice << " mm, oracle " << 1e3 * asked.oracle << " mm";
  }
}

// Settlement of a column under its own weight (uniaxial compression, base held): within 10 %
// of the oracle for w = 1 to 3 (nu = 0) and nu = 0.3 (w = 1).
TEST(PhysicalMaterial, ColumnSettlementMatchesTheFemOracle) {
  for (int w = 1; w <= 3; ++w) {
    const Sag s = column(w, 0.0);
    EXPECT_NEAR(s.lattice / s.oracle, 1.0, 0.10) << "w " << w << ": " << 1e3 * s.lattice << " mm, oracle "
                                                 << 1e3 * s.oracle << " mm";
  }
  const Sag s = column(1, 0.3);
  EXPECT_NEAR(s.lattice / s.oracle, 1.0, 0.10) << "nu 0.3: " << 1e3 * s.lattice << " mm, oracle "
                                               << 1e3 * s.oracle << " mm";
  const Sag stiff = column(1, 0.0, 2.0);
  EXPECT_LT(stiff.lattice / stiff.oracle, 0.6) << "twice the modulus must settle about half as far";
}

// Uniaxial stress: the axial strain is sigma / E within 10 % and the lateral strain -nu eps within
// 0.05 of nu (a bar 4 cells across, w = 1, and w = 2 and 3 at nu = 0.3, whose regions are all
// clipped by the sides; the material must not be capped, which would soften it). Measured:
// 1.00 to 1.04 of sigma / E, -lateral / axial 0.28 to 0.40 (bench_material); without the surface
// term the clipped regions resisted lateral strain less than the interior and the bar yielded
// 1.09 (w 1) to 1.24 (w 3) at nu = 0.3.
TEST(PhysicalMaterial, UniaxialStretchHasTheModulusAndPoissonsRatioAskedFor) {
  struct Case {
    int w;
    double nu;
  };
  for (const Case& c : {Case{1, 0.0}, Case{1, 0.2}, Case{1, 0.3}, Case{1, 0.4}, Case{2, 0.3}, Case{3, 0.3}}) {
    // nu = 0.4 (lambda = 2.9 mu) needs shorter sub-steps than the others for the same E
    const Strain s = stretch(c.w, c.nu, c.nu > 0.3 ? 16 : 4);
    ASSERT_FALSE(s.saturated) << "w " << c.w << " nu " << c.nu;
    EXPECT_NEAR(s.axial / s.expectedAxial, 1.0, 0.10) << "w " << c.w << " nu " << c.nu;
    EXPECT_NEAR(-s.lateral / s.axial, c.nu, 0.05) << "w " << c.w << " nu " << c.nu;
  }
}

// The implicit step at ONE sub-step of 1/60 s, from a soft to a stiff material: the stretched
// bar settles to sigma / E and -nu within the explicit step's bounds above, where the explicit
// step at one sub-step is capped (the bar is pulled apart, bench_material). A stiff
// bar needs steps, not time, to settle: its conjugate gradients stop at a relative tolerance, and
// 10 / omega_1 is a step or two (bench_material ran that long and read 0.85 of sigma / E).
TEST(PhysicalMaterial, ImplicitStepStretchesAsAskedFromSoftToStiffAtOneSubstep) {
  for (double E : {30e3, 1e6, 10e6})
    for (double nu : {0.0, 0.3}) {
      const Strain s = stretch(1, nu, 1, Integrator::Implicit, E, 90);
      EXPECT_NEAR(s.axial / s.expectedAxial, 1.0, 0.10) << "E " << E << " nu " << nu;
      EXPECT_NEAR(-s.lateral / s.axial, nu, 0.05) << "E " << E << " nu " << nu;
    }
}
