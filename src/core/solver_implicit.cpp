// The implicit sub-step: linearly implicit backward Euler on FastLSM's shape-matching energy with
// the co-rotated region stiffness (one Newton step per sub-step), solved by preconditioned
// conjugate gradients. See docs/method.md, "The implicit step".
//
// Backward Euler, linearised about the state at the start of the sub-step (Baraff & Witkin 1998):
//   (M + h C + h^2 K) dv = h (f(x_n, v_n) - h K v_n),   v+ = v_n + dv,   x+ = x_n + h v+
// which, with f = f_el(x_n) - C v_n, is the same as solving for v+ directly:
//   A v+ = M v_n + h f_el(x_n),   A = M + h C + h^2 K.
// - f_el: shape matching k m~_i sum_r beta_r (T_r x0_i - x_i) = k m_i s_i (g_i - x_i) (g_i the
//   beta-weighted goal of the ordinary region pass, k = alpha / h^2 with alpha as requested, no
//   cap), gravity, timed forces, spring drags, the Poisson term;
// - K: the co-rotated region stiffness k sum_r beta_r K_r (CorotatedHessian, the rotations R_r of
//   the region pass at x_n), the Gauss-Newton Hessian of the Poisson term, and the spring drags'
//   stiffness (diagonal);
// - C: region damping, damping * sum_r K_r (the explicit step's pull of every particle towards
//   its regions' rigid velocity fits, as a matrix), and ambient damping c M, relative to the
//   object's rigid motion v_obj when free (right-hand side + h c M (v_obj + h g)) or to rest when
//   the world holds the object.
// Pinned and hard-dragged particles have their velocity prescribed: their rows and columns leave
// the system (filtered CG). Contact is split off: the contact pass runs after the velocity solve,
// as in the explicit step. Free of pins, drags and colliders, the step keeps the linear and
// angular momentum the external forces give exactly: K annihilates translations but not the
// rotation of a deformed region about its deformed centre, and CG stops at a residual, so the
// six rigid modes of the solution are corrected (correctRigidModes()).
#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/solver.h"
#include "implicit_solve.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>

namespace deformable_flsm {

using namespace implicit_solve;

namespace {

/// Largest volumetric strain the Poisson term acts on (as computeVolumetricForces()): beyond it
/// the force is constant, so its Hessian is zero.
constexpr double kMaxVolumetricStrain = 0.5;
/// A free particle joins the contacts when the solution carries it deeper into a collider than
/// this fraction of the contact radius (the contact pass after the solve takes what is less).
/// At the start of a sub-step a particle predicted within it of a surface, outside as well as
/// inside, is a contact: the solve ends a resting contact on the surface, where round-off (and
/// the contact pass's push-out) leaves it a hair outside or inside. Counted only inside, resting
/// contacts fell out of the set every other sub-step, and out of it a contact is held only by the
/// contact pass's friction, at most mu times a normal change of about the slop over h: two pads
/// gripping the bunny lifted it 2 cm of 10, then lost it (test_solver_implicit).
constexpr double kContactSlop = 1e-3;
/// A sliding contact's kinetic friction is set again to mu_k times the pass's normal impulse when
/// they differ by more than this fraction (another pass for less would cost more than it gives).
constexpr double kFrictionChange = 0.02;
/// The contact states kept from one sub-step to the next (implicitContactState_).
constexpr char kNoContact = 0, kSticking = 1, kSliding = 2, kReleased = 3;
/// At most this many aggregates in the preconditioner's coarse space (6 unknowns each, a dense
/// Cholesky factorisation per sub-step): docs/performance.md gives the iterations and the cost.
constexpr int kCoarseAggregates = 64;
/// The coarse matrix is assembled and factorised again once an aggregate has turned by this angle
/// (rad) since the last assembly, or after kCoarseAge sub-steps (the Poisson term's stretch),
/// or when the diagonal or the coefficients change (TwoLevelPreconditioner::needsAssembly()):
/// an older factorisation is still a valid preconditioner, and these bounds cost few iterations
/// (docs/performance.md).
constexpr double kCoarseTurn = 0.05;
constexpr int kCoarseAge = 30;
/// BDF2 steps the object while no particle's offset from its goal (goal - x, the elastic force
/// it feels) changed by more than this (in cells) over the last sub-step; beyond, far from the
/// slow, near-linear motion where its second order pays (a crushed or scrambled object, a hard
/// drag's jerk, a landing), the sub-step is backward Euler's, which recovers from any start
/// (docs/method.md). A steady load (an object standing under its weight) changes nothing.
constexpr double kBdf2MaxGoalGapChange = 0.1;
/// Inertia eigenvalues below this fraction of the largest are treated as zero (a collinear object
/// cannot spin about its own line).
constexpr double kInertiaRankTolerance = 1e-10;

}  // namespace

void Solver::configureIntegrator() {
  if (params_.integrator != Integrator::Implicit) return;
  // No stability cap: alpha (and with it k = alpha / h^2, independent of h) as requested. The
  // Poisson term was scaled by alpha / requested with the cap; undo that.
  const double requested = params_.requestedAlpha(lattice_->spacing());
  if (volumetric_ && alpha_ > 0.0) {
    const double scale = requested / alpha_;
    for (VolumetricStencil& st : stencil_) {
      st.weight *= scale;
      for (double& d : st.deficit) d *= scale;
    }
  }
  alpha_ = requested;
  alphaCap_ = requested;
  const std::size_t n = lattice_->size();
  if (!hessian_)
    hessian_ = std::make_unique<CorotatedHessian>(*summer_, lattice_->regionMassFractions(), restCentered_,
                                                  regionMass_, regionRestCenter_);
  if (!coarse_)
    coarse_ = std::make_unique<TwoLevelPreconditioner>(*lattice_, lattice_->regionMassFractions(), restCentered_,
                                                       regionMass_, regionRestCenter_, kCoarseAggregates);
  // the region moments of the coarse space, gathered here rather than in the first step (the
  // constructor sizes the pins after this)
  if (pinned_.size() == n) coarse_->setFixed(*summer_, pinned_, hardDragged_);
  weightSum_.resize(n);
  for (std::size_t i = 0; i < n; ++i) weightSum_[i] = 1.0 / invWeightSum_[i];
  if (implicitVelocity_.size() != n) {
    pcg_.resize(n);
    implicitGoal_.assign(n, Eigen::Vector3d::Zero());
    implicitRhs_.assign(n, Eigen::Vector3d::Zero());
    implicitVelocity_.assign(n, Eigen::Vector3d::Zero());
    implicitDiagonal_.assign(n, Eigen::Vector3d::Zero());
    implicitInvPrecond_.assign(n, Eigen::Vector3d::Zero());
    implicitLastDv_.assign(n, Eigen::Vector3d::Zero());
    implicitConstraint_.assign(n, PcgConstraint::Free);
    implicitNormal_.assign(n, Eigen::Vector3d::Zero());
    implicitContactBody_.assign(n, -1);
    implicitContactState_.assign(n, kNoContact);
    implicitFriction_.assign(n, Eigen::Vector3d::Zero());
  }
  volumetricLinear_.resize(volumetric_ ? n : 0);
  const bool bdf2 = params_.implicitScheme == ImplicitScheme::Bdf2;
  bdf2LastX_.resize(bdf2 ? n : 0);
  bdf2LastV_.resize(bdf2 ? n : 0);
  bdf2LastGap_.assign(bdf2 ? n : 0, Eigen::Vector3d::Zero());
  bdf2GapChange_ = std::numeric_limits<double>::infinity();  // no last sub-step to compare with
  bdf2Ready_ = false;  // a new step length or scheme: start again with backward Euler
  bdf2Step_ = false;
}

void Solver::implicitSubstep(double substep) {
  const bool bdf2 = params_.implicitScheme == ImplicitScheme::Bdf2;
  // the backward Euler step solved: the sub-step itself, or BDF2's 2/3 of it from its start
  bdf2Step_ = false;
  const double h = bdf2 ? bdf2Begin(substep) : substep;
  implicitBegin(h);
  const bool contacts = !contactBodies_.empty();
  // Contacts by an active set (see constrainContacts()): solve, let go of the contacts whose
  // impulse pulls, turn the sticking ones whose impulse leaves the friction cone into sliding
  // ones, and solve again from where it was.
  const auto product = [this](const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
    implicitProduct(p, y);
  };
  const auto precondition = [this](const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
    coarse_->apply(implicitInvPrecond_, r, z);
  };
  int iterations = 0;
  double passFloor = implicitFloor_;
  bool guessChanged = true;
  for (int pass = 0;; ++pass) {
    implicitSolve_ = pcg_.solveWith(product, precondition, implicitConstraint_, implicitNormal_, implicitRhs_,
                                    implicitVelocity_, passFloor, kCgTolerance, kCgMaxIterations, !guessChanged);
    iterations += implicitSolve_.iterations;
    if (pass == 0) passFloor = std::max(implicitFloor_, kCgContactTolerance * implicitSolve_.initialResidual);
    guessChanged = false;
    if (!contacts || pass + 1 >= kContactPasses || !updateContactSet(h, guessChanged, pcg_, 0)) break;
  }
  implicitSolve_.iterations = iterations;
  implicitEnd(h, pcg_.residual(), 0, substep);
  if (bdf2) bdf2End(substep);
}

double Solver::bdf2Begin(double h) {
  const std::size_t n = x_.size();
  if (impulsePending_) {
    // an impulse changes v_n and, for the extrapolation, v_{n-1} alike
    for (std::size_t i = 0; i < n; ++i) {
      v_[i] += impulseDv_[i];
      if (bdf2Ready_) bdf2LastV_[i] += impulseDv_[i];
    }
    std::fill(impulseDv_.begin(), impulseDv_.end(), Eigen::Vector3d::Zero());
    impulsePending_ = false;
  }
  if (!bdf2Ready_ || bdf2GapChange_ > kBdf2MaxGoalGapChange) {
    bdf2LastX_ = x_;  // same size: no allocation
    bdf2LastV_ = v_;
    bdf2Ready_ = true;
    return h;
  }
  // the momenta BDF2's solve must keep (correctRigidModes()): a linear multistep method keeps
  // the linear one by itself, not the spin
  const auto& m = lattice_->masses();
  double M = 0.0;
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), L = Eigen::Vector3d::Zero();
  bdf2P_.setZero();
  for (std::size_t i = 0; i < n; ++i) {
    M += m[i];
    mx += m[i] * (x_[i] - x_[0]);
    bdf2P_ += m[i] * v_[i];
    L += m[i] * (x_[i] - x_[0]).cross(v_[i]);
  }
  bdf2Spin_ = L - (mx / M).cross(bdf2P_);  // about the centre of mass
  bdf2Step_ = true;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = x_[i], v = v_[i];
    x_[i] = x + (x - bdf2LastX_[i]) / 3.0;
    v_[i] = v + (v - bdf2LastV_[i]) / 3.0;
    bdf2LastX_[i] = x;
    bdf2LastV_[i] = v;
  }
  return 2.0 * h / 3.0;
}

void Solver::bdf2End(double h) {
  const std::size_t n = x_.size();
  for (std::size_t i = 0; i < n; ++i) {
    // implicitVelocity_ holds the solve's v+: the contact pass after it, a pin or a hard drag
    // changed v_ since
    const bool moved = pinned_[i] != 0 || hardDragged_[i] != 0 || implicitContactState_[i] != kNoContact ||
                       v_[i] != implicitVelocity_[i];
    if (!moved) continue;
    bdf2LastX_[i] = x_[i] - h * v_[i];
    bdf2LastV_[i] = v_[i];
  }
}

void Solver::implicitBegin(double h) {
  const std::size_t n = x_.size();
  const auto& m = lattice_->masses();
  implicitH_ = h;
  if (impulsePending_) {
    for (std::size_t i = 0; i < n; ++i) v_[i] += impulseDv_[i];
    std::fill(impulseDv_.begin(), impulseDv_.end(), Eigen::Vector3d::Zero());
    impulsePending_ = false;
  }
  // a timed force's last sub-step is cut by the time the sub-step advances (BDF2 solves 2/3 of it)
  accumulateForces(bdf2Step_ ? params_.substepLength() : h);
  // The linearisation point: one ordinary region pass gives the goals and the rotations R_r.
  computeGoals(implicitGoal_);
  if (volumetric_) {
    computeVolumetricForces();
    // The Poisson term linearised at x_n: E_i = w/2 e^2 + sum_a D_a/2 e_aa^2 has the Hessian
    //   w grad e grad e^T + sum_a D_a grad e_aa grad e_aa^T + sum_a sigma_a hess e_aa,
    // grad e_aa = +-F_a / d_a at the ends of axis a, sigma_a = w e + D_a e_aa the stress along a,
    // hess e_aa = [1 -1; -1 1] / d_a^2 (x) 1. The last term is kept where it is positive (a
    // stretched stencil: without it the force, linear in F, would be explicit and unstable) and
    // dropped where negative (compression: Gauss-Newton), so the matrix stays positive
    // semi-definite. Where the strain is clamped the force is sigma F / d with sigma constant:
    // only the last term remains.
    for (std::size_t i = 0; i < n; ++i) {
      const VolumetricStencil& st = stencil_[i];
      VolumetricLinearisation& lin = volumetricLinear_[i];
      double e = 0.0, eaa[3] = {0.0, 0.0, 0.0};
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector3d F = (x_[st.plus[a]] - x_[st.minus[a]]) * st.invDistance[a];
        if (st.invDistance[a] > 0.0) eaa[a] = 0.5 * (F.squaredNorm() - 1.0);
        e += eaa[a];
        lin.gradient[a] = F * st.invDistance[a];
      }
      lin.weight = std::abs(e) < kMaxVolumetricStrain ? st.weight : 0.0;
      const double ec = std::clamp(e, -kMaxVolumetricStrain, kMaxVolumetricStrain);
      for (int a = 0; a < 3; ++a) {
        lin.deficit[a] = std::abs(eaa[a]) < kMaxVolumetricStrain ? st.deficit[a] : 0.0;
        const double ea = std::clamp(eaa[a], -kMaxVolumetricStrain, kMaxVolumetricStrain);
        lin.stretch[a] = std::max(0.0, st.weight * ec + st.deficit[a] * ea) * st.invDistance[a] * st.invDistance[a];
      }
    }
  }
  const bool relative = params_.ambientDamping > 0.0 && !heldByWorld();
  if (relative) computeRigidMotion();

  // The system: A = diag(M (1 + h c [a free object]) + h^2 k_spring) + sum_r (h^2 k beta_r + h damping) K_r
  // (+ h^2 H_vol), h^2 k = alpha.
  hessian_->setRotations(rotations_);
  // alpha = h^2 k for the sub-step; a shorter solve (BDF2's 2/3 of it) keeps k
  const double substep = params_.substepLength();
  const double alpha = h == substep ? alpha_ : alpha_ * (h / substep) * (h / substep);
  hessian_->setCoefficients(alpha, h * params_.damping, regionWeight_, weightSum_, invCount_);
  const double c = params_.ambientDamping;
  // Ambient damping relative to the object's rigid motion (a free object) is in the system; an
  // object held by the world is damped as the explicit step damps it, v_n by exp(-c h) before
  // the step: in the system it would damp the sub-step's fall onto a support the solve does not
  // see (another object, whose contact comes after the solve), which then carried 1 / (1 + h c)
  // of the weight above it.
  const double damped = relative ? 1.0 + h * c : 1.0;
  const double keep = relative ? 1.0 : std::exp(-c * h);
  for (std::size_t i = 0; i < n; ++i) implicitDiagonal_[i].setConstant(m[i] * damped);
  for (const auto& entry : drags_) {
    const Drag& drag = entry.second;
    const Eigen::Isometry3d& frame = drag.frame;
    double M = 0.0;
    for (std::uint32_t p : drag.particles) M += m[p];
    for (std::size_t e = 0; e < drag.particles.size(); ++e) {
      const std::uint32_t p = drag.particles[e];
      if (drag.stiffness > 0.0)
        implicitDiagonal_[p].array() += h * h * drag.stiffness * m[p] / M;
      else if (pinned_[p] == 0)
        implicitVelocity_[p] = (frame * drag.offsets[e] - x_[p]) / h;  // reaches the target
    }
  }
  // Right-hand side M v_n + h f_el(x_n), the initial guess and the Jacobi preconditioner.
  const double pull = alpha / h;  // h k
  double rhsNorm = 0.0, gravityNorm = 0.0, goalGap2 = 0.0;
  const bool bdf2 = params_.implicitScheme == ImplicitScheme::Bdf2 && bdf2LastGap_.size() == n;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3d a = params_.gravity;
    if (!forcedParticles_.empty()) a += forceAccel_[i];
    if (volumetric_) a += volumetricAccel_[i];
    Eigen::Vector3d b = m[i] * (keep * v_[i] + h * a + pull * stiffnessFactor_[i] * (implicitGoal_[i] - x_[i]));
    if (bdf2) {
      const Eigen::Vector3d gap = implicitGoal_[i] - x_[i];
      goalGap2 = std::max(goalGap2, (gap - bdf2LastGap_[i]).squaredNorm());
      bdf2LastGap_[i] = gap;
    }
    // relative ambient damping pulls towards the object's rigid motion as gravity carries it
    // over the sub-step (as the explicit step damps before adding gravity): free fall is exact
    if (relative) b += (h * c * m[i]) * (rigidVelocity_ + rigidSpin_.cross(x_[i] - xref_) + h * params_.gravity);
    implicitRhs_[i] = b;
    implicitInvPrecond_[i] = (implicitDiagonal_[i].array() + hessian_->diagonalBound(i)).inverse();
    implicitConstraint_[i] = (pinned_[i] != 0 || hardDragged_[i] != 0) ? PcgConstraint::Fixed : PcgConstraint::Free;
    implicitContactBody_[i] = -1;
    if (pinned_[i] != 0)
      implicitVelocity_[i].setZero();
    else if (hardDragged_[i] == 0)
      implicitVelocity_[i] = v_[i] + implicitLastDv_[i] + h * params_.gravity;
  }
  if (volumetric_) {
    // the Gauss-Newton Hessian's diagonal, for the preconditioner only
    for (std::size_t i = 0; i < n; ++i) {
      const VolumetricStencil& st = stencil_[i];
      const VolumetricLinearisation& lin = volumetricLinear_[i];
      for (int a = 0; a < 3; ++a) {
        const Eigen::Vector3d d = (h * h * (lin.weight + lin.deficit[a])) * lin.gradient[a].cwiseAbs2() +
                                  Eigen::Vector3d::Constant(h * h * lin.stretch[a]);
        implicitInvPrecond_[st.plus[a]] = (implicitInvPrecond_[st.plus[a]].cwiseInverse() + d).cwiseInverse();
        implicitInvPrecond_[st.minus[a]] = (implicitInvPrecond_[st.minus[a]].cwiseInverse() + d).cwiseInverse();
      }
    }
  }
  constrainContacts(h);
  assembleCoarse(h);
  std::size_t free = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (pinned_[i] != 0 || hardDragged_[i] != 0) continue;
    ++free;
    const Eigen::Vector3d impulse = implicitRhs_[i] - m[i] * v_[i];  // h f(x_n)
    rhsNorm += impulse.dot(implicitInvPrecond_[i].cwiseProduct(impulse));
    const Eigen::Vector3d g = (m[i] * h) * params_.gravity;
    gravityNorm += g.dot(implicitInvPrecond_[i].cwiseProduct(g));
  }
  implicitFreeCount_ = free;
  bdf2GapChange_ = std::sqrt(goalGap2) / lattice_->spacing();
  implicitRhsNorm2_ = rhsNorm;
  implicitGravityNorm2_ = gravityNorm;
  implicitFloor_ = kCgFloor * std::max({std::sqrt(rhsNorm), std::sqrt(gravityNorm), 1e-300}) /
                   std::sqrt(static_cast<double>(std::max<std::size_t>(free, 1)));
}

void Solver::implicitEnd(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset,
                         double elapsed) {
  const std::size_t n = x_.size();
  if (!contactBodies_.empty()) sumContactImpulses(h, residual, offset);
  if (!heldByWorld()) correctRigidModes(h);

  // v+ and x+ = x_n + h v+ for the free particles; the pinned and hard-dragged ones are
  // finishSubstep()'s, as in the explicit step.
  for (std::size_t i = 0; i < n; ++i) {
    if (pinned_[i] != 0 || hardDragged_[i] != 0) continue;
    implicitLastDv_[i] = implicitVelocity_[i] - v_[i] - h * params_.gravity;
    v_[i] = implicitVelocity_[i];
    x_[i] += h * v_[i];
  }
  endSubstep(h, elapsed > 0.0 ? elapsed : h);
}

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
bool Solver::constrainContacts(double h) {
  if (contactBodies_.empty()) return false;
  // the colliders move over the time the sub-step advances (BDF2 solves 2/3 of it)
  const double elapsed = bdf2Step_ ? params_.substepLength() : h;
  const double r = contactRadius();
  const double slop = kContactSlop * r;
  // below this slip speed a contact's slip direction is noise: what gravity adds in a sub-step
  // (on a slope, along the surface), or the contact slop over a sub-step without gravity
  const double slipFloor = std::max(h * params_.gravity.norm(), slop / h);
  // every collider where the contact pass will see it at the end of this sub-step (the contact
  // pass sets the same pose and bounds again)
  for (ContactBody& body : contactBodies_) {
    const Collider& c = *body.collider;
    body.before = advancePose(body.start, c.linearVelocity, c.angularVelocity, contactTime_);
    body.now = advancePose(body.start, c.linearVelocity, c.angularVelocity, contactTime_ + elapsed);
    body.bounded = colliderBounds(c.shape, body.now, body.lo, body.hi);
    if (body.bounded) {
      body.lo.array() -= r + slop;
      body.hi.array() += r + slop;
    }
  }
  bool any = false;
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (pinned_[i] != 0 || hardDragged_[i] != 0) continue;
    const Eigen::Vector3d predicted = v_[i] + h * params_.gravity;
    const Eigen::Vector3d x = x_[i] + h * predicted;
    Eigen::Vector3d normal, vc;
    double depth = 0.0;
    const int b = deepestContact(x, slop, normal, depth, vc);
    const Eigen::Vector3d slid = implicitFriction_[i];  // its kinetic friction, if it slid
    implicitFriction_[i].setZero();
    const char last = implicitContactState_[i];
    implicitContactState_[i] = b < 0 ? kNoContact : kSticking;
    if (b < 0) continue;
    // a contact let go of last sub-step (it pulled) starts free while it is still predicted in
    // contact: the solve adds it back if the solution carries it into the collider
    if (last == kReleased) {
      implicitContactState_[i] = kReleased;
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
    // takes 0.7 s (test_solver_implicit).
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
                    slipSpeed > contactBodies_[static_cast<std::size_t>(b)].collider->staticFriction * std::max(0.0, into))) {
      if (carried) {
        implicitFriction_[i] = slid - slid.dot(normal) * normal;
        if (slipSpeed > slipFloor)
          implicitFriction_[i] = -(implicitFriction_[i].norm() / slipSpeed) * slip;
        implicitRhs_[i] += implicitFriction_[i];
      }
      implicitVelocity_[i] += (predicted.dot(normal) + undo - implicitVelocity_[i].dot(normal)) * normal;
      implicitConstraint_[i] = PcgConstraint::Normal;
      implicitNormal_[i] = normal;
      implicitContactBody_[i] = b;
      implicitContactState_[i] = kSliding;
      any = true;
      continue;
    }
    // every other contact starts sticking (the solve then says whether its impulse stays in the
    // cone): at rest the set holds from step to step
    implicitVelocity_[i] = vc + (predicted.dot(normal) + undo - vc.dot(normal)) * normal;
    implicitConstraint_[i] = PcgConstraint::Fixed;
    implicitNormal_[i] = normal;
    implicitContactBody_[i] = b;
    any = true;
  }
  return any;
}

double Solver::startDepth(std::size_t i, int b) const {
  const ContactBody& body = contactBodies_[static_cast<std::size_t>(b)];
  Eigen::Vector3d normal;
  // BDF2 solves from its extrapolated start x_: the sub-step starts at x_n (a landing particle's
  // extrapolation into the collider is not a penetration to keep)
  const Eigen::Vector3d& x = bdf2Step_ ? bdf2LastX_[i] : x_[i];
  return colliderDistance(body.collider->shape, body.before, x, normal) - contactRadius();
}

int Solver::deepestContact(const Eigen::Vector3d& x, double within, Eigen::Vector3d& normal, double& depth,
                           Eigen::Vector3d& colliderVelocity) const {
  const double r = contactRadius();
  int deepest = -1;
  depth = within;
  for (std::size_t b = 0; b < contactBodies_.size(); ++b) {
    const ContactBody& body = contactBodies_[b];
    if (body.bounded && ((x.array() < body.lo.array()).any() || (x.array() > body.hi.array()).any())) continue;
    const Collider& c = *body.collider;
    Eigen::Vector3d n;
    const double d = colliderDistance(c.shape, body.now, x, n) - r;
    if (!(d < depth)) continue;
    deepest = static_cast<int>(b);
    depth = d;
    normal = n;
    colliderVelocity = c.linearVelocity + c.angularVelocity.cross(x - body.now.translation());
  }
  return deepest;
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
bool Solver::updateContactSet(double h, bool& guessChanged, Pcg& pcg, std::size_t offset) {
  const std::vector<Eigen::Vector3d>& residual = pcg.residual();
  // a friction force of the solve: the right-hand side and the residual PCG keeps change together
  const auto addFriction = [this, &pcg, offset](std::size_t i, const Eigen::Vector3d& f) {
    implicitRhs_[i] += f;
    pcg.addToResidual(offset + i, f);
  };
  const double slop = kContactSlop * contactRadius();
  bool changed = false;
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (pinned_[i] != 0 || hardDragged_[i] != 0) continue;
    if (implicitContactBody_[i] < 0) {
      Eigen::Vector3d normal, vc;
      double depth = 0.0;
      const int b = deepestContact(x_[i] + h * implicitVelocity_[i], 0.0, normal, depth, vc);
      if (b < 0 || depth > -slop) continue;
      const Eigen::Vector3d v = implicitVelocity_[i];
      const double undo = (std::min(startDepth(i, b), 0.0) - depth) / h;
      const Eigen::Vector3d rel = v - vc;
      implicitNormal_[i] = normal;
      implicitContactBody_[i] = b;
      if (implicitContactState_[i] != kReleased || (rel - rel.dot(normal) * normal).isZero(0.0)) {
        implicitVelocity_[i] = vc + (v.dot(normal) + undo - vc.dot(normal)) * normal;
        implicitConstraint_[i] = PcgConstraint::Fixed;
        implicitContactState_[i] = kSticking;
      } else {
        // a contact let go of (it pulled) that comes back slipping joins sliding, its kinetic
        // friction set by the next pass: added sticking, the uphill edge of a block sliding down
        // a slope came back into the plane, held the block, pulled, was let go, ... every pass
        implicitVelocity_[i] = v + undo * normal;
        implicitConstraint_[i] = PcgConstraint::Normal;
        implicitContactState_[i] = kSliding;
      }
      changed = true;
      guessChanged = true;
      continue;
    }
    const Collider& c = *contactBodies_[static_cast<std::size_t>(implicitContactBody_[i])].collider;
    const Eigen::Vector3d J = -residual[offset + i];
    const double Jn = J.dot(implicitNormal_[i]);
    const Eigen::Vector3d& n = implicitNormal_[i];
    if (Jn < 0.0) {
      addFriction(i, -implicitFriction_[i]);
      implicitFriction_[i].setZero();
      implicitConstraint_[i] = PcgConstraint::Free;
      implicitContactBody_[i] = -1;
      implicitContactState_[i] = kReleased;
      changed = true;
    } else if (implicitConstraint_[i] == PcgConstraint::Fixed) {
      const Eigen::Vector3d Jt = J - Jn * n;
      const double t = Jt.norm();
      if (t > c.staticFriction * Jn) {
        // out of the cone: slide, with kinetic friction mu_k J.n along the impulse that held it
        // (against the slip it resisted) as a force of the solve, so that the rest of the object
        // moves with the slip
        implicitFriction_[i] = (c.kineticFriction * Jn / t) * Jt;
        addFriction(i, implicitFriction_[i]);
        implicitConstraint_[i] = PcgConstraint::Normal;
        implicitContactState_[i] = kSliding;
        changed = true;
      }
    } else {
      const Eigen::Vector3d x = x_[i] + h * implicitVelocity_[i];
      const Eigen::Isometry3d& pose = contactBodies_[static_cast<std::size_t>(implicitContactBody_[i])].now;
      const Eigen::Vector3d vc = c.linearVelocity + c.angularVelocity.cross(x - pose.translation());
      const Eigen::Vector3d rel = implicitVelocity_[i] - vc;
      const Eigen::Vector3d slip = rel - rel.dot(n) * n;
      const double f = implicitFriction_[i].norm(), kinetic = c.kineticFriction * Jn;
      if (f == 0.0) {
        // joined sliding in this sub-step: kinetic friction against its slip from now on
        const double s = slip.norm();
        if (s > 0.0 && kinetic > 0.0) {
          implicitFriction_[i] = -(kinetic / s) * slip;
          addFriction(i, implicitFriction_[i]);
          changed = true;
        }
        continue;
      }
      // sliding: friction that carried the particle backwards (its slip along the friction
      // force) means it stops: it sticks
      if (slip.dot(implicitFriction_[i]) > 0.0) {
        addFriction(i, -implicitFriction_[i]);
        implicitFriction_[i].setZero();
        implicitVelocity_[i] = vc + (implicitVelocity_[i] - vc).dot(n) * n;
        implicitConstraint_[i] = PcgConstraint::Fixed;
        implicitContactState_[i] = kSticking;
        changed = true;
        guessChanged = true;
      } else if (std::abs(kinetic - f) > kFrictionChange * f) {
        // still sliding: kinetic friction mu_k J.n with this pass's normal impulse (the one it
        // was set with, the sticking solve's, held a sliding object's momentum too)
        const Eigen::Vector3d df = (kinetic / f - 1.0) * implicitFriction_[i];
        addFriction(i, df);
        implicitFriction_[i] += df;
        changed = true;
      }
    }
  }
  return changed;
}

// After the last solve: the impulses of every contact go to its collider's wrench, as the contact
// pass's do.
void Solver::sumContactImpulses(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset) {
  const double r = contactRadius();
  // BDF2's solve of 2/3 of the sub-step takes 2/3 of its impulses (its momentum balance is
  // P+ = (4 P_n - P_{n-1}) / 3 + (2h/3) (F + contact)): the sub-step's impulse is 3/2 of it
  const double perSubstep = bdf2Step_ ? params_.substepLength() / h : 1.0;
  for (ContactBody& body : contactBodies_) body.solved = 0;
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (implicitContactBody_[i] < 0) continue;
    ContactBody& body = contactBodies_[static_cast<std::size_t>(implicitContactBody_[i])];
    const Eigen::Vector3d& n = implicitNormal_[i];
    const Eigen::Isometry3d& pose = body.now;
    Eigen::Vector3d J = -residual[offset + i];
    // a sliding contact's impulse: the normal one and the kinetic friction the solve applied
    if (implicitConstraint_[i] == PcgConstraint::Normal) J = std::max(0.0, J.dot(n)) * n + implicitFriction_[i];
    J *= perSubstep;
    const Eigen::Vector3d x = x_[i] + h * implicitVelocity_[i];
    body.impulse += J;
    body.moment += (x - r * n - pose.translation()).cross(J);
    record(body, i, J, x - r * n);
    // a contact whose normal impulse pushes (one the solve let go of does not), counted on this
    // body in the contact pass that follows in this sub-step (countedContact())
    if ((-residual[offset + i]).dot(n) > 0.0 && markCounted(i, implicitContactBody_[i], contactPasses_ + 1))
      ++body.solved;
  }
}

// The preconditioner's coarse matrix P^T A P for this sub-step (TwoLevelPreconditioner): the
// diagonal (mass, damping, springs), the regions' co-rotated stiffness and the Poisson term's
// Hessian as addVolumetricProduct() applies it, per stencil h^2 [w (sum_a g_a . d_a)^2 +
// sum_a D_a (g_a . d_a)^2 + sum_a sigma_a^+ / d_a^2 |d_a|^2], d_a = p_plus - p_minus on axis a.
// Pinned and hard-dragged particles are outside the coarse space; contacts are left in it (they
// change within the sub-step; PCG's filter keeps them prescribed).
void Solver::assembleCoarse(double h) {
  coarse_->setFixed(*activeSummer_, pinned_, hardDragged_);
  if (!coarse_->needsAssembly(implicitDiagonal_, *hessian_, kCoarseTurn, kCoarseAge)) return;
  coarse_->beginAssembly(implicitDiagonal_, *hessian_);
  coarse_->addRegions(*hessian_);
  if (volumetric_) {
    const double h2 = h * h;
    std::uint32_t ends[6];
    Eigen::Vector3d g[6];
    for (std::size_t i = 0; i < stencil_.size(); ++i) {
      const VolumetricStencil& st = stencil_[i];
      const VolumetricLinearisation& lin = volumetricLinear_[i];
      for (int a = 0; a < 3; ++a) {
        ends[2 * a] = st.plus[a];
        ends[2 * a + 1] = st.minus[a];
        g[2 * a] = lin.gradient[a];
        g[2 * a + 1] = -lin.gradient[a];
        if (lin.deficit[a] != 0.0) coarse_->addOuter(&ends[2 * a], &g[2 * a], 2, h2 * lin.deficit[a]);
        if (lin.stretch[a] != 0.0) coarse_->addEdge(st.plus[a], st.minus[a], h2 * lin.stretch[a]);
      }
      if (lin.weight != 0.0) coarse_->addOuter(ends, g, 6, h2 * lin.weight);
    }
  }
  coarse_->factorize();
}

void Solver::implicitProduct(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
  hessian_->apply(*activeSummer_, implicitDiagonal_, p, y);
  if (volumetric_) addVolumetricProduct(p, y);
}

// h^2 H_vol p with H_vol the Hessian linearised in implicitSubstep(): per stencil,
// de_a = grad e_aa . p (the strain rate along a), de = sum_a de_a, and the ends of axis a get
// +- h^2 [(w de + D_a de_a) grad e_aa + sigma_a^+ / d_a^2 (p_plus - p_minus)].
void Solver::addVolumetricProduct(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) const {
  const double h2 = implicitH_ * implicitH_;
  for (std::size_t i = 0; i < stencil_.size(); ++i) {
    const VolumetricStencil& st = stencil_[i];
    const VolumetricLinearisation& lin = volumetricLinear_[i];
    double de[3], sum = 0.0;
    for (int a = 0; a < 3; ++a) {
      de[a] = lin.gradient[a].dot(p[st.plus[a]] - p[st.minus[a]]);
      sum += de[a];
    }
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d f = (h2 * (lin.weight * sum + lin.deficit[a] * de[a])) * lin.gradient[a] +
                                (h2 * lin.stretch[a]) * (p[st.plus[a]] - p[st.minus[a]]);
      y[st.plus[a]] += f;
      y[st.minus[a]] -= f;
    }
  }
}

// The free object's linear and angular momentum after the step are what the external forces give:
//   P+ = sum m (v_n + h a_ext),   L+ = sum m x_n x (v_n + h a_ext)   (x+ = x_n + h v+, so
//   sum m x+ x v+ = sum m x_n x v+),
// a_ext = gravity + timed forces. The solution is corrected by the uniform velocity u and the
// rotation w x (x - c) about the centre of mass c that restore both: u = dP / M, w = I_c^+ dL_c.
void Solver::correctRigidModes(double h) {
  const auto& m = lattice_->masses();
  const std::size_t n = x_.size();
  const Eigen::Vector3d ref = x_[anchor_];
  double M = 0.0;
  Eigen::Vector3d mp = Eigen::Vector3d::Zero(), dP = Eigen::Vector3d::Zero(), dL = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mpp = Eigen::Matrix3d::Zero();
  const bool forced = !forcedParticles_.empty();
  // BDF2 (x_, v_ its extrapolated start, h 2/3 of the sub-step H): P+ = P_n + H F, and the spin
  // about the centre of mass S+ = sum m (x+ - c+) x v+ = sum m (x_ - c) x v+ is S_n plus H times
  // the external torque about c (a uniform gravity has none). (The angular momentum about a fixed
  // point would need the centre's path within the step: x_'s centre is a third of a step ahead of
  // x_n's, not half.)
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  Eigen::Vector3d solvedP = Eigen::Vector3d::Zero(), solvedL = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = x_[i] - ref;
    Eigen::Vector3d target = v_[i] + h * params_.gravity;
    if (forced) target += h * forceAccel_[i];
    Eigen::Vector3d d = m[i] * (target - implicitVelocity_[i]);
    if (!implicitCouplingImpulse_.empty()) d += implicitCouplingImpulse_[i];
    M += m[i];
    mp += m[i] * p;
    dP += d;
    dL += p.cross(d);
    mpp.noalias() += m[i] * p * p.transpose();
    if (bdf2Step_) {
      const Eigen::Vector3d a = forced ? Eigen::Vector3d(params_.gravity + forceAccel_[i]) : params_.gravity;
      force += m[i] * a;
      torque += m[i] * p.cross(a);
      solvedP += m[i] * implicitVelocity_[i];
      solvedL += m[i] * p.cross(implicitVelocity_[i]);
    }
  }
  const Eigen::Vector3d c = mp / M;
  Eigen::Vector3d dLc = dL - c.cross(dP);  // what remains about c once u is added
  if (bdf2Step_) {
    const double H = 1.5 * h;
    const Eigen::Vector3d targetS = bdf2Spin_ + H * (torque - c.cross(force));
    dP = bdf2P_ + H * force - solvedP;
    dLc = targetS - (solvedL - c.cross(solvedP));
  }
  const Eigen::Vector3d u = dP / M;
  const Eigen::Matrix3d P = mpp - M * c * c.transpose();
  const Eigen::Matrix3d I = P.trace() * Eigen::Matrix3d::Identity() - P;
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(I);
  const Eigen::Vector3d& lambda = eig.eigenvalues();
  const double cutoff = kInertiaRankTolerance * lambda.cwiseAbs().maxCoeff();
  Eigen::Vector3d inv;
  for (int a = 0; a < 3; ++a) inv[a] = lambda[a] > cutoff ? 1.0 / lambda[a] : 0.0;
  const Eigen::Matrix3d& V = eig.eigenvectors();
  const Eigen::Vector3d w = V * inv.asDiagonal() * (V.transpose() * dLc);
  for (std::size_t i = 0; i < n; ++i) implicitVelocity_[i] += u + w.cross(x_[i] - ref - c);
}

}  // namespace deformable_flsm
