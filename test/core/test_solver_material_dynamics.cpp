// The physical mode in motion: the cap on alpha against the stability of the update (strong
// damping included), robustness from degenerate starts at the cap, momentum kept by the Poisson
// term and by ambient damping, and ambient damping's ratio on a swinging cantilever.
#include "deformable_flsm/core/solver.h"
#include "fixtures.h"
#include "solver_material_fixtures.h"
#include "support/fem_oracle.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <random>
#include <utility>
#include <vector>

using deformable_flsm::Integrator;
using deformable_flsm::Lattice;
using deformable_flsm::Solver;
using deformable_flsm::SolverParams;
using deformable_flsm::Voxelization;
using namespace deformable_flsm::solver_material_fixtures;
namespace analytic = deformable_flsm::analytic;

namespace {

/// An L-shaped solid (a 6 x 4 x 4 box with a 3 x 2 x 4 notch): regions clipped by concave
/// corners, where the region weights and stencils are most uneven.
Voxelization notched() {
  return deformable_flsm::test::makeVoxels(Eigen::Vector3i(6, 4, 4), 0.01,
                                           [](int i, int j, int) { return !(i >= 3 && j >= 2); });
}

/// The 6 x 4 x 4 box with one more layer along x whose cells are slivers (fill fraction 0.01), as
/// a curved surface leaves them: a particle of a hundredth of a cell's mass next to full ones.
Voxelization slivered() {
  Voxelization v = deformable_flsm::test::makeVoxels(Eigen::Vector3i(7, 4, 4), 0.01, [](int, int, int) { return true; });
  for (std::size_t c = 0; c < v.cells.size(); ++c)
    if (v.cells[c].x() == 6) v.fillFraction[c] = 0.01;
  return v;
}

/// The largest eigenvalue of h^2 M^-1 K, (omega h)^2 of the stiffest mode of the linearised
/// sub-step, by power iteration through the solver itself: from zero velocity and positions
/// x0 + eps u, one sub-step gives v = -h M^-1 K eps u (gravity and damping off). Returns the
/// M-weighted Rayleigh quotient after `iterations`.
double stiffestOmegaH2(Solver& s, int iterations) {
  const auto& x0 = s.lattice().restPositions();
  const auto& m = s.lattice().masses();
  const std::size_t n = x0.size();
  const double eps = 1e-6 * s.lattice().spacing();
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  std::vector<Eigen::Vector3d> u(n), x(n);
  for (auto& ui : u) ui = Eigen::Vector3d(uni(rng), uni(rng), uni(rng));
  const std::vector<Eigen::Vector3d> still(n, Eigen::Vector3d::Zero());
  double quotient = 0.0;
  for (int it = 0; it < iterations; ++it) {
    double norm = 0.0;
    for (std::size_t i = 0; i < n; ++i) norm += m[i] * u[i].squaredNorm();
    norm = std::sqrt(norm);
    for (std::size_t i = 0; i < n; ++i) {
      u[i] /= norm;
      x[i] = x0[i] + eps * u[i];
    }
    s.setPositions(x);
    s.setVelocities(still);
    s.step();
    double uKu = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d Ku = -s.params().timeStep * s.velocities()[i] / eps;
      uKu += m[i] * u[i].dot(Ku);
      u[i] = Ku;
    }
    quotient = uKu;  // u was M-normalised
  }
  return quotient;
}

}  // namespace

// The cap on alpha follows the stability of symplectic Euler, (omega h)^2 < 4, with the margin of
// 1/2: at the cap the stiffest mode of the linearised sub-step has (omega h)^2 <= 2, and not far
// below it: for nu = 0 the bound alpha s_max is attained, and the Poisson term's Gershgorin bound
// may overestimate, so >= 1.4 is asserted, i.e. the cap is at most 2.9x below the blow-up
// threshold (the test prints (omega h)^2 for each case; docs/method.md has them).
// Box, notched and slivered solids, w = 1 to 3, nu = 0 to 0.45. The slivers must not pull the cap
// down: a Poisson stencil weighed by its own cell would shake a sliver neighbour (a cell filled to
// 1 %) a hundred times harder; weighed by its lightest member the slivered box keeps at least
// half the box's cap.
TEST(PhysicalMaterial, AlphaCapSitsBelowTheStabilityLimitWithItsMargin) {
  const char* const names[] = {"box", "notched", "slivered"};
  std::map<std::pair<int, double>, double> boxCap;
  for (int shape = 0; shape < 3; ++shape)
    for (int w = 1; w <= 3; ++w)
      for (double nu : {0.0, 0.3, 0.45}) {
        SolverParams p = physical(1e9, nu, w, 1);  // far above the cap: alpha is the cap
        p.gravity.setZero();
        p.damping = 0.0;
        p.ambientDamping = 0.0;
        const Voxelization vox =
            shape == 0 ? deformable_flsm::test::makeBox(6, 4, 4, 0.01) : shape == 1 ? notched() : slivered();
        Solver s(std::make_shared<const Lattice>(vox, kDensity, w), p);
        ASSERT_TRUE(s.stiffnessSaturated());
        const std::pair<int, double> key(w, nu);
        if (shape == 0) boxCap[key] = s.alpha();
        if (shape == 2) {
          EXPECT_GT(s.alpha(), 0.5 * boxCap[key])
              << "slivered w " << w << " nu " << nu << ": alpha " << s.alpha() << ", the box's " << boxCap[key];
        }
        const double omegaH2 = stiffestOmegaH2(s, 400);
        // blow-up threshold of alpha: 4 / (omegaH2 / alpha)
        EXPECT_LE(omegaH2, 2.0 * (1.0 + 1e-6)) << names[shape] << " w " << w << " nu " << nu
                                               << ": alpha " << s.alpha() << ", blow-up at alpha "
                                               << 4.0 * s.alpha() / omegaH2;
        EXPECT_GE(omegaH2, 1.4) << names[shape] << " w " << w << " nu " << nu << ": alpha "
                                << s.alpha() << ", blow-up at alpha " << 4.0 * s.alpha() / omegaH2;
        std::printf("  cap: %s w %d nu %.2f: alpha %.3f, (omega h)^2 %.3f\n", names[shape], w, nu,
                    s.alpha(), omegaH2);
      }
}

// Damping narrows symplectic Euler's stability limit: with the factor keep of the velocity kept
// each sub-step the linearised step is stable for (omega h)^2 < 2 (1 + keep), 4 undamped, 2 when
// the damping takes it all, less when two dampings together take more than all of it. A free
// object's stiffest modes keep exp(-c h) - kd (ambient damping c; region damping kd = 1 -
// exp(-damping h) on top); the cap keeps them at half of that limit. A 1 MPa bar at one sub-step
// of 1/60 s (capped), pulled apart by end forces for 0.5 s and released, with c = 200 /s and
// region damping 10 /s (keep 0.036 - 0.15) comes to rest in its rest shape; with region damping
// 100 /s as well (keep -0.78, a cap a tenth as high: a far softer bar) it stays bounded and is
// on its way back. With the undamped limit in the cap ((omega h)^2 = 2 at nu = 0) both grew
// without bound: the first 1e18 m away after 6 s, the second 1e42.
TEST(PhysicalMaterial, StrongDampingLowersTheCapAndTheBarStaysStable) {
  const int along = 16, across = 4;
  const double h = 0.025, t = across * h, c = 200.0;
  for (double damping : {10.0, 100.0}) {
    SolverParams p = physical(1e6, 0.0, 1, 1);
    p.gravity.setZero();
    p.ambientDamping = c;
    p.damping = damping;
    auto lattice =
        std::make_shared<const Lattice>(box(along, across, across, h, Eigen::Vector3d::Zero()), kDensity, 1);
    Solver s(lattice, p);
    ASSERT_TRUE(s.stiffnessSaturated());
    const double keep = std::exp(-c * kStep) - (1.0 - std::exp(-damping * kStep));
    const double omegaH2 = stiffestOmegaH2(s, 400);
    EXPECT_LE(omegaH2, (1.0 + keep) * (1.0 + 1e-6)) << "half the damped limit 2 (1 + keep), damping " << damping;
    s.reset();
    pullEnds(s, along, 0.002 * p.youngsModulus * t * t, 0.5);  // 20 N: more than the capped bar holds
    for (int i = 0; i < static_cast<int>(std::lround(6.0 / kStep)); ++i) s.step();
    double speed = 0.0;
    for (std::size_t i = 0; i < lattice->size(); ++i) {
      ASSERT_TRUE(s.positions()[i].allFinite());
      speed = std::max(speed, s.velocities()[i].norm());
    }
    const double error = s.shapeError();
    std::printf("  damped cap, damping %.0f /s: alpha %.3f, (omega h)^2 %.3f (damped limit %.3f); after 6 s shape "
                "error %.3g m, fastest particle %.3g m/s\n", damping, s.alpha(), omegaH2, 2.0 * (1.0 + keep), error,
                speed);
    if (damping < 50.0) {
      EXPECT_LT(error, 2.5e-3 * along * h) << "back to its rest shape";
      EXPECT_LT(speed, 1e-2) << "at rest";
    } else {
      EXPECT_LT(error, 0.15 * along * h) << "bounded, on its way back";
      EXPECT_LT(speed, 0.1) << "slow";
    }
  }
}

// The physical mode at its cap (alpha s up to 2, and the Poisson term) keeps classic FastLSM's
// robustness: from a point, a plane, a scramble or a tenfold stretch, at 1/30 s in one sub-step,
// no NaN and back to the rest shape.
TEST(PhysicalMaterial, RecoversFromDegenerateStartsAtTheCap) {
  for (const char* start : {"point", "plane", "scrambled", "stretched"})
    for (double nu : {0.0, 0.3, 0.45}) {
      SolverParams p = physical(1e9, nu, 2, 1);
      p.gravity.setZero();
      p.timeStep = 1.0 / 30.0;
      Solver s(std::make_shared<const Lattice>(deformable_flsm::test::makeBox(12, 4, 4, 0.01), kDensity, 2), p);
      const double size = s.lattice().objectSize();
      deformable_flsm::test::degenerateStart(s, start);
      for (int i = 0; i < 900; ++i) {
        s.step();
        for (const auto& xi : s.positions()) ASSERT_TRUE(xi.allFinite()) << start << " nu " << nu << " step " << i;
      }
      EXPECT_LT(s.shapeError(), 1e-3 * size) << start << " nu " << nu;
    }
}

// The Poisson term's forces come from a rotation-invariant energy on differences of positions:
// linear and angular momentum are conserved to round-off.
TEST(PhysicalMaterial, PoissonTermConservesMomentum) {
  SolverParams p = physical(5e3, 0.4, 2, 4);
  p.gravity.setZero();
  p.ambientDamping = 0.0;
  Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
  const auto scale = deformable_flsm::test::deformAndSpin(s, Eigen::Vector3d(2.0, 0.0, 0.0), 17);
  const double pScale = scale.linear, lScale = scale.angular;
  const Eigen::Vector3d P0 = s.linearMomentum(), L0 = s.angularMomentum();
  for (int i = 0; i < 200; ++i) s.step();
  EXPECT_LT((s.linearMomentum() - P0).norm(), 1e-11 * pScale);
  EXPECT_LT((s.angularMomentum() - L0).norm(), 1e-10 * lScale);
}

// Ambient damping acts on the motion relative to the object's rigid motion: an object falling
// under gravity with ambient damping falls exactly as without (v = g t, to round-off), where a
// drag in the world frame would hold it to (1 - e^-ct) / c of that after t = 1 s.
TEST(AmbientDamping, FreeFallKeepsItsMomentum) {
  SolverParams p = physical(5e3, 0.3, 2, 4);
  p.ambientDamping = 0.5;
  Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
  for (int i = 0; i < 60; ++i) s.step();
  const double M = s.lattice().totalMass();
  const Eigen::Vector3d expected = M * s.time() * p.gravity;
  EXPECT_LT((s.linearMomentum() - expected).norm(), 1e-9 * expected.norm());
  EXPECT_LT(s.shapeError(), 1e-9 * s.lattice().objectSize()) << "free fall deforms nothing";
}

namespace {

/// Kinetic energy of the motion relative to the rigid motion with the object's linear and angular
/// momentum (J).
double wobbleEnergy(const Solver& s) {
  const auto& m = s.lattice().masses();
  const auto& x = s.positions();
  const auto& v = s.velocities();
  const double M = s.lattice().totalMass();
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), V = Eigen::Vector3d::Zero(), L = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    c += m[i] * x[i] / M;
    V += m[i] * v[i] / M;
  }
  Eigen::Matrix3d I = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    const Eigen::Vector3d r = x[i] - c;
    L += m[i] * r.cross(v[i]);
    I += m[i] * (r.squaredNorm() * Eigen::Matrix3d::Identity() - r * r.transpose());
  }
  const Eigen::Vector3d w = I.ldlt().solve(L);
  double e = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) e += 0.5 * m[i] * (v[i] - V - w.cross(x[i] - c)).squaredNorm();
  return e;
}

}  // namespace

// A thrown, spinning object keeps its linear and angular momentum under ambient damping, while
// its wobble (motion relative to its rigid motion) dies out.
TEST(AmbientDamping, ThrownSpinningObjectKeepsMomentumAndStopsWobbling) {
  SolverParams p = physical(5e3, 0.0, 2, 4);
  p.gravity.setZero();
  p.damping = 0.0;
  p.ambientDamping = 2.0;
  Solver s(std::make_shared<const Lattice>(notched(), kDensity, 2), p);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> v(s.positions().size());
  for (std::size_t i = 0; i < v.size(); ++i)
    v[i] = Eigen::Vector3d(0.3, -0.1, 0.2) + Eigen::Vector3d(0.5, 3.0, -1.0).cross(s.positions()[i]) +
           0.2 * Eigen::Vector3d(u(rng), u(rng), u(rng));
  s.setVelocities(v);
  double pScale = 0.0, lScale = 0.0;
  for (std::size_t i = 0; i < v.size(); ++i) {
    pScale += s.lattice().masses()[i] * v[i].norm();
    lScale += s.lattice().masses()[i] * s.positions()[i].norm() * v[i].norm();
  }
  const Eigen::Vector3d P0 = s.linearMomentum(), L0 = s.angularMomentum();
  const double wobble0 = wobbleEnergy(s);
  for (int i = 0; i < 300; ++i) s.step();  // 5 s: e^-20 of the relative motion's energy is left
  EXPECT_LT((s.linearMomentum() - P0).norm(), 1e-10 * pScale);
  EXPECT_LT((s.angularMomentum() - L0).norm(), 1e-9 * lScale);
  EXPECT_LT(wobbleEnergy(s), 1e-4 * wobble0) << "the wobble must have died out (a spinning body keeps a "
                                                 "steady centrifugal stretch, so the shape is not the measure)";
}

// Ambient damping is mass-proportional Rayleigh damping, C = c M: a vibration mode of angular
// frequency omega gets the damping ratio c / (2 omega). A cantilever released from rest under a
// light load oscillates about its sag in its first bending mode; the logarithmic decrement of its
// tip's swings gives zeta = delta / sqrt(4 pi^2 + delta^2), which must be c / (2 omega_n) within
// 20 % (omega_n from the measured period). Region damping off: it is the other channel.
namespace {

struct Decay {
  double zeta = 0.0;    // from the logarithmic decrement of the tip's swings
  double omegaN = 0.0;  // natural angular frequency from the measured period (rad/s)
  bool swung = false;   // at least six extremes
};

// The cantilever of the test below, released from rest under a light load, with ambient damping
// c (1/s) and `integrator` at `substeps` sub-steps; region damping off.
Decay cantileverDecay(double c, Integrator integrator, int substeps) {
  const double t = 0.1, L = 0.8, h = 0.05;
  const Voxelization vox = box(18, 2, 2, h, Eigen::Vector3d(-2 * h, 0, 0));
  const double E = modulusFor(h);
  const double omegaBeam = analytic::cantileverFirstBendingFrequency(L, t, E, kDensity);
  SolverParams p = physical(E, 0.0, 1, substeps);
  p.integrator = integrator;
  p.damping = 0.0;
  p.ambientDamping = c;
  p.gravity = Eigen::Vector3d(0, 0, -0.01 * L * E * t * t / (1.5 * kDensity * std::pow(L, 4)));
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, 1);
  Solver s(lattice, p);
  s.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.0, kBig, kBig), true);
  const double period = 2.0 * M_PI / omegaBeam;
  const std::vector<double> z =
      deformable_flsm::test::tipHeights(s, L - h, static_cast<int>(6.0 * period / kStep));
  // swings: extremes of the tip, each the largest or smallest within a quarter of a period
  // (so that the faint higher modes cannot make extremes of their own)
  const auto extremes = deformable_flsm::test::swingExtremes(z, static_cast<int>(0.25 * period / kStep));
  Decay out;
  out.swung = extremes.size() >= 6u;
  if (!out.swung) return out;
  double logRatio = 0.0;
  const std::size_t swings = extremes.size() - 2;
  for (std::size_t e = 0; e < swings; ++e) {
    const double r0 = std::abs(extremes[e + 1].second - extremes[e].second);
    const double r1 = std::abs(extremes[e + 2].second - extremes[e + 1].second);
    logRatio += std::log(r0 / r1);
  }
  const double halfPeriods = (extremes.back().first - extremes.front().first) * kStep / (extremes.size() - 1);
  const double delta = 2.0 * logRatio / swings;  // per full period
  out.zeta = delta / std::sqrt(4.0 * M_PI * M_PI + delta * delta);
  out.omegaN = M_PI / halfPeriods / std::sqrt(1.0 - out.zeta * out.zeta);
  return out;
}

double cantileverOmega() {
  const double t = 0.1, L = 0.8, h = 0.05;
  return analytic::cantileverFirstBendingFrequency(L, t, modulusFor(h), kDensity);
}

}  // namespace

TEST(AmbientDamping, LogarithmicDecrementGivesTheDampingRatio) {
  const double omegaBeam = cantileverOmega();
  for (double zeta : {0.02, 0.08}) {
    const double c = 2.0 * zeta * omegaBeam;
    const Decay d = cantileverDecay(c, Integrator::Explicit, 4);
    ASSERT_TRUE(d.swung) << "zeta " << zeta;
    const double expected = c / (2.0 * d.omegaN);
    EXPECT_NEAR(d.zeta / expected, 1.0, 0.20) << "zeta asked " << zeta << ": measured " << d.zeta
                                              << ", c / (2 omega_n) " << expected << ", omega_n " << d.omegaN
                                              << " rad/s (Euler-Bernoulli " << omegaBeam << ")";
  }
}

// With the implicit step at one sub-step the ambient damping ratio adds to the step's own
// numerical damping (about omega h / 2): the ratio measured with c, less the one without, is
// c / (2 omega_n) within 20 %.
TEST(AmbientDamping, ImplicitStepAddsTheDampingRatioToItsOwn) {
  const double omegaBeam = cantileverOmega();
  const Decay own = cantileverDecay(0.0, Integrator::Implicit, 1);
  ASSERT_TRUE(own.swung);
  for (double zeta : {0.02, 0.08}) {
    const double c = 2.0 * zeta * omegaBeam;
    const Decay d = cantileverDecay(c, Integrator::Implicit, 1);
    ASSERT_TRUE(d.swung) << "zeta " << zeta;
    const double expected = c / (2.0 * d.omegaN);
    std::printf("[ damping ] implicit, 1 sub-step: omega_n h %.3f, own zeta %.4f, with c %.3f /s: %.4f, added %.4f, "
                "c / (2 omega_n) %.4f\n", d.omegaN * kStep, own.zeta, c, d.zeta, d.zeta - own.zeta, expected);
    EXPECT_NEAR((d.zeta - own.zeta) / expected, 1.0, 0.20) << "zeta asked " << zeta;
  }
}
