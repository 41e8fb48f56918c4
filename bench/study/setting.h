/// @file setting.h
/// A study setting (resolution, sub-steps, frame step, material, loads) and the single place
/// where it becomes FastLSM solver parameters.
///
/// Every FastLSM run of the speed/accuracy study (bench/study/flsm_study.cpp, scripts/study) and
/// of the stress tests (test/core/test_scenarios.cpp) takes its SolverParams from flsmParams()
/// below: a change of how the solver is configured is one edit here.
#pragma once

#include "deformable_flsm/core/solver_params.h"
#include "support/params.h"

#include <Eigen/Core>

namespace deformable_flsm {
namespace study {

/// Mass density of every study object (kg/m^3).
constexpr double kStudyDensity = 1000.0;
/// Poisson's ratio of every study material (FastLSM, the FEM oracle and Bullet's deformable body
/// take it; the mass-spring lattice and the legacy soft body have no such parameter).
constexpr double kStudyPoissonRatio = 0.3;
/// The bunny file's units to metres in the study's programs (the ~2-unit bunny becomes ~30 cm).
constexpr double kStudyBunnyScale = 0.1;

/// One point of the study's grid: how finely space and time are cut, the material, the loads.
struct Setting {
  /// Lattice cells along the object's longest bounding-box axis (VoxelizeOptions::resolution).
  int resolution = 16;
  /// Sub-steps per frame.
  int substeps = 1;
  /// Frame step (s): the simulated time one call of step() advances.
  double frameStep = 1.0 / 60.0;
  /// Young's modulus of the object (Pa).
  double youngsModulus = 1e4;
  /// Poisson's ratio of the object.
  double poissonRatio = kStudyPoissonRatio;
  /// Reach of a shape-matching region (m), the same at every resolution.
  double regionRadius = 0.01;
  /// Rate (1/s) of drag towards rest in the world frame (SolverParams::ambientDamping); every
  /// method of the study gets the same.
  double ambientDamping = 0.5;
  /// Gravitational acceleration or body load (m/s^2).
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();

  /// Sub-step length h = frameStep / substeps (s).
  double substep() const { return frameStep / substeps; }
};

/// The FastLSM parameters of a study run: Young's modulus (the same material at every resolution
/// and step, SolverParams::youngsModulus), the regions of the lattice it runs on (buildLattice():
/// the object's region radius narrowed to its thinnest section), alpha capped at 1 (a sub-step
/// too long for the explicit step's modulus simulates a softer object; the study measures that),
/// the setting's ambient damping and loads, the package's default region damping, one thread.
///
/// @param[in] setting            resolution, sub-steps, frame step, material, damping, gravity
/// @param[in] regionHalfWidth    w of the lattice built for this setting (Lattice::regionHalfWidth())
/// @param[in] kind               Fast (FastLSM summation) or Naive (direct region sums)
/// @param[in] integrator         Explicit (symplectic Euler, alpha capped) or Implicit (linearly
///                               implicit backward Euler, alpha as asked at every sub-step)
/// @return parameters that pass SolverParams::validate()
inline SolverParams flsmParams(const Setting& setting, int regionHalfWidth, SolverKind kind,
                               Integrator integrator = Integrator::Explicit) {
  SolverParams p = test::physicalParams(setting.youngsModulus, setting.poissonRatio, regionHalfWidth,
                                        setting.frameStep, setting.substeps, integrator);
  p.kind = kind;
  p.density = kStudyDensity;
  p.stiffness = 1.0;
  p.ambientDamping = setting.ambientDamping;
  p.gravity = setting.gravity;
  p.threads = 1;  // the study compares single-thread costs
  p.validate();
  return p;
}

}  // namespace study
}  // namespace deformable_flsm
