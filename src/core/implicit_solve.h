// The implicit step's solve parameters, shared by Solver's sub-step and ImplicitCoupling's
// (several objects as one system). Internal to the core.
#pragma once

#include "deformable_flsm/core/pcg.h"

#include <Eigen/Core>

#include <algorithm>
#include <vector>

namespace deformable_flsm {
namespace implicit_solve {

/// CG stops when the residual's preconditioned norm is this fraction of its initial one (the warm
/// start's): the error is a fraction of what the warm start misses, so that at rest, where it
/// misses nothing, the step stays at rest, and a vibration is not fed by a solve stopped along its
/// last increment carried forward. (Against the whole right-hand side M v_n + h f a cantilever at
/// 30 kPa gained 2 % of amplitude per period, and a resting object kept jittering at ~1e-3 g h.)
/// Chosen by measurement: against 1e-3, the cantilever's first bending frequency, its amplitude
/// decay over seven periods and its settled tip are unchanged within 0.1 % from 30 kPa to 10 MPa
/// for a third fewer iterations (docs/performance.md).
constexpr double kCgTolerance = 1e-2;
/// ... or when it is this fraction of the step's force impulse per particle (the larger of h f(x_n)
/// and the gravity impulse M g h, their norms over sqrt(n), n the free particles): a warm start this
/// good needs no iteration. Per particle rather than of the whole norm, because the residual left
/// may sit on a few particles: within a fraction of the whole norm, one particle's error could be
/// sqrt(n) times the mean, and a 10k lattice's ears kept jittering and never came to rest. So the
/// error left at any one particle is at most ~1e-3 of its gravity impulse g h whatever the lattice
/// size, far below the rest tests' bound (test_solver_implicit_contact).
constexpr double kCgFloor = 1e-3;
/// At most this many CG iterations per sub-step: a bound on the cost of a step, far above the
/// counts measured (docs/performance.md); the step then takes the iterate reached.
constexpr int kCgMaxIterations = 300;
/// The solves after the first one of a sub-step (the contact set changed) stop when the residual
/// is this fraction of the first solve's initial residual (or at kCgTolerance of their own, or the
/// floor). Their own initial residual is that of a few contacts changed, and kCgTolerance of it
/// made each one cost as many iterations as the first solve; kCgTolerance of the first solve's, on
/// the other hand, left a 10 MPa block dropped on the ground rocking between contact sets for
/// good. This fraction was chosen by measurement (docs/performance.md).
constexpr double kCgContactTolerance = 3e-3;
/// Solves per sub-step with contacts: the first, and again after letting go of the contacts that
/// pulled (one-sided contact by an active set, at most this many passes; what remains pulling
/// after the last is released by the next sub-step's prediction).
constexpr int kContactPasses = 4;

/// A free particle joins the contacts when the solution carries it deeper into a collider than
/// this fraction of the contact radius (the contact pass after the solve takes what is less).
/// At the start of a sub-step a particle predicted within it of a surface, outside as well as
/// inside, is a contact: the solve ends a resting contact on the surface, where round-off (and
/// the contact pass's push-out) leaves it a hair outside or inside. Counted only inside, resting
/// contacts fell out of the set every other sub-step, and out of it a contact is held only by the
/// contact pass's friction, at most mu times a normal change of about the slop over h: two pads
/// gripping the bunny lifted it 2 cm of 10, then lost it (test_solver_implicit_contact).
constexpr double kContactSlop = 1e-3;
/// The CG and active-set loop of an implicit sub-step, one object's (Solver) or several objects'
/// as one system (ImplicitCoupling): prepare() (the system's vectors, which a change of the set
/// may change), solve, solved(); then update(guessChanged) changes the active set and returns
/// whether it did, setting guessChanged when it prescribed a velocity (the next solve computes
/// its residual again); at most kContactPasses solves. The solves after the first stop at
/// kCgContactTolerance of the first one's initial residual, or `tolerance` of their own, or
/// `floor`. Returns the last solve's result with the iterations of all of them.
template <class Prepare, class Apply, class Precondition, class Solved, class Update>
PcgResult solveWithContactSet(Pcg& pcg, Prepare&& prepare, Apply&& apply, Precondition&& precondition,
                              const std::vector<PcgConstraint>& constraint, const std::vector<Eigen::Vector3d>& normal,
                              const std::vector<Eigen::Vector3d>& rhs, std::vector<Eigen::Vector3d>& velocity,
                              double floor, double tolerance, Solved&& solved, Update&& update) {
  PcgResult result;
  int iterations = 0;
  double passFloor = floor;
  bool guessChanged = true;
  for (int pass = 0;; ++pass) {
    prepare();
    result = pcg.solveWith(apply, precondition, constraint, normal, rhs, velocity, passFloor, tolerance,
                           kCgMaxIterations, !guessChanged);
    iterations += result.iterations;
    if (pass == 0) passFloor = std::max(floor, kCgContactTolerance * result.initialResidual);
    solved();
    if (pass + 1 >= kContactPasses) break;
    guessChanged = false;
    if (!update(guessChanged)) break;
  }
  result.iterations = iterations;
  return result;
}

/// The contact states kept from one sub-step to the next (Solver::ImplicitStep::contactState_).
constexpr char kNoContact = 0, kSticking = 1, kSliding = 2, kReleased = 3;

}  // namespace implicit_solve
}  // namespace deformable_flsm
