// The implicit integrator (Solver with SolverParams::integrator = Implicit, solver_implicit.cpp):
// momentum, the material against the FEM oracle at one sub-step where the explicit step
// saturates, stability at long steps, constraints, thread-count independence, steps that
// allocate nothing, and BDF2.
#include "support/fem_oracle.h"
#include "deformable_flsm/core/solver.h"
#include "allocation_counter.h"
#include "fixtures.h"
#include "solver_implicit_fixtures.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/resolution.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <new>
#include <string>
#include <vector>

using deformable_flsm::Collider;
using deformable_flsm::ColliderType;
using deformable_flsm::FemMaterial;
using deformable_flsm::FemOracle;
using deformable_flsm::FemSolution;
using deformable_flsm::Integrator;
using deformable_flsm::Lattice;
using deformable_flsm::Solver;
using deformable_flsm::SolverParams;
using deformable_flsm::Voxelization;
using namespace deformable_flsm::solver_implicit_fixtures;
namespace analytic = deformable_flsm::analytic;

namespace {

/// A notched block (regions clipped by the surface and the notch), 6 x 5 x 4 cells of 1 cm.
Voxelization notched() {
  return deformable_flsm::test::makeVoxels(Eigen::Vector3i(6, 5, 4), 0.01,
                                           [](int i, int j, int k) { return !(i >= 3 && j >= 3 && k >= 2); });
}

struct Sag {
  double lattice = 0.0, oracle = 0.0;
  bool explicitSaturated = false;
  int maxIterations = 0;  // CG iterations of the worst step
};

/// The clamped cantilever of test_solver_material.cpp (section 0.1 m, 4 cells across, free length
/// 0.8 m, held by its first two cell layers, w = 1) at modulus E, loaded to sag ~1 % of its length,
/// at ONE sub-step of 1/60 s. Critically damped (ambient damping 2 omega_1) and settled for
/// 8 / omega_1; mean deflection of the last cell layer, solver and FEM oracle (m).
Sag cantilever(double E, double nu) {
  const int across = 4;
  const double t = 0.1, L = 0.8, h = t / across;
  const int along = static_cast<int>(std::lround(L / h));
  Voxelization vox = deformable_flsm::test::makeBox(along + 2, across, across, h);
  vox.origin = Eigen::Vector3d(-2 * h, 0, 0);
  const double g = 0.01 * L * E * t * t / (1.5 * kDensity * std::pow(L, 4));
  const double omega = analytic::cantileverFirstBendingFrequency(L, t, E, kDensity);
  SolverParams p = implicitParams(E, nu, 1, 1.0 / 60.0);
  p.gravity = Eigen::Vector3d(0, 0, -g);
  p.ambientDamping = 2.0 * omega;
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, 1);
  Solver s(lattice, p);
  s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.0, kBig, kBig), true);
  const int steps = static_cast<int>(std::ceil(std::max(8.0 / omega, 1.0) * 60.0));
  Sag out;
  for (int i = 0; i < steps; ++i) {
    s.step();
    out.maxIterations = std::max(out.maxIterations, s.lastImplicitSolve().iterations);
  }
  FemOracle fem(vox, FemMaterial{E, nu, kDensity}, 2);
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(-0.5 * h + 1e-9, kBig, kBig));
  const FemSolution u = fem.solveStatic(p.gravity);
  int count = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i)
    if (lattice->restPositions()[i].x() > L - h) {
      out.lattice += lattice->restPositions()[i].z() - s.positions()[i].z();
      out.oracle -= u.cellDisplacements[i].z();
      ++count;
    }
  out.lattice /= count;
  out.oracle /= count;
  SolverParams e = p;
  e.integrator = Integrator::Explicit;
  out.explicitSaturated = Solver(lattice, e).stiffnessSaturated();
  return out;
}

}  // namespace

TEST(Integrator, ParsesItsNamesAndRefusesOthers) {
  EXPECT_EQ(deformable_flsm::parseIntegrator("explicit"), Integrator::Explicit);
  EXPECT_EQ(deformable_flsm::parseIntegrator("implicit"), Integrator::Implicit);
  EXPECT_STREQ(deformable_flsm::toString(Integrator::Implicit), "implicit");
  EXPECT_THROW(deformable_flsm::parseIntegrator("backward_euler"), std::invalid_argument);
}

// The implicit step has no stability cap: alpha is what the modulus asks for, never saturated.
TEST(ImplicitStep, TakesTheRequestedAlphaWithoutCap) {
  auto lattice = std::make_shared<const Lattice>(notched(), kDensity, 1);
  SolverParams p = implicitParams(1e6, 0.3, 1, 1.0 / 60.0);
  Solver s(lattice, p);
  EXPECT_FALSE(s.stiffnessSaturated());
  EXPECT_DOUBLE_EQ(s.alpha(), p.requestedAlpha(lattice->spacing()));
  p.integrator = Integrator::Explicit;
  Solver e(lattice, p);
  EXPECT_TRUE(e.stiffnessSaturated()) << "the explicit step cannot take 1 MPa at 1 cm in one sub-step";
}

// Free of external forces, a deformed, spinning object keeps its linear and angular momentum to
// round-off (the step corrects the CG's residual along the six rigid modes), with region and
// ambient damping and the Poisson term on.
TEST(ImplicitStep, DeformedSpinningObjectKeepsItsMomentum) {
  for (double nu : {0.0, 0.3}) {
    SolverParams p = implicitParams(1e6, nu, 2, 1.0 / 60.0);
    p.gravity.setZero();
    p.ambientDamping = 2.0;
    Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
    const auto scale = deformable_flsm::test::deformAndSpin(s, Eigen::Vector3d(2.0, 0.0, 5.0), 17);
    const double pScale = scale.linear, lScale = scale.angular;
    const Eigen::Vector3d P0 = s.linearMomentum(), L0 = s.angularMomentum();
    for (int i = 0; i < 120; ++i) s.step();
    EXPECT_LT((s.linearMomentum() - P0).norm(), 1e-10 * pScale) << "nu " << nu;
    EXPECT_LT((s.angularMomentum() - L0).norm(), 1e-10 * lScale) << "nu " << nu;
    EXPECT_LT(s.shapeError(), 1e-3 * s.lattice().objectSize()) << "the wobble is damped out, nu " << nu;
  }
}

// Free fall: gravity's impulse exactly, no deformation.
TEST(ImplicitStep, FreeFallIsExact) {
  SolverParams p = implicitParams(1e6, 0.3, 2, 1.0 / 60.0);
  Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
  for (int i = 0; i < 60; ++i) s.step();
  const Eigen::Vector3d expected = s.lattice().totalMass() * s.time() * p.gravity;
  EXPECT_LT((s.linearMomentum() - expected).norm(), 1e-9 * expected.norm());
  EXPECT_LT(s.shapeError(), 1e-9 * s.lattice().objectSize());
}

// reset() forgets the implicit step's warm start and contact states: dragged on the ground and
// reset mid-drag, the object then falls from its rest pose and lands exactly as a new solver's
// does. Before, the last step's velocity change stayed in the warm start and CG stopped at its
// tolerance around it: the falling object deformed (1e-6 m in the first step here), and the node's
// ~reset did not give back the rest shape at once.
TEST(ImplicitStep, ResetForgetsTheWarmStartAndTheContacts) {
  SolverParams p = implicitParams(1e6, 0.3, 2, 1.0 / 60.0);
  auto lattice = std::make_shared<const Lattice>(notched(), kDensity, 2);
  Solver dragged(lattice, p), fresh(lattice, p);
  const Collider ground = groundBelow(fresh, 0.01);
  dragged.setCollider("ground", ground);
  fresh.setCollider("ground", ground);
  for (int i = 0; i < 60; ++i) dragged.step();
  const std::uint32_t corner = 0;
  dragged.grab("pull", {corner}, dragged.positions()[corner], 0.0);
  for (int i = 1; i <= 20; ++i) {
    dragged.moveDrag("pull", dragged.positions()[corner] + Eigen::Vector3d(0.002, 0.0, 0.002));
    dragged.step();
  }
  dragged.reset();
  for (int i = 0; i < 60; ++i) {
    dragged.step();
    fresh.step();
    double apart = 0.0;
    for (std::size_t k = 0; k < lattice->size(); ++k)
      apart = std::max(apart, (dragged.positions()[k] - fresh.positions()[k]).norm());
    ASSERT_LT(apart, 1e-12) << "step " << i << " after the reset";
  }
}

// A block resting on the ground with ambient damping: the ground carries its whole weight (the
// wrench averaged over a second, statics: within 0.1 %). The contacts are in the solve, their
// velocities prescribed, so a resting object feels no drag. (Damping gravity's increment of the
// step relative to h g instead of rest loads the ground with (1 + h c) times the weight; a support
// applied after the solve, as between objects in a World, reads 1 / (1 + h c) of it:
// docs/method.md.)
TEST(ImplicitStep, GroundCarriesTheWholeWeightWithAmbientDamping) {
  for (double c : {0.5, 2.0}) {
    SolverParams p = implicitParams(1e6, 0.3, 1, 1.0 / 60.0);
    p.ambientDamping = c;
    auto lattice = std::make_shared<const Lattice>(deformable_flsm::test::makeBox(6, 6, 3, 0.01), kDensity, 1);
    Solver s(lattice, p);
    s.setCollider("ground", groundBelow(s, 0.0));
    for (int i = 0; i < 120; ++i) s.step();
    Eigen::Vector3d force = Eigen::Vector3d::Zero();
    for (int i = 0; i < 60; ++i) {
      s.step();
      force += s.contactWrench("ground").force / 60.0;
    }
    const double weight = lattice->totalMass() * 9.81;
    EXPECT_NEAR(-force.z(), weight, 1e-3 * weight) << "ambient damping " << c;
    // every particle of the bottom layer pushes on the ground, counted once
    std::size_t bottom = 0;
    double lowest = lattice->restPositions()[0].z();
    for (const Eigen::Vector3d& q : lattice->restPositions()) lowest = std::min(lowest, q.z());
    for (const Eigen::Vector3d& q : lattice->restPositions()) bottom += q.z() < lowest + 1e-9 ? 1 : 0;
    EXPECT_EQ(s.contactWrench("ground").contacts, bottom) << "ambient damping " << c;
  }
}

// The clamped cantilever at ONE sub-step of 1/60 s settles within 10 % of the FEM oracle from a
// soft to a stiff material, with and without the Poisson term, where the explicit step at one
// sub-step saturates (and would be 1.3 to 300 times too soft). With the two-level preconditioner
// PCG needs at most kCantileverIterations per step here: with Jacobi alone it needed over 100
// from 1 MPa on (the aggregates carry the bending that Jacobi spreads one region per iteration).
TEST(ImplicitStep, CantileverAtOneSubstepMatchesTheFemOracle) {
  constexpr int kCantileverIterations = 60;
  for (double E : {30e3, 1e6, 10e6})
    for (double nu : {0.0, 0.3}) {
      const Sag s = cantilever(E, nu);
      EXPECT_TRUE(s.explicitSaturated) << "E " << E;
      EXPECT_NEAR(s.lattice / s.oracle, 1.0, 0.10)
          << "E " << E << " nu " << nu << ": " << 1e3 * s.lattice << " mm, oracle " << 1e3 * s.oracle << " mm";
      EXPECT_LE(s.maxIterations, kCantileverIterations) << "E " << E << " nu " << nu;
    }
}

// A 10 MPa block (10 cm, 1 cm cells) dropped tilted from 6 cm onto the ground with one sub-step of
// 1/30 s, with friction: stays finite, lands on an edge and tumbles, comes to rest on the ground
// in its rest shape. It falls 4 cm (four cells) in its last step before impact: with contact
// after an unconstrained solve the bottom layers are flattened into the ground and shape matching
// keeps the crushed shape (2.9 cm of shape error, explicit step alike); contact inside the solve
// stops the block as a whole. What remains is the shear static friction holds after the impact,
// a small fraction of the size: bound at 0.5 % of it.
TEST(ImplicitStep, StiffBlockDroppedOnTheGroundComesToRest) {
  for (double nu : {0.0, 0.3}) {
    SolverParams p = implicitParams(10e6, nu, 1, 1.0 / 30.0);
    auto lattice = std::make_shared<const Lattice>(deformable_flsm::test::makeBox(10, 10, 10, 0.01), kDensity, 1);
    Solver s(lattice, p);
    Collider ground;
    ground.shape.type = ColliderType::HalfSpace;
    ground.pose.translation() = Eigen::Vector3d(0, 0, -0.1);
    s.setCollider("ground", ground);
    std::vector<Eigen::Vector3d> x = s.positions();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(0.5, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    for (auto& xi : x) xi = R * xi;
    s.setPositions(x);
    for (int i = 0; i < 150; ++i) {
      s.step();
      for (const auto& xi : s.positions()) ASSERT_TRUE(xi.allFinite()) << "step " << i;
    }
    double lowest = kBig;
    for (const auto& xi : s.positions()) lowest = std::min(lowest, xi.z());
    const double r = s.contactRadius();
    EXPECT_NEAR(lowest, -0.1 + r, 0.5 * r) << "resting on the ground, nu " << nu;
    // 1e-6 of the energy of the fall: at rest
    EXPECT_LT(s.kineticEnergy(), 1e-6 * s.lattice().totalMass() * 9.81 * 0.06) << "at rest, nu " << nu;
    EXPECT_LT(s.shapeError(), 5e-3 * s.lattice().objectSize()) << "nu " << nu;
  }
}

// Pins hold exactly; a hard drag puts its particles on their targets; a stiff spring drag (far
// stiffer than an explicit step could take) holds its particles at target up to m g / k.
TEST(ImplicitStep, PinsAndDragsHold) {
  auto lattice = std::make_shared<const Lattice>(notched(), kDensity, 1);
  SolverParams p = implicitParams(1e6, 0.3, 1, 1.0 / 60.0);
  {
    Solver s(lattice, p);
    s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.005, kBig, kBig), true);
    const std::vector<Eigen::Vector3d> x0 = s.positions();
    const std::vector<std::uint32_t> tip = s.particlesWithin(Eigen::Vector3d(0.055, 0.025, 0.015), 0.012);
    ASSERT_FALSE(tip.empty());
    s.grab("hard", tip, Eigen::Vector3d(0.08, 0.03, 0.0), 0.0);
    for (int i = 0; i < 60; ++i) s.step();
    for (std::size_t i = 0; i < x0.size(); ++i)
      if (s.isPinned(static_cast<std::uint32_t>(i))) {
        EXPECT_EQ(s.positions()[i], x0[i]);
      }
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (std::uint32_t i : tip) c += s.positions()[i];
    EXPECT_LT((c / tip.size() - Eigen::Vector3d(0.08, 0.03, 0.0)).norm(), 1e-12);
    for (const auto& xi : s.positions()) ASSERT_TRUE(xi.allFinite());
  }
  {
    Solver s(lattice, p);
    const std::vector<std::uint32_t> all = s.nearestParticles(Eigen::Vector3d::Zero(), lattice->size());
    const double k = 1e7;  // N/m: omega h = sqrt(k / M) h ~ 60 for this 0.1 kg block
    const Eigen::Vector3d target(0.03, 0.02, 0.5);
    s.grab("spring", all, target, k);
    for (int i = 0; i < 120; ++i) s.step();
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < lattice->size(); ++i) c += lattice->masses()[i] * s.positions()[i];
    c /= lattice->totalMass();
    const double sag = lattice->totalMass() * 9.81 / k;
    EXPECT_LT((c - (target + Eigen::Vector3d(0, 0, -sag))).norm(), 0.1 * sag);
  }
}

// One or two threads: the same sums in the same order, bit-identical states, with either scheme.
TEST(ImplicitStep, OneAndTwoThreadsGiveIdenticalResults) {
  const auto vox = deformable_flsm::test::makeBox(12, 10, 9, 0.01);
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, 2);
  for (auto scheme : {deformable_flsm::ImplicitScheme::BackwardEuler, deformable_flsm::ImplicitScheme::Bdf2}) {
    std::vector<std::vector<Eigen::Vector3d>> result;
    for (int threads : {1, 2}) {
      SolverParams p = implicitParams(1e6, 0.3, 2, 1.0 / 60.0);
      p.threads = threads;
      p.implicitScheme = scheme;
      Solver s(lattice, p);
      s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.005, kBig, kBig), true);
      s.grab("spring", s.particlesWithin(Eigen::Vector3d(0.11, 0.05, 0.05), 0.02),
             Eigen::Vector3d(0.15, 0.05, 0.1), 50.0);
      for (int i = 0; i < 20; ++i) s.step();
      result.push_back(s.positions());
    }
    for (std::size_t i = 0; i < result[0].size(); ++i)
      ASSERT_EQ(result[0][i], result[1][i]) << "particle " << i << ", " << toString(scheme);
  }
}

// An implicit step (either scheme) allocates nothing once the solver has stepped once: the preconditioner's
// aggregates, region moments and coarse factorisation live in buffers sized outside the step,
// with pins, a hard and a spring drag, a timed force, the Poisson term and a ground contact.
TEST(ImplicitStep, StepDoesNotAllocate) {
  for (int run = 0; run < 4; ++run) {
    const int threads = 1 + run % 2;
    SolverParams p = implicitParams(1e6, 0.3, 2, 1.0 / 60.0);
    p.threads = threads;
    if (run >= 2) p.implicitScheme = deformable_flsm::ImplicitScheme::Bdf2;
    Solver s(std::make_shared<const Lattice>(deformable_flsm::test::makeBox(12, 4, 4, 0.01), kDensity, 2), p);
    s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(0.016, 1.0, 1.0), true);
    s.grab("hard", {100}, Eigen::Vector3d(0.15, 0.0, 0.0), 0.0);
    s.grab("spring", {120}, Eigen::Vector3d(0.15, 0.05, 0.0), 20.0);
    s.applyForce({150, 151}, Eigen::Vector3d(0.0, 0.0, 1.0), 10.0);
    Collider ground;
    ground.shape.type = ColliderType::HalfSpace;
    ground.pose.translation() = Eigen::Vector3d(0, 0, -0.001);
    s.setCollider("ground", ground);
    s.step();
    const long before = gAllocations.load();
    for (int i = 0; i < 20; ++i) s.step();
    EXPECT_EQ(gAllocations.load() - before, 0) << "threads " << threads << ", " << toString(p.implicitScheme);
  }
}
// BDF2 (ImplicitScheme::Bdf2): the second-order scheme keeps a vibration that backward Euler
// damps. A clamped bar (0.7 m free, 0.1 m thick, 7.5 MPa: first bending mode at omega h ~ 0.3 for
// steps of 1/60 s), released straight under a light load, no damping of any kind: the amplitude
// its tip keeps per period is what each scheme's characteristic root gives a linear mode at the
// measured omega h, backward Euler (1 + (omega h)^2)^(-pi / (omega h)) ~ 0.4, BDF2 ~ 0.96.
namespace {

struct Swing {
  double kept = 0.0;    // amplitude kept per period, mean over the swings
  double omegaH = 0.0;  // the measured angular frequency times the step
  bool swung = false;
};

Swing barSwing(deformable_flsm::ImplicitScheme scheme) {
  const double t = 0.1, L = 0.7, h = 0.05, E = 7.5e6, step = 1.0 / 60.0;
  const int along = static_cast<int>(std::lround(L / h));
  Voxelization vox = deformable_flsm::test::makeBox(along + 2, 2, 2, h);
  vox.origin = Eigen::Vector3d(-2 * h, 0, 0);
  SolverParams p = implicitParams(E, 0.0, 1, step);
  p.implicitScheme = scheme;
  p.damping = 0.0;
  p.ambientDamping = 0.0;
  p.gravity = Eigen::Vector3d(0, 0, -0.01 * L * E * t * t / (1.5 * kDensity * std::pow(L, 4)));
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, 1);
  Solver s(lattice, p);
  s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.0, kBig, kBig), true);
  const double omegaBeam = analytic::cantileverFirstBendingFrequency(L, t, E, kDensity);
  const double period = 2.0 * M_PI / omegaBeam;
  const std::vector<double> z =
      deformable_flsm::test::tipHeights(s, L - h, static_cast<int>(6.0 * period / step));
  const auto extremes =
      deformable_flsm::test::swingExtremes(z, std::max(1, static_cast<int>(0.25 * period / step)));
  Swing out;
  out.swung = extremes.size() >= 5u;
  if (!out.swung) return out;
  // swings (peak to peak) two apart are a period apart
  double logKept = 0.0;
  int count = 0;
  for (std::size_t e = 0; e + 3 < extremes.size(); ++e) {
    const double r0 = std::abs(extremes[e + 1].second - extremes[e].second);
    const double r2 = std::abs(extremes[e + 3].second - extremes[e + 2].second);
    logKept += std::log(r2 / r0);
    ++count;
  }
  out.kept = std::exp(logKept / count);
  const double halfPeriod = (extremes.back().first - extremes.front().first) * step / (extremes.size() - 1);
  out.omegaH = M_PI / halfPeriod * step;
  return out;
}

double bdf2Keeps(double z) {
  const std::complex<double> a(1.5, -z), sq = std::sqrt(std::complex<double>(4.0, 0.0) - 2.0 * a);
  const std::complex<double> r1 = (2.0 + sq) / (2.0 * a), r2 = (2.0 - sq) / (2.0 * a);
  const std::complex<double> r = std::abs(r1) > std::abs(r2) ? r1 : r2;
  return std::pow(std::abs(r), 2.0 * M_PI / std::abs(std::arg(r)));
}

}  // namespace

TEST(ImplicitStep, Bdf2KeepsTheVibrationThatBackwardEulerDamps) {
  using deformable_flsm::ImplicitScheme;
  const Swing be = barSwing(ImplicitScheme::BackwardEuler);
  const Swing bdf2 = barSwing(ImplicitScheme::Bdf2);
  ASSERT_TRUE(be.swung && bdf2.swung);
  const double beKeeps = std::pow(1.0 + be.omegaH * be.omegaH, -M_PI / be.omegaH);
  std::printf("[ bdf2 ] omega h %.3f / %.3f: kept per period, backward Euler %.3f (its root %.3f), BDF2 %.3f (%.3f)\n",
              be.omegaH, bdf2.omegaH, be.kept, beKeeps, bdf2.kept, bdf2Keeps(bdf2.omegaH));
  EXPECT_NEAR(be.kept, beKeeps, 0.05);
  EXPECT_NEAR(bdf2.kept, bdf2Keeps(bdf2.omegaH), 0.05);
  EXPECT_GT(bdf2.kept, 0.9);
}

// BDF2 conserves linear momentum where no external force acts (a linear multistep method keeps
// linear invariants) and angular momentum (restored after the solve, as backward Euler's is), a
// block thrown under gravity flies without turning, and a dropped bunny lands at rest, standing,
// the ground's force its weight.
TEST(ImplicitStep, Bdf2KeepsLinearMomentumAndComesToRestOnTheGround) {
  {
    SolverParams p = implicitParams(1e6, 0.3, 2, 1.0 / 60.0);
    p.implicitScheme = deformable_flsm::ImplicitScheme::Bdf2;
    p.gravity.setZero();
    p.ambientDamping = 0.0;
    Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
    const auto scale = deformable_flsm::test::deformAndSpin(s, Eigen::Vector3d(2.0, 0.0, 5.0), 17);
    const Eigen::Vector3d P0 = s.linearMomentum(), L0 = s.angularMomentum();
    for (int i = 0; i < 120; ++i) s.step();
    EXPECT_LT((s.linearMomentum() - P0).norm(), 1e-10 * scale.linear);
    EXPECT_LT((s.angularMomentum() - L0).norm(), 1e-10 * scale.angular);
  }
  {
    // thrown sideways under gravity: it flies without turning (the spin about its centre of mass
    // is what the correction keeps; about a fixed point BDF2's extrapolated centre would turn
    // gravity's torque into spin)
    SolverParams p = implicitParams(1e6, 0.3, 2, 1.0 / 30.0);
    p.implicitScheme = deformable_flsm::ImplicitScheme::Bdf2;
    p.ambientDamping = 0.0;
    Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
    std::vector<std::uint32_t> all(s.positions().size());
    for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
    const double M = s.lattice().totalMass();
    s.applyImpulse(all, Eigen::Vector3d(M, 0.0, 0.0));  // 1 m/s
    for (int i = 0; i < 60; ++i) s.step();
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero(), spin = Eigen::Vector3d::Zero();
    const auto& m = s.lattice().masses();
    for (std::size_t i = 0; i < all.size(); ++i) {
      c += m[i] * s.positions()[i] / M;
      v += m[i] * s.velocities()[i] / M;
    }
    for (std::size_t i = 0; i < all.size(); ++i) spin += m[i] * (s.positions()[i] - c).cross(s.velocities()[i] - v);
    EXPECT_LT(spin.norm(), 1e-9 * M * s.lattice().objectSize()) << "spin " << spin.transpose();
    EXPECT_NEAR(v.x(), 1.0, 1e-9);
    EXPECT_NEAR(v.z(), -9.81 * s.time(), 1e-9);
  }
  deformable_flsm::TriMesh mesh = deformable_flsm::loadMesh(deformable_flsm::kBunnyMeshPath, 0.1);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.5 * M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (auto& v : mesh.vertices) v = R * v;
  auto lattice = std::make_shared<const Lattice>(deformable_flsm::nearestResolution(mesh, 2500).voxels, kDensity, 2);
  SolverParams p = implicitParams(30e3, 0.0, 2, 1.0 / 30.0);
  p.implicitScheme = deformable_flsm::ImplicitScheme::Bdf2;
  p.damping = 10.0;
  p.ambientDamping = 0.5;
  Solver s(lattice, p);
  s.setCollider("ground", groundBelow(s, 0.02));
  const double height0 = lattice->restMax().z() - lattice->restMin().z();
  for (int i = 0; i < 300; ++i) s.step();
  double vmax = 0.0, lo = kBig, hi = -kBig;
  for (std::size_t i = 0; i < s.positions().size(); ++i) {
    vmax = std::max(vmax, s.velocities()[i].norm());
    lo = std::min(lo, s.positions()[i].z());
    hi = std::max(hi, s.positions()[i].z());
  }
  const double weight = lattice->totalMass() * 9.81;
  const double carried = -s.contactWrench("ground").force.z() / weight;  // the force on the ground
  std::printf("[ bdf2 ] bunny after 10 s: fastest particle %.3g m/s, height %.3f of its rest height, the ground "
              "carries %.4f of its weight\n", vmax, (hi - lo) / height0, carried);
  EXPECT_LT(vmax, 1e-3);
  EXPECT_GT(hi - lo, 0.8 * height0);
  EXPECT_NEAR(carried, 1.0, 0.01) << "the ground's force is the weight";
}
