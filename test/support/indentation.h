/// @file indentation.h
/// The local cases of the material: a flat punch and a sphere pressed into a block of lattice
/// cells held by its bottom layer, read as the indenter's force once settled, and the FEM
/// oracle's punch on the same voxels. Shared by test_local_stiffness and bench_material --local.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "support/axisymmetric_press.h"
#include "support/fem_oracle.h"
#include "support/params.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <memory>

namespace deformable_flsm {
namespace indentation {

/// Height (m) of a block's top face (its base on z = 0).
inline double topOf(const Voxelization& vox) {
  int top = 0;
  for (const Eigen::Vector3i& c : vox.cells) top = std::max(top, c.z() + 1);
  return top * vox.spacing;
}

/// How a block is pressed.
struct Press {
  Integrator integrator = Integrator::Implicit;
  int substeps = 4;
  int w = 1;
  double nu = 0.0;
  double youngsModulus = 20000.0;
  double density = 1000.0;
  /// step (s); the indenter is lowered over `pressSeconds`, then held `holdSeconds`
  double timeStep = 1.0 / 30.0;
  double pressSeconds = 0.5;
  double holdSeconds = 1.5;
};

/// What press() read.
struct PressResult {
  /// the indenter's force (N, upwards) over the last step
  double force = 0.0;
  std::size_t contacts = 0;
  /// the explicit step's alpha was capped: the material was softer than asked
  bool saturated = false;
};

/// The solver's parameters for `how`, gravity off.
inline SolverParams solverParams(const Press& how) {
  SolverParams p = test::physicalParams(how.youngsModulus, how.nu, how.w, how.timeStep, how.substeps, how.integrator);
  p.density = how.density;
  p.gravity.setZero();
  return p;
}

/// Pins the bottom layer of particles of a block whose base is on z = 0.
inline void holdBase(Solver& s, const Voxelization& vox) {
  s.pinBox(Eigen::Vector3d::Constant(-1e3), Eigen::Vector3d(1e3, 1e3, 0.6 * vox.spacing), true);
}

/// Into the block (voxels with their base on z = 0) that solver `s` holds as its caller set it
/// up, the frictionless indenter `shape` (collider "indenter") with its lowest point `bottom`
/// below its frame origin, starting at the block's top face, lowered by `depth` (m) over
/// how.pressSeconds, then held how.holdSeconds; its contacts recorded
/// (s.recordedContacts("indenter")) when `record`.
inline void lower(Solver& s, const Voxelization& vox, const Collider& shape, double bottom, double depth,
                  const Press& how, bool record = false) {
  const double top = topOf(vox);
  Collider c = shape;
  c.staticFriction = c.kineticFriction = 0.0;
  c.pose.translation() = Eigen::Vector3d(0, 0, top + bottom);
  s.setCollider("indenter", c);
  if (record) s.recordContacts("indenter", true);
  const int pressSteps = std::max(1, static_cast<int>(std::lround(how.pressSeconds / how.timeStep)));
  const int holdSteps = static_cast<int>(std::lround(how.holdSeconds / how.timeStep));
  for (int i = 0; i < pressSteps + holdSteps; ++i) {
    const bool moving = i < pressSteps;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(0, 0, top + bottom - depth * std::min(1.0, double(i) / pressSteps));
    const double speed = moving ? depth / (pressSteps * how.timeStep) : 0.0;
    s.moveCollider("indenter", pose, Eigen::Vector3d(0, 0, -speed), Eigen::Vector3d::Zero());
    s.step();
  }
}

/// The block held by its bottom layer of particles, gravity off, the indenter lowered into it
/// (lower()).
inline PressResult press(const Voxelization& vox, const Collider& shape, double bottom, double depth,
                         const Press& how) {
  Solver s(std::make_shared<const Lattice>(vox, how.density, how.w), solverParams(how));
  holdBase(s, vox);
  lower(s, vox, shape, bottom, depth, how);
  return {s.contactWrench("indenter").force.z(), s.contactWrench("indenter").contacts, s.stiffnessSaturated()};
}

/// A flat square punch k cells wide (a little less, so that exactly k x k particles meet it when
/// centred over the middle cell of a block with an odd number of cells across); its lowest
/// point 0.01 m below its frame origin.
inline Collider punch(int k, double dx) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = Eigen::Vector3d(0.5 * (k - 0.4) * dx, 0.5 * (k - 0.4) * dx, 0.01);
  return c;
}
constexpr double kPunchBottom = 0.01;

inline Collider sphere(double radius) {
  Collider c;
  c.shape.type = ColliderType::Sphere;
  c.shape.radius = radius;
  return c;
}

/// The oracle's press on the same block: its nodes held up to the centres of the pinned layer
/// (with one element per cell, only the base face has nodes there), the top nodes within
/// `halfWidth` of the z axis lowered by `depth` (frictionless: z only; `bonded`: held sideways
/// too, a punch the surface sticks to). The solution, and in `force` the tool's force (N,
/// upwards).
inline FemSolution femPress(FemOracle& fem, const Voxelization& vox, double halfWidth, double depth,
                            double& force, bool bonded = false) {
  const double dx = vox.spacing, top = topOf(vox), half = halfWidth;
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-1e3), Eigen::Vector3d(1e3, 1e3, 0.5 * dx + 1e-9));
  const Eigen::Vector3d lo(-half, -half, top - 1e-9), hi(half, half, top + 1e-9);
  if (bonded) {
    fem.prescribeInBox(lo, hi, 0, 0.0);
    fem.prescribeInBox(lo, hi, 1, 0.0);
  }
  fem.prescribeInBox(lo, hi, 2, -depth);
  FemSolution u = fem.solveStatic(Eigen::Vector3d::Zero());
  force = -fem.reactionInBox(u, Eigen::Vector3d(-1e3, -1e3, top - 1e-9), Eigen::Vector3d::Constant(1e3)).z();
  return u;
}

/// The oracle's punch: the top nodes over the k x k cells the punch meets pressed (femPress()),
/// one element per cell (two per edge read 3 % less on 13 cells at nu 0, but take minutes to
/// factorize). The punch's force (N).
inline double femPunch(const Voxelization& vox, int k, double depth, const FemMaterial& material,
                       bool bonded = false) {
  FemOracle fem(vox, material, 1);
  double force = 0.0;
  femPress(fem, vox, 0.5 * k * vox.spacing + 1e-9, depth, force, bonded);
  return force;
}

/// The oracle's sphere on the same block: the axisymmetric FEM (axisymmetricPress()) of a
/// cylinder of the block's top area, bonded at its pinned layer's centres, a sphere of `radius`
/// pressed `depth` into the top face's centre, frictionless. Its force (N).
inline double sphereOracle(const Voxelization& vox, double radius, double depth, const FemMaterial& material) {
  const double top = topOf(vox);
  std::size_t topCells = 0;
  for (const Eigen::Vector3i& c : vox.cells) topCells += (c.z() + 1) * vox.spacing > top - 1e-9;
  AxisymmetricPress p;
  p.indenterRadius = radius;
  p.depth = depth;
  p.thickness = top - 0.5 * vox.spacing;
  p.outerRadius = vox.spacing * std::sqrt(static_cast<double>(topCells) / 3.14159265358979323846);
  p.material = material;
  return axisymmetricPress(p).force;
}

}  // namespace indentation
}  // namespace deformable_flsm
