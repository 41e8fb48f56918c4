// The implicit sub-step's contact set: which particles the solve holds on a collider's surface
// (sticking, or sliding with kinetic friction), updated between the solves of a sub-step as an
// active set, and the impulses the set carried, summed as the colliders' wrenches. See
// docs/method.md, "The implicit step"; the solve itself is in solver_implicit.cpp.
#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/solver.h"
#include "implicit_solve.h"
#include "implicit_step.h"

#include <algorithm>
#include <cmath>
#include <limits>

namespace deformable_flsm {

using namespace implicit_solve;

namespace {

/// A sliding contact's kinetic friction is set again to mu_k times the pass's normal impulse when
/// they differ by more than this fraction (another pass for less would cost more than it gives).
constexpr double kFrictionChange = 0.02;

}  // namespace

// Contact inside the solve. A particle that its velocity with gravity's increment, v* = v_n + h g,
// would carry into a collider or onto it, x_n + h v* at depth phi - r below the slop
// (kContactSlop), is constrained: its normal
// velocity to the one that undoes the penetration the sub-step's own motion makes,
// v.n = v*.n + (min(phi_0 - r, 0) - (phi - r)) / h with phi_0 - r its depth at the start of the
// sub-step (the contact pass's normal response, contactVelocityChange() in contact.h: one that
// came from outside ends on the surface, one already inside goes no deeper and is moved out by
// position only, at most r per sub-step, by the contact pass after the solve; a start
// penetration becomes no velocity), and, sticking, its tangential velocity to the collider
// surface's. (v* rather than the warm start: a resting object's warm start already
// holds the support and would predict no contact.) The impact then decelerates the whole object
// through its stiffness within the step, instead of stopping the touching layer alone and leaving
// the rest to crush it: the contact pass after an unconstrained solve, at a long step, flattens
// the layers that travel more than a cell into the collider, and shape matching may not undo it.
// Friction is in the solve too: a sticking contact whose tangential velocity were corrected after
// the solve would leave the rest of the object moving as if it slid, and feed energy into it.
bool Solver::ImplicitStep::constrainContacts(double h) {
  if (o_.contactBodies_.empty()) return false;
  const double r = o_.contactRadius();
  const double slop = kContactSlop * r;
  // below this slip speed a contact's slip direction is noise: what gravity adds in a sub-step
  // (on a slope, along the surface), or the contact slop over a sub-step without gravity
  const double slipFloor = std::max(h * o_.params_.gravity.norm(), slop / h);
  bool any = false;
  for (std::size_t i = 0; i < o_.x_.size(); ++i) {
    if (o_.pinned_[i] != 0 || o_.hardDragged_[i] != 0) continue;
    const Eigen::Vector3d predicted = o_.v_[i] + h * o_.params_.gravity;
    const Eigen::Vector3d x = o_.x_[i] + h * predicted;
    Eigen::Vector3d normal, vc;
    double depth = 0.0;
    const int b = deepestContact(x, slop, normal, depth, vc);
    const Eigen::Vector3d slid = friction_[i];  // its kinetic friction, if it slid
    friction_[i].setZero();
    const char last = contactState_[i];
    contactState_[i] = b < 0 ? kNoContact : kSticking;
    if (b < 0) continue;
    // a contact let go of last sub-step (it pulled) starts free while it is still predicted in
    // contact: the solve adds it back if the solution carries it into the collider
    if (last == kReleased) {
      contactState_[i] = kReleased;
      continue;
    }
    const double undo = (std::min(startDepth(i, b), 0.0) - depth) / h;
    // its predicted slip along the surface and speed into it
    const Eigen::Vector3d rel = predicted - vc;
    const double into = -rel.dot(normal);
    const Eigen::Vector3d slip = rel + into * normal;
    const double slipSpeed = slip.norm();
    // a contact that ended the last sub-step sliding goes on sliding, under the kinetic friction
    // it had (in this normal's tangent plane), until the solve finds its slip reversed: started
    // sticking, a sliding object's contacts took its whole momentum in the first solve and only
    // some of them left the cone per pass, and those left sticking after the last pass held it.
    // Its friction turns against the slip it now has when that is faster than slipFloor (slower,
    // a grasp's contacts keep the direction that held): kept along the slip it joined with, a
    // block spun at 20 rad/s on a plane with mu 0.1 stopped at 0.4 s, where Coulomb's friction
    // takes 0.7 s (test_solver_implicit_contact).
    //
    // A contact that did not stick in the last sub-step and slips faster than its own approach
    // could stop within the cone (|slip| > mu_s times its speed into the surface, and > slipFloor:
    // a pad squeezing an object from the side sees gravity's h g as slip) starts sliding
    // too, its kinetic friction set by the first solve's normal impulse (updateContactSet()):
    // started sticking, the contacts of a block landing while it slid took its whole tangential
    // momentum in the first solve, and those the passes had not let slide when they ran out held
    // it (a block launched at 3 m/s along the ground took 1.08 mu_k times its normal impulse)
    const bool carried = last == kSliding && !slid.isZero(0.0);
    if (carried || (last != kSticking && slipSpeed > slipFloor &&
                    slipSpeed > o_.posed(static_cast<std::size_t>(b)).collider->staticFriction * std::max(0.0, into))) {
      if (carried) {
        friction_[i] = slid - slid.dot(normal) * normal;
        if (slipSpeed > slipFloor)
          friction_[i] = -(friction_[i].norm() / slipSpeed) * slip;
        rhs_[i] += friction_[i];
      }
      velocity_[i] += (predicted.dot(normal) + undo - velocity_[i].dot(normal)) * normal;
      constraint_[i] = PcgConstraint::Normal;
      normal_[i] = normal;
      contactBody_[i] = b;
      contactState_[i] = kSliding;
      any = true;
      continue;
    }
    // every other contact starts sticking (the solve then says whether its impulse stays in the
    // cone): at rest the set holds from step to step
    velocity_[i] = vc + (predicted.dot(normal) + undo - vc.dot(normal)) * normal;
    constraint_[i] = PcgConstraint::Fixed;
    normal_[i] = normal;
    contactBody_[i] = b;
    any = true;
  }
  return any;
}

double Solver::ImplicitStep::startDepth(std::size_t i, int b) const {
  Eigen::Vector3d normal;
  // BDF2 solves from its extrapolated start x_: the sub-step starts at x_n (a landing particle's
  // extrapolation into the collider is not a penetration to keep)
  const Eigen::Vector3d& x = bdf2Step_ ? bdf2LastX_[i] : o_.x_[i];
  return o_.posed(static_cast<std::size_t>(b)).startGap(x, o_.contactRadius(), normal);
}

int Solver::ImplicitStep::deepestContact(const Eigen::Vector3d& x, double within, Eigen::Vector3d& normal, double& depth,
                           Eigen::Vector3d& colliderVelocity) const {
  const double r = o_.contactRadius();
  const double reach = r + kContactSlop * r;  // bounds that miss x by more miss the contact
  int deepest = -1;
  depth = within;
  for (std::size_t b = 0; b < o_.contactBodies_.size(); ++b) {
    const PosedCollider& body = o_.posed(b);
    if (!body.near(x, reach)) continue;
    Eigen::Vector3d n;
    const double d = body.gap(x, r, n);
    if (!(d < depth)) continue;
    deepest = static_cast<int>(b);
    depth = d;
    normal = n;
    colliderVelocity = body.surfaceVelocity(x);
  }
  return deepest;
}

// A free particle the solution carries deeper than the slop into a collider joins the contact set:
// sticking, or sliding if it was let go of and comes back slipping. Returns whether it joined.
bool Solver::ImplicitStep::joinContact(std::size_t i, double h, double slop) {
  Eigen::Vector3d normal, vc;
  double depth = 0.0;
  const int b = deepestContact(o_.x_[i] + h * velocity_[i], 0.0, normal, depth, vc);
  if (b < 0 || depth > -slop) return false;
  const Eigen::Vector3d v = velocity_[i];
  const double undo = (std::min(startDepth(i, b), 0.0) - depth) / h;
  const Eigen::Vector3d rel = v - vc;
  normal_[i] = normal;
  contactBody_[i] = b;
  if (contactState_[i] != kReleased || (rel - rel.dot(normal) * normal).isZero(0.0)) {
    velocity_[i] = vc + (v.dot(normal) + undo - vc.dot(normal)) * normal;
    constraint_[i] = PcgConstraint::Fixed;
    contactState_[i] = kSticking;
  } else {
    // a contact let go of (it pulled) that comes back slipping joins sliding, its kinetic
    // friction set by the next pass: added sticking, the uphill edge of a block sliding down
    // a slope came back into the plane, held the block, pulled, was let go, ... every pass
    velocity_[i] = v + undo * normal;
    constraint_[i] = PcgConstraint::Normal;
    contactState_[i] = kSliding;
  }
  return true;
}

// The active set after a solve, from the constraint impulse on each contact particle, what its
// equation lacks: J = (A v+ - b)_i, the solve's residual with the sign turned. A contact with
// J.n < 0 pulls the particle towards the collider: let go. A sticking contact with |J_t| > mu_s J.n
// leaves Coulomb's cone: it slides (normal velocity kept, tangential free) under kinetic friction
// mu_k J.n along J_t, a force of the next solve: the slip it allows moves the whole object, which
// relaxes the shear that pushed the contact out of the cone. A sliding contact whose slip the
// friction turned backwards (slip along the friction force) has stopped: it sticks again. (Friction
// applied to the contact particles after the solve, instead, left the object's shear in place and
// the contacts sliding at rest for as long as they touched: the object never came to rest after a
// drag.) A sliding contact's kinetic friction follows each pass's normal impulse. A free particle
// that the solution carries into a collider (deeper than kContactSlop) becomes a sticking contact,
// or a sliding one if it was let go of in this sub-step and comes back slipping. Returns whether
// the set changed.
bool Solver::ImplicitStep::updateContactSet(double h, bool& guessChanged, Pcg& pcg, std::size_t offset) {
  if (o_.contactBodies_.empty()) return false;
  const std::vector<Eigen::Vector3d>& residual = pcg.residual();
  // a friction force of the solve: the right-hand side and the residual PCG keeps change together
  const auto addFriction = [this, &pcg, offset](std::size_t i, const Eigen::Vector3d& f) {
    rhs_[i] += f;
    pcg.addToResidual(offset + i, f);
  };
  const double slop = kContactSlop * o_.contactRadius();
  bool changed = false;
  for (std::size_t i = 0; i < o_.x_.size(); ++i) {
    if (o_.pinned_[i] != 0 || o_.hardDragged_[i] != 0) continue;
    if (contactBody_[i] < 0) {
      if (joinContact(i, h, slop)) changed = guessChanged = true;
      continue;
    }
    const PosedCollider& body = o_.posed(static_cast<std::size_t>(contactBody_[i]));
    const Collider& c = *body.collider;
    const Eigen::Vector3d J = -residual[offset + i];
    const double Jn = J.dot(normal_[i]);
    const Eigen::Vector3d& n = normal_[i];
    if (Jn < 0.0) {
      addFriction(i, -friction_[i]);
      friction_[i].setZero();
      constraint_[i] = PcgConstraint::Free;
      contactBody_[i] = -1;
      contactState_[i] = kReleased;
      changed = true;
    } else if (constraint_[i] == PcgConstraint::Fixed) {
      const Eigen::Vector3d Jt = J - Jn * n;
      const double t = Jt.norm();
      if (t > c.staticFriction * Jn) {
        // out of the cone: slide, with kinetic friction mu_k J.n along the impulse that held it
        // (against the slip it resisted) as a force of the solve, so that the rest of the object
        // moves with the slip
        friction_[i] = (c.kineticFriction * Jn / t) * Jt;
        addFriction(i, friction_[i]);
        constraint_[i] = PcgConstraint::Normal;
        contactState_[i] = kSliding;
        changed = true;
      }
    } else {
      const Eigen::Vector3d vc = body.surfaceVelocity(o_.x_[i] + h * velocity_[i]);
      const Eigen::Vector3d rel = velocity_[i] - vc;
      const Eigen::Vector3d slip = rel - rel.dot(n) * n;
      const double f = friction_[i].norm(), kinetic = c.kineticFriction * Jn;
      if (f == 0.0) {
        // joined sliding in this sub-step: kinetic friction against its slip from now on
        const double s = slip.norm();
        if (s > 0.0 && kinetic > 0.0) {
          friction_[i] = -(kinetic / s) * slip;
          addFriction(i, friction_[i]);
          changed = true;
        }
        continue;
      }
      // sliding: friction that carried the particle backwards (its slip along the friction
      // force) means it stops: it sticks
      if (slip.dot(friction_[i]) > 0.0) {
        addFriction(i, -friction_[i]);
        friction_[i].setZero();
        velocity_[i] = vc + (velocity_[i] - vc).dot(n) * n;
        constraint_[i] = PcgConstraint::Fixed;
        contactState_[i] = kSticking;
        changed = true;
        guessChanged = true;
      } else if (std::abs(kinetic - f) > kFrictionChange * f) {
        // still sliding: kinetic friction mu_k J.n with this pass's normal impulse (the one it
        // was set with, the sticking solve's, held a sliding object's momentum too)
        const Eigen::Vector3d df = (kinetic / f - 1.0) * friction_[i];
        addFriction(i, df);
        friction_[i] += df;
        changed = true;
      }
    }
  }
  return changed;
}

// After the last solve: the impulses of every contact go to its collider's wrench, as the contact
// pass's do.
void Solver::ImplicitStep::sumContactImpulses(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset) {
  const double r = o_.contactRadius();
  // BDF2's solve of 2/3 of the sub-step takes 2/3 of its impulses (its momentum balance is
  // P+ = (4 P_n - P_{n-1}) / 3 + (2h/3) (F + contact)): the sub-step's impulse is 3/2 of it
  const double perSubstep = bdf2Step_ ? o_.params_.substepLength() / h : 1.0;
  for (std::size_t i = 0; i < o_.x_.size(); ++i) {
    if (contactBody_[i] < 0) continue;
    const std::size_t b = static_cast<std::size_t>(contactBody_[i]);
    ContactBody& body = o_.contactBodies_[b];
    const Eigen::Vector3d& n = normal_[i];
    const Eigen::Isometry3d& pose = o_.posed(b).now;
    Eigen::Vector3d J = -residual[offset + i];
    // a sliding contact's impulse: the normal one and the kinetic friction the solve applied
    if (constraint_[i] == PcgConstraint::Normal) J = std::max(0.0, J.dot(n)) * n + friction_[i];
    J *= perSubstep;
    const Eigen::Vector3d x = o_.x_[i] + h * velocity_[i];
    body.impulse += J;
    body.moment += (x - r * n - pose.translation()).cross(J);
    record(body, i, J, x - r * n);
    // a contact whose normal impulse pushes (one the solve let go of does not)
    if ((-residual[offset + i]).dot(n) > 0.0) o_.tally_.touch(i, b);
  }
}

}  // namespace deformable_flsm
