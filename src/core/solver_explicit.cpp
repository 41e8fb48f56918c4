// The explicit sub-step (explicit_step.h): FastLSM's symplectic Euler, its particles updated by
// the region pass (ExplicitStep::update(), inlined into Solver::particleResult()).
#include "deformable_flsm/core/solver.h"
#include "explicit_step.h"

#include <cmath>

namespace deformable_flsm {

Solver::ExplicitStep::ExplicitStep(Solver& object)
    : o_(object),
      goal_(object.lattice_->size(), Eigen::Vector3d::Zero()),
      freeVelocity_(object.lattice_->size(), Eigen::Vector3d::Zero()) {}

// One sub-step of FastLSM dynamics (Rivers & James 2007, eq. 7):
//   v <- v + alpha (g - x) / h + h f / m,   damping,   x <- x + h v.
// Shape matching and both dampings act on the state at the start of the sub-step:
//   v <- v_obj + keep (v - v_obj) + alpha s_i (g - x) / h + h f / m + kd (v_rigid(v) - v)
// with v_obj the object's rigid motion; v <- (v + ...) keep when held by the world (see
// Solver::rigidMotion()).
// The update of each particle is the last step of the region pass (update()), done as soon as its
// goal is known: the state is read and written in one sweep over the lattice.
void Solver::ExplicitStep::substep(double h) {
  o_.applyPendingImpulses();
  o_.accumulateForces(h);
  k_.h = h;
  k_.kd = 1.0 - std::exp(-o_.params_.damping * h);
  k_.pull = o_.alpha_ / h;
  k_.keep = std::exp(-o_.params_.ambientDamping * h);
  k_.relative = o_.params_.ambientDamping > 0.0 && !o_.heldByWorld();
  k_.forced = !o_.forcedParticles_.empty();
  if (k_.relative) rigid_ = o_.rigidMotion();
  if (o_.volumetric_) o_.computeVolumetricForces();
  // the region pass integrates, and finishSubstep() counts the hard drags' impulses, with this step
  o_.integrating_ = this;
  o_.regionPass(k_.kd > 0.0);
  o_.endSubstep(h, h);
  o_.integrating_ = nullptr;
}

}  // namespace deformable_flsm
