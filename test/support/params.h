/// @file params.h
/// The physical material that the tests and benchmarks give their solvers.
#pragma once

#include "deformable_flsm/core/solver_params.h"

namespace deformable_flsm {
namespace test {

/// Young's modulus E (Pa), Poisson's ratio nu, regions of half-width w, frames of `timeStep` s
/// in `substeps` sub-steps of `integrator`; every other field SolverParams' default.
inline SolverParams physicalParams(double E, double nu, int w, double timeStep, int substeps,
                                   Integrator integrator = Integrator::Explicit) {
  SolverParams p;
  p.youngsModulus = E;
  p.poissonsRatio = nu;
  p.regionHalfWidth = w;
  p.timeStep = timeStep;
  p.substeps = substeps;
  p.integrator = integrator;
  return p;
}

}  // namespace test
}  // namespace deformable_flsm
