// What the object (Solver) drives either integrator's sub-step through: the explicit step
// (explicit_step.h) and the implicit one (implicit_step.h) each implement it with their own
// state. Internal to the core.
#pragma once

#include "deformable_flsm/core/solver.h"

#include <Eigen/Core>

#include <vector>

namespace deformable_flsm {

class Solver::IntegratorStep {
 public:
  virtual ~IntegratorStep() = default;
  /// One sub-step of length h, from the pending impulses to the prescribed particles and the
  /// clock (Solver::endSubstep()).
  virtual void substep(double h) = 0;
  /// The goals of the running sub-step's region pass: the contact pass bounds its push-out by them.
  virtual const std::vector<Eigen::Vector3d>& goals() const = 0;
  /// The state was set from outside, or the object slept: what the step carries over from the
  /// last sub-step's state no longer holds.
  virtual void forgetHistory() = 0;
};

}  // namespace deformable_flsm
