// The material under a finger: a flat punch and a sphere pressed into a block, against the FEM
// oracle (the punch, its displacement prescribed on the same footprint) and Hertz's contact on a
// bonded layer (the sphere), and a cube squeezed between two pads, against the oracle, with both
// integrators; the regions' size against what a dent narrower than a region meets; a pad placed
// into the object, counted as such. bench_material prints the table for w 1 to 3 (after the
// global cases, or alone with --local-only).
#include "deformable_flsm/core/solver.h"
#include "fixtures.h"
#include "support/fem_oracle.h"
#include "support/indentation.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

using deformable_flsm::FemMaterial;
using deformable_flsm::FemOracle;
using deformable_flsm::FemSolution;
using deformable_flsm::Solver;
using deformable_flsm::SolverParams;
using deformable_flsm::Integrator;
using deformable_flsm::Voxelization;
namespace analytic = deformable_flsm::analytic;

namespace {

namespace ind = deformable_flsm::indentation;
constexpr double kModulus = 20000.0;  // soft enough for the explicit step at 60-120 sub-steps

/// A block of nx x ny x nz cells of spacing dx, its base on z = 0, centred on the z axis.
Voxelization block(int nx, int ny, int nz, double dx) {
  Voxelization v = deformable_flsm::test::makeBox(nx, ny, nz, dx);
  v.origin = Eigen::Vector3d(-0.5 * nx * dx, -0.5 * ny * dx, 0.0);
  return v;
}

ind::Press how(Integrator integrator, int substeps, int w, double nu) {
  ind::Press p;
  p.integrator = integrator;
  p.substeps = substeps;
  p.w = w;
  p.nu = nu;
  p.youngsModulus = kModulus;
  return p;
}

double femPunch(const Voxelization& vox, int k, double depth, double nu) {
  return ind::femPunch(vox, k, depth, FemMaterial{kModulus, nu, 1000.0});
}

}  // namespace

// 13 cells across (5 cm), a punch 5 cells wide pressed 2 mm (half a cell): the default regions
// (w = 1) meet the oracle's force within 12 % at nu 0 and 0.3, with both integrators (measured:
// -10.0 % and -8.2 %; against the oracle at two elements per cell edge, -7 % at nu 0; a punch 7
// cells wide on 19 cells, -8.0 % against this oracle), and the two integrators agree within 2 %
// (measured: 0.02 %).
TEST(LocalStiffness, FlatPunchMeetsTheFemOracleWithBothIntegrators) {
  const double dx = 0.05 / 13, depth = 0.002;
  const Voxelization vox = block(13, 13, 13, dx);
  for (double nu : {0.0, 0.3}) {
    const double oracle = femPunch(vox, 5, depth, nu);
    const double implicitForce =
        ind::press(vox, ind::punch(5, dx), ind::kPunchBottom, depth, how(Integrator::Implicit, 4, 1, nu)).force;
    const ind::PressResult e =
        ind::press(vox, ind::punch(5, dx), ind::kPunchBottom, depth, how(Integrator::Explicit, nu > 0 ? 120 : 60, 1, nu));
    const double explicitForce = e.force;
    const bool saturated = e.saturated;
    std::printf("[ punch   ] nu %.1f: oracle %.4f N, implicit %.4f N (%+.1f %%), explicit %.4f N (%+.1f %%)\n", nu,
                oracle, implicitForce, 100 * (implicitForce / oracle - 1), explicitForce,
                100 * (explicitForce / oracle - 1));
    EXPECT_FALSE(saturated) << "the explicit step must get the asked modulus for the comparison";
    EXPECT_NEAR(implicitForce / oracle, 1.0, 0.12) << "nu " << nu;
    EXPECT_NEAR(explicitForce / oracle, 1.0, 0.12) << "nu " << nu;
    EXPECT_NEAR(explicitForce / implicitForce, 1.0, 0.02) << "nu " << nu;
  }
}

// A dent narrower than a region meets less than the modulus: the same punch with wider regions
// carries less, monotonically (the reason the node's default regions are w = 1). A wrong
// modulus must show as well.
TEST(LocalStiffness, WiderRegionsAreSofterUnderAPunch) {
  const double dx = 0.05 / 13, depth = 0.002;
  const Voxelization vox = block(13, 13, 13, dx);
  const double oracle = femPunch(vox, 5, depth, 0.0);
  double previous = 2.0 * oracle;
  for (int w : {1, 2, 4}) {
    const double f = ind::press(vox, ind::punch(5, dx), ind::kPunchBottom, depth, how(Integrator::Implicit, 4, w, 0.0)).force;
    std::printf("[ punch   ] w = %d: %.4f N, %.2f of the oracle\n", w, f, f / oracle);
    EXPECT_LT(f, previous);
    previous = f;
  }
  EXPECT_LT(previous / oracle, 0.6) << "w = 4 averages the dent away";
}

// A sphere of radius 2 cm pressed 1, 2 and 3 mm into a block 5 x 5 x 3 cm of 2.5 mm cells
// (contact radius 1.8 to 3.1 cells), against two references: Hertz on a layer bonded to its base
// (the block's pinned layer; a paraboloid, the layer unbounded) and the axisymmetric FEM of the
// block (the sphere as a sphere, the block as a cylinder of its area with a free side), 1 to 5 %
// below Hertz's series here. The lattice reads (measured) +16, +15, +15 % of the FEM at nu 0 and
// +12, +8, +5 % at 0.3 (+14, +12, +10 % and +10, +5, +1 % of Hertz's series): within 20 % of the
// FEM and 15 % of the series, the exponent 1.5 within 0.15; the explicit step agrees with the
// implicit within 2 %. About 3 % of the excess is the contact model's: its particles are spheres of
// radius r, so an indenter of radius R meets their centres as one of R + r (sqrt(1 + r / R)); the
// rest is the lattice's (docs/method.md: at nu 0 it stays +12 % at 3 to 5 cells of contact radius).
// The explicit step runs at 120 sub-steps, alpha a quarter of its cap: nearer the cap (60
// to 90 sub-steps) the frictionless dent gives way after 3 to 7 s, the top layer under the sphere
// scrambled and the force a third, a fault of the explicit step's contact on a curved surface
// (the same state handed to the implicit step recovers; docs/method.md).
TEST(LocalStiffness, SpherePressedIntoABlockFollowsHertz) {
  const double dx = 0.0025, R = 0.02;
  const Voxelization vox = block(21, 21, 12, dx);
  const double thickness = 11.5 * dx;  // from the pinned centres to the top face
  for (double nu : {0.0, 0.3}) {
    double f1 = 0.0, f3 = 0.0;
    for (double depth : {0.001, 0.002, 0.003}) {
      const double hertz = analytic::hertzSphereOnBondedLayerForce(R, depth, thickness, kModulus, nu);
      const double oracle = ind::sphereOracle(vox, R, depth, FemMaterial{kModulus, nu, 1000.0});
      const double f = ind::press(vox, ind::sphere(R), R, depth, how(Integrator::Implicit, 4, 1, nu)).force;
      std::printf("[ sphere  ] nu %.1f, depth %.0f mm: %.4f N, the FEM %.4f N (%+.1f %%), Hertz on the layer %.4f N "
                  "(%+.1f %%; half-space %.4f N)\n", nu, 1e3 * depth, f, oracle, 100 * (f / oracle - 1), hertz,
                  100 * (f / hertz - 1), analytic::hertzSphereForce(R, depth, kModulus, nu));
      EXPECT_NEAR(f / oracle, 1.0, 0.2) << "nu " << nu << ", depth " << depth;
      EXPECT_NEAR(f / hertz, 1.0, 0.15) << "nu " << nu << ", depth " << depth;
      EXPECT_LT(oracle, hertz) << "the sphere and the free side give less than the paraboloid on an unbounded layer";
      EXPECT_GT(oracle, 0.93 * hertz);
      if (depth == 0.001) f1 = f;
      if (depth == 0.003) f3 = f;
      if (depth == 0.002) {
        const ind::PressResult explicitPress = ind::press(vox, ind::sphere(R), R, depth, how(Integrator::Explicit, 120, 1, nu));
        const double e = explicitPress.force;
        const bool saturated = explicitPress.saturated;
        std::printf("[ sphere  ] explicit: %.4f N (%+.2f %% of the implicit)\n", e, 100 * (e / f - 1));
        EXPECT_FALSE(saturated);
        EXPECT_NEAR(e / f, 1.0, 0.02) << "nu " << nu;
      }
    }
    const double exponent = std::log(f3 / f1) / std::log(3.0);
    std::printf("[ sphere  ] nu %.1f: force ~ depth^%.3f\n", nu, exponent);
    EXPECT_NEAR(exponent, 1.5, 0.15);
  }
}

// The pressure under the sphere, what a touch image shows: each particle's recorded force on the
// sphere (Solver::recordContacts(), which ~tactile images are made of) over its cell's area, on a
// finer block (33 x 33 x 16 cells of 1.5 mm, R 2 cm, 2 mm deep: the contact 4 cells in radius).
// Against Hertz from the depth alone: the contact radius sqrt(R d) from the force's second moment
// about the axis (2 a^2 / 5 for Hertz's p0 sqrt(1 - r^2 / a^2)), and the peak p0 = 2 E* / pi
// sqrt(d / R), within 15 % (measured: radius +10 % and +11 %, peak +10 % and +1 % at nu 0 and
// 0.3; the layer bonded to its base widens and stiffens the contact); and the profile's shape,
// the mean pressure of each ring of particles against Hertz's with the measured force's a and p0,
// within 12 % of p0 (measured: 9.4 % and 7.7 % at most).
TEST(LocalStiffness, ThePressureUnderASphereHasHertzsProfile) {
  const double dx = 0.0015, R = 0.02, depth = 0.002;
  const Voxelization vox = block(33, 33, 16, dx);
  for (double nu : {0.0, 0.3}) {
    ind::Press p = how(Integrator::Implicit, 1, 1, nu);
    p.pressSeconds = p.holdSeconds = 1.0;
    Solver s(std::make_shared<const deformable_flsm::Lattice>(vox, p.density, p.w), ind::solverParams(p));
    ind::holdBase(s, vox);
    ind::lower(s, vox, ind::sphere(R), R, depth, p, true);
    const auto& contacts = s.recordedContacts("indenter");
    const auto& rest = s.lattice().restPositions();
    double force = 0.0, moment = 0.0, peak = 0.0;
    std::vector<std::pair<double, double>> rings;  // (radius, pressure) per particle
    for (const deformable_flsm::ParticleContact& c : contacts) {
      const double r = std::hypot(rest[c.particle].x(), rest[c.particle].y());
      force += c.force.z();
      moment += c.force.z() * r * r;
      peak = std::max(peak, c.force.z() / (dx * dx));
      rings.emplace_back(r, c.force.z() / (dx * dx));
    }
    const double eStar = kModulus / (1.0 - nu * nu);
    const double a = std::sqrt(2.5 * moment / force), aHertz = std::sqrt(R * depth);
    const double p0Hertz = 2.0 * eStar / M_PI * std::sqrt(depth / R);
    std::printf("[ profile ] nu %.1f: %zu particles, %.4f N; contact radius %.2f mm (Hertz %.2f, %+.1f %%), "
                "peak %.0f Pa (Hertz %.0f, %+.1f %%)\n", nu, contacts.size(), force, 1e3 * a, 1e3 * aHertz,
                100 * (a / aHertz - 1), peak, p0Hertz, 100 * (peak / p0Hertz - 1));
    EXPECT_GE(contacts.size(), 40u);
    EXPECT_NEAR(a / aHertz, 1.0, 0.15) << "nu " << nu;
    EXPECT_NEAR(peak / p0Hertz, 1.0, 0.15) << "nu " << nu;
    // the shape: Hertz's profile with the measured force's a and p0
    const double aF = std::cbrt(3.0 * force * R / (4.0 * eStar)), p0F = 3.0 * force / (2.0 * M_PI * aF * aF);
    std::sort(rings.begin(), rings.end());
    double worst = 0.0;
    for (std::size_t k = 0; k < rings.size();) {
      std::size_t end = k;
      double sum = 0.0;
      while (end < rings.size() && rings[end].first < rings[k].first + 1e-9) sum += rings[end++].second;
      const double r = rings[k].first, mean = sum / static_cast<double>(end - k);
      const double hertz = r < aF ? p0F * std::sqrt(1.0 - r * r / (aF * aF)) : 0.0;
      EXPECT_NEAR(mean, hertz, 0.12 * p0F) << "nu " << nu << ", ring at " << 1e3 * r << " mm";
      worst = std::max(worst, std::abs(mean - hertz) / p0F);
      k = end;
    }
    std::printf("[ profile ] nu %.1f: each ring within %.1f %% of p0 of Hertz's profile for the force\n", nu, 100 * worst);
  }
}

// A grasp's squeeze: a 5 cm cube of 13 cells, no gravity and no pins, held only between two
// pads (boxes wider than its faces, friction 1 as the grasp scenes' fingers) closed 1 mm each
// over 0.5 s and held: each pad's force against the oracle's cube with both faces' nodes moved
// 1 mm inwards and held there across (the pads stick), within 15 %, at nu 0 and 0.3, both steps
// (measured: +4.8 % and +10.2 %, the steps within 0.05 % of each other; at nu 0 the oracle is
// E A 2d / L exactly, and the lattice's outer particle layers, whose spheres the pads push, are
// L - dx apart).
TEST(LocalStiffness, SqueezeBetweenTwoPadsMeetsTheFemOracle) {
  const double dx = 0.05 / 13, d = 0.001, L = 0.05;
  Voxelization vox = block(13, 13, 13, dx);
  for (double nu : {0.0, 0.3}) {
    FemOracle fem(vox, FemMaterial{kModulus, nu, 1000.0}, 1);
    const double big = 1e3, eps = 1e-9;
    for (int side : {-1, 1}) {
      const Eigen::Vector3d lo(side < 0 ? -big : 0.5 * L - eps, -big, -big);
      const Eigen::Vector3d hi(side < 0 ? -0.5 * L + eps : big, big, big);
      fem.prescribeInBox(lo, hi, 0, -side * d);
      fem.prescribeInBox(lo, hi, 1, 0.0);
      fem.prescribeInBox(lo, hi, 2, 0.0);
    }
    const FemSolution u = fem.solveStatic(Eigen::Vector3d::Zero());
    // the +x face's reaction pushes the body along -x
    const double oracle = -fem.reactionInBox(u, Eigen::Vector3d(0.5 * L - eps, -big, -big), Eigen::Vector3d::Constant(big)).x();
    double forces[2] = {0.0, 0.0};
    int k = 0;
    for (Integrator integrator : {Integrator::Implicit, Integrator::Explicit}) {
      const SolverParams p = ind::solverParams(how(integrator, integrator == Integrator::Explicit ? 120 : 4, 1, nu));
      Solver s(std::make_shared<const deformable_flsm::Lattice>(vox, p.density, 1), p);
      for (int side : {-1, 1}) {
        deformable_flsm::Collider c;
        c.shape.type = deformable_flsm::ColliderType::Box;
        c.shape.halfExtents = Eigen::Vector3d(0.01, 0.04, 0.04);
        c.staticFriction = c.kineticFriction = 1.0;
        c.pose.translation() = Eigen::Vector3d(side * (0.5 * L + 0.01), 0, 0.5 * L);
        s.setCollider(side < 0 ? "left" : "right", c);
      }
      for (int i = 0; i < 60; ++i) {
        const double closed = d * std::min(1.0, i / 15.0);
        for (int side : {-1, 1}) {
          Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
          pose.translation() = Eigen::Vector3d(side * (0.5 * L + 0.01 - closed), 0, 0.5 * L);
          s.moveCollider(side < 0 ? "left" : "right", pose, Eigen::Vector3d(i < 15 ? -side * d / 0.5 : 0.0, 0, 0),
                         Eigen::Vector3d::Zero());
        }
        s.step();
      }
      EXPECT_FALSE(s.stiffnessSaturated());
      forces[k++] = s.contactWrench("right").force.x();
    }
    std::printf("[ squeeze ] nu %.1f: oracle %.3f N, implicit %.3f N (%+.1f %%), explicit %.3f N (%+.1f %%)\n", nu,
                oracle, forces[0], 100 * (forces[0] / oracle - 1), forces[1], 100 * (forces[1] / oracle - 1));
    EXPECT_NEAR(forces[0] / oracle, 1.0, 0.15) << "nu " << nu;
    EXPECT_NEAR(forces[1] / oracle, 1.0, 0.15) << "nu " << nu;
    EXPECT_NEAR(forces[1] / forces[0], 1.0, 0.02) << "nu " << nu;
  }
}

// A pad placed 3 mm into 3.85 mm cells (deeper than a particle's radius, 1.92 mm) is a state no
// motion made: its wrench counts the buried particles, so that the node can say so; pressed in
// over 0.5 s, none is buried at any step.
TEST(LocalStiffness, APadPlacedIntoTheObjectCountsTheParticlesBuriedInIt) {
  const double dx = 0.05 / 13, depth = 0.003;
  const Voxelization vox = block(13, 13, 13, dx);
  const SolverParams p = ind::solverParams(how(Integrator::Implicit, 4, 1, 0.0));
  const auto lattice = std::make_shared<const deformable_flsm::Lattice>(vox, p.density, 1);
  const double top = ind::topOf(vox);
  auto pad = [&](Solver& s, double z) {
    deformable_flsm::Collider c = ind::punch(5, dx);
    c.pose.translation() = Eigen::Vector3d(0, 0, z + ind::kPunchBottom);
    s.setCollider("pad", c);
  };
  Solver placed(lattice, p);
  ind::holdBase(placed, vox);
  pad(placed, top - depth);
  placed.step();
  EXPECT_GE(placed.contactWrench("pad").buried, 9u) << "the 5 x 5 particles under the pad start inside it";
  for (int i = 0; i < 30; ++i) placed.step();
  EXPECT_EQ(placed.contactWrench("pad").buried, 0u) << "pushed out, nothing is buried any more";

  Solver pressed(lattice, p);
  ind::holdBase(pressed, vox);
  pad(pressed, top);
  for (int i = 0; i < 30; ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(0, 0, top + ind::kPunchBottom - depth * std::min(1.0, i / 15.0));
    pressed.moveCollider("pad", pose, Eigen::Vector3d(0, 0, i < 15 ? -depth / 0.5 : 0.0), Eigen::Vector3d::Zero());
    pressed.step();
    ASSERT_EQ(pressed.contactWrench("pad").buried, 0u) << "step " << i;
  }
  EXPECT_GT(pressed.contactWrench("pad").contacts, 0u);
}

