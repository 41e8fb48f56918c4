// The material under a finger: a flat punch and a sphere pressed into a block, against the FEM
// oracle (the punch, its displacement prescribed on the same footprint) and Hertz's contact on a
// bonded layer (the sphere), with both integrators; the regions' size against what a dent
// narrower than a region meets. bench_material prints the full table (--local).
#include "deformable_flsm/core/solver.h"
#include "fixtures.h"
#include "support/fem_oracle.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

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
namespace analytic = deformable_flsm::analytic;

namespace {

constexpr double kDensity = 1000.0;
constexpr double kStep = 1.0 / 30.0;
constexpr double kModulus = 20000.0;  // soft enough for the explicit step at 60-120 sub-steps

/// Height (m) of a block's top face (its base on z = 0).
double topOf(const Voxelization& vox) {
  int top = 0;
  for (const Eigen::Vector3i& c : vox.cells) top = std::max(top, c.z() + 1);
  return top * vox.spacing;
}

/// A block of nx x ny x nz cells of spacing dx, its base on z = 0, centred on the z axis.
Voxelization block(int nx, int ny, int nz, double dx) {
  Voxelization v = deformable_flsm::test::makeBox(nx, ny, nz, dx);
  v.origin = Eigen::Vector3d(-0.5 * nx * dx, -0.5 * ny * dx, 0.0);
  return v;
}

struct Press {
  Integrator integrator = Integrator::Implicit;
  int substeps = 4;
  int w = 1;
  double nu = 0.0;
};

/// The block held by its bottom layer of particles, gravity off, an indenter (frictionless,
/// the collider `shape` with its lowest point at the block's top centre at rest, offset by
/// `bottom` below the frame origin) lowered by `depth` over 0.5 s and held 1.5 s. The indenter's
/// force (N, upwards) once settled.
double press(const Voxelization& vox, const Collider& shape, double bottom, double depth, const Press& how,
             bool* saturated = nullptr) {
  SolverParams p;
  p.density = kDensity;
  p.youngsModulus = kModulus;
  p.poissonsRatio = how.nu;
  p.regionHalfWidth = how.w;
  p.timeStep = kStep;
  p.substeps = how.substeps;
  p.integrator = how.integrator;
  p.gravity.setZero();
  Solver s(std::make_shared<const Lattice>(vox, kDensity, how.w), p);
  s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(1.0, 1.0, 0.6 * vox.spacing), true);
  const double top = topOf(vox);
  Collider c = shape;
  c.staticFriction = c.kineticFriction = 0.0;
  c.pose.translation() = Eigen::Vector3d(0, 0, top + bottom);
  s.setCollider("indenter", c);
  const int pressSteps = static_cast<int>(std::lround(0.5 / kStep)), holdSteps = static_cast<int>(std::lround(1.5 / kStep));
  for (int i = 0; i < pressSteps + holdSteps; ++i) {
    const bool moving = i < pressSteps;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(0, 0, top + bottom - depth * std::min(1.0, double(i) / pressSteps));
    s.moveCollider("indenter", pose, Eigen::Vector3d(0, 0, moving ? -depth / 0.5 : 0.0), Eigen::Vector3d::Zero());
    s.step();
  }
  if (saturated) *saturated = s.stiffnessSaturated();
  return s.contactWrench("indenter").force.z();
}

/// A flat square punch k cells wide (a little less, so that exactly k x k particles meet it),
/// centred over the middle cell of a block with an odd number of cells across.
Collider punch(int k, double dx) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = Eigen::Vector3d(0.5 * (k - 0.4) * dx, 0.5 * (k - 0.4) * dx, 0.01);
  return c;
}

/// The oracle's punch: the same block, its nodes held up to the centres of the pinned layer, the
/// top nodes over the k x k cells the punch meets lowered by `depth` (frictionless: z only),
/// one element per cell (two per edge: 3 % less at 13 cells across and nu = 0, but minutes of
/// factorization). The punch's force (N).
double femPunch(const Voxelization& vox, int k, double depth, double nu) {
  FemOracle fem(vox, FemMaterial{kModulus, nu, kDensity}, 1);
  const double dx = vox.spacing, top = topOf(vox), half = 0.5 * k * dx + 1e-9;
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(1.0, 1.0, 0.5 * dx + 1e-9));
  fem.prescribeInBox(Eigen::Vector3d(-half, -half, top - 1e-9), Eigen::Vector3d(half, half, top + 1e-9), 2, -depth);
  const FemSolution u = fem.solveStatic(Eigen::Vector3d::Zero());
  double force = 0.0;
  for (std::size_t n = 0; n < u.nodeReactions.size(); ++n)
    if (fem.nodePositions()[n].z() > top - 1e-9) force -= u.nodeReactions[n].z();
  return force;
}

Collider sphere(double radius) {
  Collider c;
  c.shape.type = ColliderType::Sphere;
  c.shape.radius = radius;
  return c;
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
    bool saturated = true;
    const double implicitForce = press(vox, punch(5, dx), 0.01, depth, {Integrator::Implicit, 4, 1, nu});
    const double explicitForce =
        press(vox, punch(5, dx), 0.01, depth, {Integrator::Explicit, nu > 0 ? 120 : 60, 1, nu}, &saturated);
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
    const double f = press(vox, punch(5, dx), 0.01, depth, {Integrator::Implicit, 4, w, 0.0});
    std::printf("[ punch   ] w = %d: %.4f N, %.2f of the oracle\n", w, f, f / oracle);
    EXPECT_LT(f, previous);
    previous = f;
  }
  EXPECT_LT(previous / oracle, 0.6) << "w = 4 averages the dent away";
}

// A sphere of radius 2 cm pressed 1, 2 and 3 mm into a block 5 x 5 x 3 cm of 2.5 mm cells
// (contact radius 1.8 to 3.1 cells): the force follows Hertz on a layer bonded to its base
// (the block's pinned layer) within 15 % (measured: +14, +12, +10 % at nu 0, +10, +5, +1 % at
// 0.3; part of it is the contact model's, whose particles are spheres of radius r, so that an
// indenter of radius R meets their centres as one of R + r: sqrt(1 + r / R) = 1.03 here), the
// exponent 1.5 within 0.15, at nu 0 and 0.3; the explicit step agrees with the implicit within
// 2 %. The explicit step runs at 120 sub-steps, alpha a quarter of its cap: nearer the cap (60
// to 90 sub-steps) the held dent gives way after 3 to 7 s, the force falling to a third with the
// surface buckled under the sphere, which the implicit step does not do (not yet understood).
TEST(LocalStiffness, SpherePressedIntoABlockFollowsHertz) {
  const double dx = 0.0025, R = 0.02;
  const Voxelization vox = block(21, 21, 12, dx);
  const double thickness = 11.5 * dx;  // from the pinned centres to the top face
  for (double nu : {0.0, 0.3}) {
    double f1 = 0.0, f3 = 0.0;
    for (double depth : {0.001, 0.002, 0.003}) {
      const double hertz = analytic::hertzSphereOnBondedLayerForce(R, depth, thickness, kModulus, nu);
      const double f = press(vox, sphere(R), R, depth, {Integrator::Implicit, 4, 1, nu});
      std::printf("[ sphere  ] nu %.1f, depth %.0f mm: %.4f N, Hertz on the layer %.4f N (%+.1f %%; half-space %.4f N)\n",
                  nu, 1e3 * depth, f, hertz, 100 * (f / hertz - 1),
                  analytic::hertzSphereForce(R, depth, kModulus, nu));
      EXPECT_NEAR(f / hertz, 1.0, 0.15) << "nu " << nu << ", depth " << depth;
      if (depth == 0.001) f1 = f;
      if (depth == 0.003) f3 = f;
      if (depth == 0.002) {
        bool saturated = true;
        const double e = press(vox, sphere(R), R, depth, {Integrator::Explicit, 120, 1, nu}, &saturated);
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
