// The explicit step of one object: FastLSM's symplectic Euler sub-step (Rivers & James 2007,
// eq. 7), each particle updated by the region pass as soon as its goal is known
// (Solver::particleResult() calls update()). The object (Solver) owns it, made with the explicit
// integrator, and drives it through substep(). Internal to the core; solver_explicit.cpp defines
// its sub-step.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "integrator_step.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

/// Reads and moves the object's particles (o_); what only this step needs is its own.
class Solver::ExplicitStep final : public Solver::IntegratorStep {
 public:
  explicit ExplicitStep(Solver& object);

  void substep(double h) override;
  const std::vector<Eigen::Vector3d>& goals() const override { return goal_; }
  /// Nothing carries over: every sub-step starts from the object's state alone.
  void forgetHistory() override {}

  /// Particle i's sub-step in the region pass, g its goal and s its regions' sums (transforms,
  /// then the damping field's u and omega).
  // Always inlined: particleResult()'s loop is compiled per SIMD level with everything it calls.
  [[gnu::always_inline]] inline void update(std::size_t i, const Eigen::Vector3d& g, const double* s);
  /// Counts into hard drag d the impulse that held particle p on its target against this
  /// sub-step (after finishSubstep() moved it there).
  void countDragImpulse(Drag& d, std::uint32_t p) const;

 private:
  /// What the region pass of a sub-step needs to update the particles (update()).
  struct Constants {
    double h = 0.0;          // sub-step (s)
    double kd = 0.0;         // region damping fraction per sub-step
    double pull = 0.0;       // alpha / h
    double keep = 1.0;       // ambient damping factor per sub-step
    bool forced = false;     // some particle has a force or spring acceleration (forceAccel_)
    bool relative = false;   // ambient damping relative to the object's rigid motion
  };

  Solver& o_;  // the object stepped
  Constants k_;
  /// each particle's goal in the sub-step's region pass (the contact pass's, goals())
  std::vector<Eigen::Vector3d> goal_;
  /// per hard-dragged particle: the velocity the sub-step gave it before its drag held it
  /// (countDragImpulse() counts the difference as the drag's impulse)
  std::vector<Eigen::Vector3d> freeVelocity_;
  /// the object's rigid motion at the start of the sub-step, what relative ambient damping
  /// leaves alone (k_.relative)
  RigidMotion rigid_;
};

// v <- v_obj + keep (v - v_obj) + alpha s_i (g - x) / h + h (gravity + f / m) + kd (v_rigid - v);
// x <- x + h v
inline void Solver::ExplicitStep::update(std::size_t i, const Eigen::Vector3d& g, const double* s) {
  Solver& o = o_;
  const Constants& k = k_;
  goal_[i] = g;  // the contact pass bounds its push-out by it
  // (a pinned or hard-dragged particle is left to finishSubstep(), the latter's free velocity
  // kept for its drag's impulse)
  if (o.pinned_[i] != 0) return;
  Eigen::Vector3d a = o.params_.gravity;
  if (k.forced) a += o.forceAccel_[i];
  if (o.volumetric_) a += o.volumetricAccel_[i];
  Eigen::Vector3d dv = k.pull * o.stiffnessFactor_[i] * (g - o.x_[i]) + k.h * a;
  if (o.passDamping_) {
    const Eigen::Vector3d p = o.x_[i] - o.xref_;
    const Eigen::Vector3d target =
        (Eigen::Vector3d(s[12], s[13], s[14]) + Eigen::Vector3d(s[15], s[16], s[17]).cross(p)) * o.invCount_[i];
    dv += k.kd * (target - o.v_[i]);
  }
  Eigen::Vector3d v;
  if (k.relative) {
    // ambient damping of the motion relative to the object's rigid motion (Solver::rigidMotion())
    const Eigen::Vector3d rigid = rigid_.velocity + rigid_.spin.cross(o.x_[i] - o.xref_);
    v = rigid + k.keep * (o.v_[i] - rigid) + dv;
  } else {
    v = (o.v_[i] + dv) * k.keep;  // held by the world: drag towards rest
  }
  if (o.hardDragged_[i] != 0) {
    freeVelocity_[i] = v;
    return;
  }
  o.v_[i] = v;
  o.x_[i] += k.h * v;
}

// The sub-step damped the updated velocity, v = keep (v_n + dv) (a dragged object is held by the
// world), so the drag's impulse is m (v / keep - (v_n + dv)) = m (v - v_free) / keep.
inline void Solver::ExplicitStep::countDragImpulse(Drag& d, std::uint32_t p) const {
  Solver::countDragImpulse(d, o_.x_[p], o_.lattice_->masses()[p] * (o_.v_[p] - freeVelocity_[p]) / k_.keep);
}

}  // namespace deformable_flsm
