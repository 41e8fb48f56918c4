/// @file solver_fixtures.h
/// What the solver's tests share (test_solver, test_solver_drags): a small bar, weightless and
/// isolated parameters, a finiteness check, a rigid motion.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "fixtures.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <memory>
#include <vector>

namespace deformable_flsm {
namespace solver_fixtures {

/// A 12 x 4 x 4 bar of 1 cm cells (12 cm long).
inline std::shared_ptr<const Lattice> bar(int w = 2) {
  return std::make_shared<const Lattice>(test::makeBox(12, 4, 4, 0.01), 1000.0, w);
}

inline SolverParams weightless() {
  SolverParams p;
  p.gravity.setZero();
  return p;
}

/// No external influence at all: what momentum conservation is about.
inline SolverParams isolated() {
  SolverParams p = weightless();
  p.ambientDamping = 0.0;
  return p;
}

inline bool allFinite(const std::vector<Eigen::Vector3d>& x) {
  for (const auto& v : x)
    if (!v.allFinite()) return false;
  return true;
}

inline Eigen::Isometry3d someRigidMotion() {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(2.5, Eigen::Vector3d(1, -2, 0.5).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(3.0, -1.0, 0.4);
  return T;
}

}  // namespace solver_fixtures
}  // namespace deformable_flsm
