/// @file solver_implicit_fixtures.h
/// What the implicit integrator's tests share (test_solver_implicit,
/// test_solver_implicit_contact): its parameters at one sub-step, a ground below a solver.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "support/params.h"

#include <Eigen/Core>

#include <algorithm>

namespace deformable_flsm {
namespace solver_implicit_fixtures {

constexpr double kDensity = 1000.0;
constexpr double kBig = 1e3;

inline SolverParams implicitParams(double E, double nu, int w, double timeStep) {
  return test::physicalParams(E, nu, w, timeStep, 1, Integrator::Implicit);
}

/// A ground plane `gap` below the solver's lowest particle's contact sphere.
inline Collider groundBelow(const Solver& s, double gap) {
  double lowest = kBig;
  for (const auto& x : s.positions()) lowest = std::min(lowest, x.z());
  Collider ground;
  ground.shape.type = ColliderType::HalfSpace;
  ground.pose.translation() = Eigen::Vector3d(0, 0, lowest - s.contactRadius() - gap);
  return ground;
}

}  // namespace solver_implicit_fixtures
}  // namespace deformable_flsm
