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
#include "explicit_step.h"
#include "implicit_solve.h"
#include "implicit_step.h"
#include "inertia.h"

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

}  // namespace

// --- the object's side: the step made with the integrator, and a coupled solve's member ------

Solver::~Solver() = default;

void Solver::configureIntegrator() {
  if (params_.integrator != Integrator::Implicit) {
    if (!explicit_) explicit_ = std::make_unique<ExplicitStep>(*this);
    integrator_ = explicit_.get();
    return;
  }
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
  if (!implicit_) implicit_ = std::make_unique<ImplicitStep>(*this);
  implicit_->configure();
  integrator_ = implicit_.get();
}

const PcgResult& Solver::lastImplicitSolve() const {
  static const PcgResult none;
  return implicit_ ? implicit_->lastSolve() : none;
}

void Solver::beginCoupledSubstep(int s, double h) {
  interpolateDragFrames(static_cast<double>(s + 1) / params_.substeps);
  beginContactSubstep(s);
  implicit_->begin(h);
}

std::vector<Eigen::Vector3d>& Solver::implicitVelocity() { return implicit_->velocity(); }
// (an explicit object has no system, even with an implicit step kept from before a switch:
// empty, as a coupled solve may ask a sleeping neighbour's)
namespace {
const std::vector<Eigen::Vector3d> kNoVectors;
const std::vector<PcgConstraint> kNoConstraints;
}  // namespace

const Solver::ImplicitStep* Solver::implicitSystem() const {
  return params_.integrator == Integrator::Implicit ? implicit_.get() : nullptr;
}

const std::vector<Eigen::Vector3d>& Solver::implicitRhs() const {
  return implicitSystem() ? implicitSystem()->rhs() : kNoVectors;
}
const std::vector<PcgConstraint>& Solver::implicitConstraints() const {
  return implicitSystem() ? implicitSystem()->constraints() : kNoConstraints;
}
const std::vector<Eigen::Vector3d>& Solver::implicitNormals() const {
  return implicitSystem() ? implicitSystem()->normals() : kNoVectors;
}
const std::vector<Eigen::Vector3d>& Solver::implicitInvDiagonal() const {
  return implicitSystem() ? implicitSystem()->invDiagonal() : kNoVectors;
}
double Solver::implicitRhsNorm2() const { return implicitSystem() ? implicitSystem()->rhsNorm2() : 0.0; }
double Solver::implicitGravityNorm2() const { return implicitSystem() ? implicitSystem()->gravityNorm2() : 0.0; }
std::size_t Solver::implicitFreeCount() const { return implicitSystem() ? implicitSystem()->freeCount() : 0; }

void Solver::implicitProduct(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
  implicit_->product(p, y);
}

void Solver::implicitPrecondition(const std::vector<Eigen::Vector3d>& invDiagonal,
                                  const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
  implicit_->precondition(invDiagonal, r, z);
}

bool Solver::updateContactSet(double h, bool& guessChanged, Pcg& pcg, std::size_t offset) {
  return implicit_->updateContactSet(h, guessChanged, pcg, offset);
}

void Solver::endCoupledSubstep(double h, const PcgResult& result, const std::vector<Eigen::Vector3d>& residual,
                               std::size_t offset, const std::vector<Eigen::Vector3d>& couplingImpulse) {
  implicit_->endCoupled(h, result, residual, offset, couplingImpulse);
}

void Solver::addCoupledSolveTime(double seconds) {
  if (singleSummer_ != nullptr) stepSeconds_ += seconds;  // only with a governor (threads > 1)
}

// --- the implicit step ---------------------------------------------------------------------

Solver::ImplicitStep::ImplicitStep(Solver& object) : o_(object) {}

void Solver::ImplicitStep::configure() {
  const std::size_t n = o_.lattice_->size();
  if (!hessian_)
    hessian_ = std::make_unique<CorotatedHessian>(*o_.summer_, o_.lattice_->regionMassFractions(), o_.restCentered_,
                                                  o_.regionMass_, o_.regionRestCenter_);
  if (!coarse_)
    coarse_ = std::make_unique<TwoLevelPreconditioner>(*o_.lattice_, o_.lattice_->regionMassFractions(),
                                                       o_.restCentered_, o_.regionMass_, o_.regionRestCenter_,
                                                       kCoarseAggregates);
  // the region moments of the coarse space, gathered here rather than in the first step (the
  // constructor sizes the pins after this)
  if (o_.pinned_.size() == n) coarse_->setFixed(*o_.summer_, o_.pinned_, o_.hardDragged_);
  weightSum_.resize(n);
  for (std::size_t i = 0; i < n; ++i) weightSum_[i] = 1.0 / o_.invWeightSum_[i];
  if (velocity_.size() != n) {
    pcg_.resize(n);
    goals_.assign(n, Eigen::Vector3d::Zero());
    rhs_.assign(n, Eigen::Vector3d::Zero());
    velocity_.assign(n, Eigen::Vector3d::Zero());
    diagonal_.assign(n, Eigen::Vector3d::Zero());
    invPrecond_.assign(n, Eigen::Vector3d::Zero());
    lastDv_.assign(n, Eigen::Vector3d::Zero());
    constraint_.assign(n, PcgConstraint::Free);
    normal_.assign(n, Eigen::Vector3d::Zero());
    contactBody_.assign(n, -1);
    contactState_.assign(n, kNoContact);
    friction_.assign(n, Eigen::Vector3d::Zero());
  }
  volumetricLinear_.resize(o_.volumetric_ ? n : 0);
  const bool bdf2 = o_.params_.implicitScheme == ImplicitScheme::Bdf2;
  bdf2LastX_.resize(bdf2 ? n : 0);
  bdf2LastV_.resize(bdf2 ? n : 0);
  bdf2LastGap_.assign(bdf2 ? n : 0, Eigen::Vector3d::Zero());
  bdf2GapChange_ = std::numeric_limits<double>::infinity();  // no last sub-step to compare with
  bdf2Ready_ = false;  // a new step length or scheme: start again with backward Euler
  bdf2Step_ = false;
}

void Solver::ImplicitStep::forgetMemory() {
  std::fill(lastDv_.begin(), lastDv_.end(), Eigen::Vector3d::Zero());
  std::fill(contactState_.begin(), contactState_.end(), kNoContact);
  std::fill(friction_.begin(), friction_.end(), Eigen::Vector3d::Zero());
  bdf2Ready_ = false;
}

void Solver::ImplicitStep::substep(double substep) {
  const bool bdf2 = o_.params_.implicitScheme == ImplicitScheme::Bdf2;
  // the backward Euler step solved: the sub-step itself, or BDF2's 2/3 of it from its start
  bdf2Step_ = false;
  const double h = bdf2 ? bdf2Begin(substep) : substep;
  begin(h);
  // Contacts by an active set (see constrainContacts()): solve, let go of the contacts whose
  // impulse pulls, turn the sticking ones whose impulse leaves the friction cone into sliding
  // ones, and solve again from where it was.
  const auto apply = [this](const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
    product(p, y);
  };
  const auto precond = [this](const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
    precondition(invPrecond_, r, z);
  };
  lastSolve_ = solveWithContactSet(
      pcg_, [] {}, apply, precond, constraint_, normal_, rhs_, velocity_, floor_, kCgTolerance, [] {},
      [&](bool& guessChanged) { return updateContactSet(h, guessChanged, pcg_, 0); });
  end(h, pcg_.residual(), 0, substep);
  if (bdf2) bdf2End(substep);
}

void Solver::ImplicitStep::precondition(const std::vector<Eigen::Vector3d>& invDiagonal,
                                        const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
  coarse_->apply(invDiagonal, r, z);
}

void Solver::ImplicitStep::endCoupled(double h, const PcgResult& result, const std::vector<Eigen::Vector3d>& residual,
                                      std::size_t offset, const std::vector<Eigen::Vector3d>& couplingImpulse) {
  lastSolve_ = result;
  couplingImpulse_ = &couplingImpulse;
  end(h, residual, offset);
  couplingImpulse_ = nullptr;
}

double Solver::ImplicitStep::bdf2Begin(double h) {
  const std::size_t n = o_.x_.size();
  if (o_.impulsePending_ && bdf2Ready_) {
    // an impulse changes v_n and, for the extrapolation, v_{n-1} alike
    for (std::size_t i = 0; i < n; ++i) bdf2LastV_[i] += o_.impulseDv_[i];
  }
  o_.applyPendingImpulses();
  if (!bdf2Ready_ || bdf2GapChange_ > kBdf2MaxGoalGapChange) {
    bdf2LastX_ = o_.x_;  // same size: no allocation
    bdf2LastV_ = o_.v_;
    bdf2Ready_ = true;
    return h;
  }
  // the momenta BDF2's solve must keep (correctRigidModes()): a linear multistep method keeps
  // the linear one by itself, not the spin
  const auto& m = o_.lattice_->masses();
  double M = 0.0;
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), L = Eigen::Vector3d::Zero();
  bdf2P_.setZero();
  for (std::size_t i = 0; i < n; ++i) {
    M += m[i];
    mx += m[i] * (o_.x_[i] - o_.x_[0]);
    bdf2P_ += m[i] * o_.v_[i];
    L += m[i] * (o_.x_[i] - o_.x_[0]).cross(o_.v_[i]);
  }
  bdf2Spin_ = L - (mx / M).cross(bdf2P_);  // about the centre of mass
  bdf2Step_ = true;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d x = o_.x_[i], v = o_.v_[i];
    o_.x_[i] = x + (x - bdf2LastX_[i]) / 3.0;
    o_.v_[i] = v + (v - bdf2LastV_[i]) / 3.0;
    bdf2LastX_[i] = x;
    bdf2LastV_[i] = v;
  }
  return 2.0 * h / 3.0;
}

void Solver::ImplicitStep::bdf2End(double h) {
  const std::size_t n = o_.x_.size();
  for (std::size_t i = 0; i < n; ++i) {
    // velocity_ holds the solve's v+: the contact pass after it, a pin or a hard drag
    // changed v_ since
    const bool moved = o_.pinned_[i] != 0 || o_.hardDragged_[i] != 0 || contactState_[i] != kNoContact ||
                       o_.v_[i] != velocity_[i];
    if (!moved) continue;
    bdf2LastX_[i] = o_.x_[i] - h * o_.v_[i];
    bdf2LastV_[i] = o_.v_[i];
  }
}

void Solver::ImplicitStep::begin(double h) {
  const std::size_t n = o_.x_.size();
  const auto& m = o_.lattice_->masses();
  h_ = h;
  o_.applyPendingImpulses();
  // a timed force's last sub-step is cut by the time the sub-step advances (BDF2 solves 2/3 of it)
  o_.accumulateForces(bdf2Step_ ? o_.params_.substepLength() : h);
  // The linearisation point: one ordinary region pass gives the goals and the rotations R_r.
  o_.computeGoals(goals_);
  if (o_.volumetric_) {
    o_.computeVolumetricForces();
    linearizeVolumetric();
  }
  const bool relative = o_.params_.ambientDamping > 0.0 && !o_.heldByWorld();
  const RigidMotion rigid = relative ? o_.rigidMotion() : RigidMotion();

  // The system: A = diag(M (1 + h c [a free object]) + h^2 k_spring) + sum_r (h^2 k beta_r + h damping) K_r
  // (+ h^2 H_vol), h^2 k = alpha.
  hessian_->setRotations(o_.rotations_);
  // alpha = h^2 k for the sub-step; a shorter solve (BDF2's 2/3 of it) keeps k
  const double substep = o_.params_.substepLength();
  const double alpha = h == substep ? o_.alpha_ : o_.alpha_ * (h / substep) * (h / substep);
  hessian_->setCoefficients(alpha, h * o_.params_.damping, o_.regionWeight_, weightSum_, o_.invCount_);
  const double c = o_.params_.ambientDamping;
  // Ambient damping relative to the object's rigid motion (a free object) is in the system; an
  // object held by the world is damped as the explicit step damps it, v_n by exp(-c h) before
  // the step: in the system it would damp the sub-step's fall onto a support the solve does not
  // see (another object, whose contact comes after the solve), which then carried 1 / (1 + h c)
  // of the weight above it.
  const double damped = relative ? 1.0 + h * c : 1.0;
  const double keep = relative ? 1.0 : std::exp(-c * h);
  for (std::size_t i = 0; i < n; ++i) diagonal_[i].setConstant(m[i] * damped);
  addDragsToSystem(h);
  // Right-hand side M v_n + h f_el(x_n), the initial guess and the Jacobi preconditioner.
  const double pull = alpha / h;  // h k
  double rhsNorm = 0.0, gravityNorm = 0.0, goalGap2 = 0.0;
  const bool bdf2 = o_.params_.implicitScheme == ImplicitScheme::Bdf2 && bdf2LastGap_.size() == n;
  for (std::size_t i = 0; i < n; ++i) {
    Eigen::Vector3d a = o_.params_.gravity;
    if (!o_.forcedParticles_.empty()) a += o_.forceAccel_[i];
    if (o_.volumetric_) a += o_.volumetricAccel_[i];
    Eigen::Vector3d b = m[i] * (keep * o_.v_[i] + h * a + pull * o_.stiffnessFactor_[i] * (goals_[i] - o_.x_[i]));
    if (bdf2) {
      const Eigen::Vector3d gap = goals_[i] - o_.x_[i];
      goalGap2 = std::max(goalGap2, (gap - bdf2LastGap_[i]).squaredNorm());
      bdf2LastGap_[i] = gap;
    }
    // relative ambient damping pulls towards the object's rigid motion as gravity carries it
    // over the sub-step (as the explicit step damps before adding gravity): free fall is exact
    if (relative) b += (h * c * m[i]) * (rigid.velocity + rigid.spin.cross(o_.x_[i] - o_.xref_) + h * o_.params_.gravity);
    rhs_[i] = b;
    invPrecond_[i] = (diagonal_[i].array() + hessian_->diagonalBound(i)).inverse();
    constraint_[i] = (o_.pinned_[i] != 0 || o_.hardDragged_[i] != 0) ? PcgConstraint::Fixed : PcgConstraint::Free;
    contactBody_[i] = -1;
    if (o_.pinned_[i] != 0)
      velocity_[i].setZero();
    else if (o_.hardDragged_[i] == 0)
      velocity_[i] = o_.v_[i] + lastDv_[i] + h * o_.params_.gravity;
  }
  if (o_.volumetric_) addVolumetricPreconditioner(h);
  constrainContacts(h);
  assembleCoarse(h);
  std::size_t free = 0;
  for (std::size_t i = 0; i < n; ++i) {
    if (o_.pinned_[i] != 0 || o_.hardDragged_[i] != 0) continue;
    ++free;
    const Eigen::Vector3d impulse = rhs_[i] - m[i] * o_.v_[i];  // h f(x_n)
    rhsNorm += impulse.dot(invPrecond_[i].cwiseProduct(impulse));
    const Eigen::Vector3d g = (m[i] * h) * o_.params_.gravity;
    gravityNorm += g.dot(invPrecond_[i].cwiseProduct(g));
  }
  freeCount_ = free;
  bdf2GapChange_ = std::sqrt(goalGap2) / o_.lattice_->spacing();
  rhsNorm2_ = rhsNorm;
  gravityNorm2_ = gravityNorm;
  floor_ = kCgFloor * std::max({std::sqrt(rhsNorm), std::sqrt(gravityNorm), 1e-300}) /
                   std::sqrt(static_cast<double>(std::max<std::size_t>(free, 1)));
}

void Solver::ImplicitStep::linearizeVolumetric() {
  const std::size_t n = o_.x_.size();
  // The Poisson term linearised at x_n: E_i = w/2 e^2 + sum_a D_a/2 e_aa^2 has the Hessian
  //   w grad e grad e^T + sum_a D_a grad e_aa grad e_aa^T + sum_a sigma_a hess e_aa,
  // grad e_aa = +-F_a / d_a at the ends of axis a, sigma_a = w e + D_a e_aa the stress along a,
  // hess e_aa = [1 -1; -1 1] / d_a^2 (x) 1. The last term is kept where it is positive (a
  // stretched stencil: without it the force, linear in F, would be explicit and unstable) and
  // dropped where negative (compression: Gauss-Newton), so the matrix stays positive
  // semi-definite. Where the strain is clamped the force is sigma F / d with sigma constant:
  // only the last term remains.
  for (std::size_t i = 0; i < n; ++i) {
    const VolumetricStencil& st = o_.stencil_[i];
    VolumetricLinearisation& lin = volumetricLinear_[i];
    double e = 0.0, eaa[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d F = (o_.x_[st.plus[a]] - o_.x_[st.minus[a]]) * st.invDistance[a];
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

// Each drag in the system: a spring drag's stiffness on the diagonal, a hard drag's velocity
// prescribed (the one that reaches its target in the sub-step).
void Solver::ImplicitStep::addDragsToSystem(double h) {
  const auto& m = o_.lattice_->masses();
  for (const auto& entry : o_.drags_) {
    const Drag& drag = entry.second;
    const Eigen::Isometry3d& frame = drag.frame;
    double M = 0.0;
    for (std::uint32_t p : drag.particles) M += m[p];
    for (std::size_t e = 0; e < drag.particles.size(); ++e) {
      const std::uint32_t p = drag.particles[e];
      if (drag.stiffness > 0.0)
        diagonal_[p].array() += h * h * drag.stiffness * m[p] / M;
      else if (o_.pinned_[p] == 0)
        velocity_[p] = (frame * drag.offsets[e] - o_.x_[p]) / h;  // reaches the target
    }
  }
}

void Solver::ImplicitStep::addVolumetricPreconditioner(double h) {
  const std::size_t n = o_.x_.size();
  // the Gauss-Newton Hessian's diagonal, for the preconditioner only
  for (std::size_t i = 0; i < n; ++i) {
    const VolumetricStencil& st = o_.stencil_[i];
    const VolumetricLinearisation& lin = volumetricLinear_[i];
    for (int a = 0; a < 3; ++a) {
      const Eigen::Vector3d d = (h * h * (lin.weight + lin.deficit[a])) * lin.gradient[a].cwiseAbs2() +
                                Eigen::Vector3d::Constant(h * h * lin.stretch[a]);
      invPrecond_[st.plus[a]] = (invPrecond_[st.plus[a]].cwiseInverse() + d).cwiseInverse();
      invPrecond_[st.minus[a]] = (invPrecond_[st.minus[a]].cwiseInverse() + d).cwiseInverse();
    }
  }
}

void Solver::ImplicitStep::end(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset,
                         double elapsed) {
  const std::size_t n = o_.x_.size();
  if (!o_.contactBodies_.empty()) sumContactImpulses(h, residual, offset);
  if (!o_.heldByWorld()) correctRigidModes(h);
  sumDragImpulses(h, residual, offset);

  // v+ and x+ = x_n + h v+ for the free particles; the pinned and hard-dragged ones are
  // finishSubstep()'s, as in the explicit step.
  for (std::size_t i = 0; i < n; ++i) {
    if (o_.pinned_[i] != 0 || o_.hardDragged_[i] != 0) continue;
    lastDv_[i] = velocity_[i] - o_.v_[i] - h * o_.params_.gravity;
    o_.v_[i] = velocity_[i];
    o_.x_[i] += h * o_.v_[i];
  }
  o_.endSubstep(h, elapsed > 0.0 ? elapsed : h);
}

// A hard drag's impulse is the solve's reaction on its prescribed rows, -(b - A v); BDF2's solve
// of 2/3 of the sub-step takes 2/3 of it, as its contacts' (sumContactImpulses()).
void Solver::ImplicitStep::sumDragImpulses(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset) {
  const double perSubstep = bdf2Step_ ? o_.params_.substepLength() / h : 1.0;
  for (auto& entry : o_.drags_) {
    Drag& drag = entry.second;
    if (drag.stiffness > 0.0) continue;
    for (std::uint32_t p : drag.particles)
      if (o_.pinned_[p] == 0)
        countDragImpulse(drag, o_.x_[p] + h * velocity_[p], -perSubstep * residual[offset + p]);
  }
}

// The preconditioner's coarse matrix P^T A P for this sub-step (TwoLevelPreconditioner): the
// diagonal (mass, damping, springs), the regions' co-rotated stiffness and the Poisson term's
// Hessian as addVolumetricProduct() applies it, per stencil h^2 [w (sum_a g_a . d_a)^2 +
// sum_a D_a (g_a . d_a)^2 + sum_a sigma_a^+ / d_a^2 |d_a|^2], d_a = p_plus - p_minus on axis a.
// Pinned and hard-dragged particles are outside the coarse space; contacts are left in it (they
// change within the sub-step; PCG's filter keeps them prescribed).
void Solver::ImplicitStep::assembleCoarse(double h) {
  coarse_->setFixed(*o_.activeSummer_, o_.pinned_, o_.hardDragged_);
  if (!coarse_->needsAssembly(diagonal_, *hessian_, kCoarseTurn, kCoarseAge)) return;
  coarse_->beginAssembly(diagonal_, *hessian_);
  coarse_->addRegions(*hessian_);
  if (o_.volumetric_) {
    const double h2 = h * h;
    std::uint32_t ends[6];
    Eigen::Vector3d g[6];
    for (std::size_t i = 0; i < o_.stencil_.size(); ++i) {
      const VolumetricStencil& st = o_.stencil_[i];
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

void Solver::ImplicitStep::product(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
  hessian_->apply(*o_.activeSummer_, diagonal_, p, y);
  if (o_.volumetric_) addVolumetricProduct(p, y);
}

// h^2 H_vol p with H_vol the Hessian linearised in begin(): per stencil,
// de_a = grad e_aa . p (the strain rate along a), de = sum_a de_a, and the ends of axis a get
// +- h^2 [(w de + D_a de_a) grad e_aa + sigma_a^+ / d_a^2 (p_plus - p_minus)].
void Solver::ImplicitStep::addVolumetricProduct(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) const {
  const double h2 = h_ * h_;
  for (std::size_t i = 0; i < o_.stencil_.size(); ++i) {
    const VolumetricStencil& st = o_.stencil_[i];
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
void Solver::ImplicitStep::correctRigidModes(double h) {
  const auto& m = o_.lattice_->masses();
  const std::size_t n = o_.x_.size();
  const Eigen::Vector3d ref = o_.x_[o_.anchor_];
  double M = 0.0;
  Eigen::Vector3d mp = Eigen::Vector3d::Zero(), dP = Eigen::Vector3d::Zero(), dL = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mpp = Eigen::Matrix3d::Zero();
  const bool forced = !o_.forcedParticles_.empty();
  // BDF2 (x_, v_ its extrapolated start, h 2/3 of the sub-step H): P+ = P_n + H F, and the spin
  // about the centre of mass S+ = sum m (x+ - c+) x v+ = sum m (x_ - c) x v+ is S_n plus H times
  // the external torque about c (a uniform gravity has none). (The angular momentum about a fixed
  // point would need the centre's path within the step: x_'s centre is a third of a step ahead of
  // x_n's, not half.)
  Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
  Eigen::Vector3d solvedP = Eigen::Vector3d::Zero(), solvedL = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d p = o_.x_[i] - ref;
    Eigen::Vector3d target = o_.v_[i] + h * o_.params_.gravity;
    if (forced) target += h * o_.forceAccel_[i];
    Eigen::Vector3d d = m[i] * (target - velocity_[i]);
    if (couplingImpulse_ != nullptr) d += (*couplingImpulse_)[i];
    M += m[i];
    mp += m[i] * p;
    dP += d;
    dL += p.cross(d);
    mpp.noalias() += m[i] * p * p.transpose();
    if (bdf2Step_) {
      const Eigen::Vector3d a = forced ? Eigen::Vector3d(o_.params_.gravity + o_.forceAccel_[i]) : o_.params_.gravity;
      force += m[i] * a;
      torque += m[i] * p.cross(a);
      solvedP += m[i] * velocity_[i];
      solvedL += m[i] * p.cross(velocity_[i]);
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
  const Eigen::Vector3d w = InertiaInverse(I).solve(dLc);
  for (std::size_t i = 0; i < n; ++i) velocity_[i] += u + w.cross(o_.x_[i] - ref - c);
}

}  // namespace deformable_flsm
