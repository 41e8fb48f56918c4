/// @file solver_params.h
/// Plain parameters of the FastLSM solver, filled by the caller (the ROS layer reads them).
#pragma once

#include <Eigen/Core>

#include <stdexcept>
#include <string>

namespace deformable_flsm {

/// Which way region sums are computed. Both give the same results (to round-off).
enum class SolverKind {
  /// FastLSM separable summation: cost per particle independent of the region half-width w
  Fast,
  /// Direct summation over each region's members, O(w^3) per particle (the seed's "SLSM");
  /// kept as the oracle the fast solver is tested against
  Naive,
};

/// Parses "fast" / "naive". @throws std::invalid_argument otherwise.
SolverKind parseSolverKind(const std::string& name);
/// "fast" or "naive".
const char* toString(SolverKind kind);

struct SolverParams {
  /// Region half-width w in lattice cells: a region spans up to (2w+1)^3 cells. Larger is stiffer.
  int regionHalfWidth = 2;
  /// Fraction alpha in (0, 1] of the way to the goal positions taken per time step:
  /// v += alpha (g - x) / h (Rivers & James 2007, eq. 7).
  double stiffness = 1.0;
  /// Rate (1/s) at which each region's deviation from rigid motion is damped; 0 for none.
  /// Momentum-conserving: linear and angular momentum of every region are kept. Bending modes
  /// longer than a region look nearly rigid inside each region and are damped far more slowly
  /// than this rate, hence a default well above the wobble one wants to see.
  double damping = 10.0;
  /// Rate (1/s) at which every particle's deviation from the whole object's rigid motion (the
  /// velocity field with the object's linear and angular momentum) is damped; 0 for none. It
  /// reaches the long bending modes that region damping hardly sees, damps every mode alike,
  /// and conserves the object's linear and angular momentum.
  double globalDamping = 1.0;
  /// Gravitational acceleration (m/s^2).
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  /// Simulated time advanced by one call of Solver::step() (s).
  double timeStep = 1.0 / 60.0;
  /// Sub-steps per call of Solver::step(); each advances timeStep / substeps.
  int substeps = 4;
  /// Mass density of the object (kg/m^3); particle mass = density * filled cell volume.
  double density = 1000.0;
  SolverKind kind = SolverKind::Fast;

  /// @throws std::invalid_argument with a message naming the field, its value and the valid range.
  void validate() const;
};

}  // namespace deformable_flsm
