/// @file solver_material_fixtures.h
/// What the tests of the physical mode share (test_solver_material,
/// test_solver_material_dynamics): its parameters, boxes of cells, a modulus below the cap,
/// end forces that pull a bar apart.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "fixtures.h"
#include "support/params.h"

#include <Eigen/Core>

#include <cmath>
#include <cstdint>
#include <vector>

namespace deformable_flsm {
namespace solver_material_fixtures {

constexpr double kDensity = 1000.0;
constexpr double kStep = 1.0 / 60.0;
constexpr double kBig = 1e3;

inline Voxelization box(int nx, int ny, int nz, double h, const Eigen::Vector3d& origin) {
  Voxelization v = deformable_flsm::test::makeBox(nx, ny, nz, h);
  v.origin = origin;
  return v;
}

/// Young's modulus that asks for alpha = 0.3 at w = 1 and 4 sub-steps of 1/60 s, nu = 0 (Pa):
/// below the cap, so that the material is what was asked for.
inline double modulusFor(double h) { return 0.3 * kDensity * h * h * 2.0 / (3.0 * std::pow(kStep / 4, 2)); }

inline SolverParams physical(double E, double nu, int w, int substeps) {
  return test::physicalParams(E, nu, w, kStep, substeps);
}

/// Pulls a bar of `along` cells along x apart: -F on its first cell layer, +F on its last, for
/// `duration` s.
inline void pullEnds(Solver& s, int along, double F, double duration) {
  std::vector<std::uint32_t> left, right;
  for (std::uint32_t i = 0; i < s.lattice().size(); ++i) {
    if (s.lattice().cells()[i].x() == 0) left.push_back(i);
    if (s.lattice().cells()[i].x() == along - 1) right.push_back(i);
  }
  s.applyForce(left, Eigen::Vector3d(-F, 0, 0), duration);
  s.applyForce(right, Eigen::Vector3d(F, 0, 0), duration);
}

}  // namespace solver_material_fixtures
}  // namespace deformable_flsm
