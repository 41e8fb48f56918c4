#include "deformable_flsm/core/solver.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/polar.h"
#include "deformable_flsm/core/small_matrix.h"
#include "explicit_step.h"
#include "implicit_step.h"
#include "inertia.h"
#include "region_kernels.h"
#include "simd_dispatch.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <numeric>
#include <stdexcept>
#include <thread>

namespace deformable_flsm {

namespace {

/// Channels per particle of the shape-matching sums: m~ p (3) and m~ p q^T (9).
constexpr int kShapeChannels = 12;
/// Channels per region of the transforms scattered back: R (9, row-major) and t (3).
constexpr int kTransformChannels = 12;
/// Channels per particle of the damping sums, after the shape channels: m~ v (3), p x m~ v (3),
/// m~ p p^T (6, upper triangle).
constexpr int kDampingChannels = 12;
/// Channels per region of the rigid velocity fields scattered back after the transforms: u (3) and
/// omega (3), the field being u + omega x p.
constexpr int kVelocityFieldChannels = 6;
/// omega = I^+ L through the eigen-decomposition: the general case of solveInertia().
[[gnu::noinline]] Eigen::Vector3d solveInertiaByEigen(const Eigen::Matrix3d& I, const Eigen::Vector3d& L) {
  return InertiaInverse(I).solve(L);
}

/// omega = I^+ L for a symmetric positive semi-definite inertia tensor.
inline Eigen::Vector3d solveInertia(const Eigen::Matrix3d& I, const Eigen::Vector3d& L) {
  const double trace = I.trace();
  if (!(trace > 0.0)) return Eigen::Vector3d::Zero();
  // Fast path: well conditioned (every pivot clearly positive).
  Eigen::Vector3d w;
  if (solveSymmetricPositive3(I, L, kInertiaRankTolerance * trace, w)) return w;
  return solveInertiaByEigen(I, L);
}

}  // namespace

void detail::solveInertiaGeneral(const double* I, const double* L, double* w) {
  Eigen::Map<Eigen::Vector3d> omega(w);
  omega = solveInertia(Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(I), Eigen::Map<const Eigen::Vector3d>(L));
}

namespace {

/// Threads to use: `requested`, or every hardware thread for 0.
int resolveThreadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

}  // namespace

Solver::Solver(std::shared_ptr<const Lattice> lattice, const SolverParams& params)
    : lattice_(std::move(lattice)), params_(params) {
  if (!lattice_) throw std::invalid_argument("solver: no lattice");
  params_.validate();
  if (params_.regionHalfWidth != lattice_->regionHalfWidth())
    throw std::invalid_argument("solver: region half-width " + std::to_string(params_.regionHalfWidth) +
                                " differs from the lattice's " +
                                std::to_string(lattice_->regionHalfWidth()));
  const Lattice& L = *lattice_;
  const std::size_t n = L.size();
  threads_ = resolveThreadCount(params_.threads);
  makeSummers();

  const auto& x0 = L.restPositions();
  const auto& m = L.masses();
  restCom_.setZero();
  for (std::size_t i = 0; i < n; ++i) restCom_ += m[i] * x0[i];
  restCom_ /= L.totalMass();
  restCentered_.resize(n);
  invCount_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    restCentered_[i] = x0[i] - restCom_;
    invCount_[i] = 1.0 / L.regionCounts()[i];
  }

  // Rest region masses and centres: M_r = sum m~, c0_r = sum m~ q / M_r.
  std::vector<double> mass(L.regionMassFractions()), massSum;
  summer_->gather(mass, 1, massSum);
  std::vector<double> moment(3 * n), momentSum;
  for (std::size_t i = 0; i < n; ++i)
    for (int a = 0; a < 3; ++a) moment[3 * i + a] = mass[i] * restCentered_[i][a];
  summer_->gather(moment, 3, momentSum);
  regionMass_ = massSum;
  regionInvMass_.resize(n);
  for (std::size_t r = 0; r < n; ++r) regionInvMass_[r] = 1.0 / regionMass_[r];
  regionRestCenter_.resize(n);
  for (std::size_t r = 0; r < n; ++r)
    regionRestCenter_[r] = Eigen::Vector3d(momentSum[3 * r], momentSum[3 * r + 1], momentSum[3 * r + 2]) /
                           regionMass_[r];

  computeRegionWeights();
  configureIntegrator();

  x_ = x0;
  v_.assign(n, Eigen::Vector3d::Zero());
  double anchorDistance = (x0[0] - restCom_).squaredNorm();
  for (std::size_t i = 1; i < n; ++i) {
    const double d = (x0[i] - restCom_).squaredNorm();
    if (d < anchorDistance) {
      anchorDistance = d;
      anchor_ = static_cast<std::uint32_t>(i);
    }
  }
  rotations_.assign(n, Eigen::Quaterniond::Identity());
  pinned_.assign(n, 0);
  hardDragged_.assign(n, 0);
  pinnedList_.reserve(n);
  pinPosition_ = x0;
  impulseDv_.assign(n, Eigen::Vector3d::Zero());
  forceAccel_.assign(n, Eigen::Vector3d::Zero());
}

void Solver::setParams(const SolverParams& params) {
  params.validate();
  if (params.regionHalfWidth != params_.regionHalfWidth)
    throw std::invalid_argument("solver: region_half_width cannot change at run time (it defines the "
                                "regions); restart with the new value");
  if (params.density != params_.density)
    throw std::invalid_argument("solver: density cannot change at run time (it defines the particle "
                                "masses); restart with the new value");
  const int threads = resolveThreadCount(params.threads);
  const bool rebuild = params.kind != params_.kind || threads != threads_;
  params_ = params;
  if (rebuild) {
    threads_ = threads;
    makeSummers();
  }
  computeRegionWeights();
  configureIntegrator();
  ++stateVersion_;
}

void Solver::reset() {
  x_ = lattice_->restPositions();
  std::fill(v_.begin(), v_.end(), Eigen::Vector3d::Zero());
  std::fill(rotations_.begin(), rotations_.end(), Eigen::Quaterniond::Identity());
  pinPosition_ = x_;
  drags_.clear();
  markHardDrags();
  forces_.clear();
  std::fill(impulseDv_.begin(), impulseDv_.end(), Eigen::Vector3d::Zero());
  impulsePending_ = false;
  frameRotation_.setIdentity();
  for (ContactBody& body : contactBodies_) body.wrench = ContactWrench();
  // the implicit step's memory of the last sub-step: its warm start and contact states (also of
  // one kept from before a switch to the explicit integrator)
  if (implicit_) implicit_->forgetMemory();
  time_ = 0.0;
  substeps_ = 0;
  ++stateVersion_;
}

void Solver::setPositions(const std::vector<Eigen::Vector3d>& x) {
  if (x.size() != x_.size()) throw std::invalid_argument("solver: setPositions with the wrong size");
  x_ = x;
  integrator_->forgetHistory();
  ++stateVersion_;
}

void Solver::setVelocities(const std::vector<Eigen::Vector3d>& v) {
  if (v.size() != v_.size()) throw std::invalid_argument("solver: setVelocities with the wrong size");
  v_ = v;
  integrator_->forgetHistory();
  ++stateVersion_;
}

void Solver::makeSummers() {
  singleSummer_.reset();
  governor_ = ThreadGovernor();
  if (params_.kind == SolverKind::Fast) {
    if (threads_ > 1) {
      // Each used only when the governor says so, possibly first in the middle of a run: no
      // allocation then. They never sweep at once: one set of slice buffers serves both.
      const int Kg = kShapeChannels + kDampingChannels, Ks = kTransformChannels + kVelocityFieldChannels;
      auto threaded = std::make_unique<SliceStreamSummer>(*lattice_, threads_);
      threaded->reserve(Kg, Ks);
      auto single = std::make_unique<SliceStreamSummer>(*lattice_, 1);
      single->reserve(Kg, Ks);
      if (sharedScratch_) threaded->shareScratch(sharedScratch_);
      single->shareScratch(threaded->scratch());
      summer_ = std::move(threaded);
      singleSummer_ = std::move(single);
    } else {
      auto summer = std::make_unique<SliceStreamSummer>(*lattice_, threads_);
      if (sharedScratch_) summer->shareScratch(sharedScratch_);
      summer_ = std::move(summer);
    }
  } else {
    summer_ = std::make_unique<NaiveSummer>(*lattice_);
  }
  activeSummer_ = summer_.get();
}

void Solver::shareRegionScratch(std::shared_ptr<SliceStreamScratch> scratch) {
  sharedScratch_ = std::move(scratch);
  if (!sharedScratch_) {  // buffers of its own again
    makeSummers();
    return;
  }
  // the summers as they are, their buffers the shared ones from now on
  for (RegionSummer* summer : {summer_.get(), singleSummer_.get()})
    if (auto* streamed = dynamic_cast<SliceStreamSummer*>(summer)) streamed->shareScratch(sharedScratch_);
}

std::shared_ptr<const SliceStreamScratch> Solver::regionScratch() const {
  const auto* streamed = dynamic_cast<const SliceStreamSummer*>(summer_.get());
  return streamed != nullptr ? streamed->scratch() : nullptr;
}

void Solver::step() {
  beginStep();
  for (int s = 0; s < params_.substeps; ++s) advanceSubstep(s);
  endStep();
}

void Solver::beginStep() {
  // With threads, each step runs on the threads or on one thread, whichever has been faster
  // lately (ThreadGovernor): the same sums in the same order either way, so the results do not
  // depend on the choice. The governor times the sub-steps only, so that a coordinator's work
  // between them does not count.
  const bool timed = singleSummer_ != nullptr;
  activeSummer_ = timed && !governor_.threaded() ? singleSummer_.get() : summer_.get();
  stepSeconds_ = 0.0;
  beginContactStep();
  for (auto& entry : drags_) entry.second.impulse = entry.second.moment = Eigen::Vector3d::Zero();
}

void Solver::advanceSubstep(int s) {
  const double h = params_.timeStep / params_.substeps;
  const bool timed = singleSummer_ != nullptr;
  const auto t0 = timed ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point();
  interpolateDragFrames(static_cast<double>(s + 1) / params_.substeps);
  beginContactSubstep(s);
  integrator_->substep(h);
  if (timed) stepSeconds_ += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void Solver::endStep() {
  endContactStep();
  if (singleSummer_ != nullptr) {
    governor_.record(stepSeconds_);
    activeSummer_ = summer_.get();
  }
  const double T = params_.timeStep;
  for (auto& entry : drags_) {
    Drag& d = entry.second;
    d.reached = d.pose;
    d.force = d.impulse / T;
    d.torque = d.moment / T;
  }
}

void Solver::idleStep() {
  const double h = params_.timeStep / params_.substeps;
  for (int s = 0; s < params_.substeps; ++s) {
    time_ += h;
    ++substeps_;
  }
  std::fill(v_.begin(), v_.end(), Eigen::Vector3d::Zero());
  integrator_->forgetHistory();  // its history is of before it stopped
}

// One pass over the regions computes the goal positions and, when damping is on, the damping
// targets: every sum shares one gather and one scatter (FastLSM's point: region sums cost O(1)
// per particle whatever w, here with the fewest passes over the data).
//
// Goals (Rivers & James 2007, eqs. 3-6), every region sum taken by the summer:
//   c_r = (1/M_r) sum m~_j x_j,   A_r = sum m~_j x_j q_j^T - M_r c_r c0_r^T,   R_r = polar(A_r),
//   T_r x = R_r (x - c0_r) + c_r,  g_i = sum_{r contains i} beta_r T_r q_i / sum beta_r
//        = [ (sum beta_r R_r) q_i + sum beta_r (c_r - R_r c0_r) ] / sum beta_r
// (beta_r = 1 in classic mode, see computeRegionWeights()).
// Positions enter relative to the anchor particle's position xref and rest positions relative to
// the rest centre of mass, which keeps the sums free of cancellation when the object is far away.
//
// Momentum-conserving region damping (Rivers & James 2007, sec. 5): every region's velocities are
// pulled towards the region's rigid motion v_r + omega_r x (x - c_r), where v_r and omega_r keep
// the region's linear and angular momentum (omega_r = I_r^+ L_r); the pulls of all regions
// containing a particle are averaged into dampTarget_. Summed over a region the pull has zero
// linear and angular momentum, so the object's momenta are conserved.
void Solver::regionPass(bool withDamping) {
  passDamping_ = withDamping;
  // Any point of the object keeps the sums O(object size) and gives the same goals up to
  // round-off: the anchor costs nothing, where the centre of mass would be a sweep per sub-step.
  xref_ = x_[anchor_];
  activeSummer_->apply(*this);
}

int Solver::gatherChannels() const { return passDamping_ ? kShapeChannels + kDampingChannels : kShapeChannels; }

int Solver::scatterChannels() const {
  return passDamping_ ? kTransformChannels + kVelocityFieldChannels : kTransformChannels;
}

void Solver::particleData(std::size_t begin, std::size_t end, double* out) {
  detail::withSimd([&] {
    const auto& mt = lattice_->regionMassFractions();
    const int in = gatherChannels();
    for (std::size_t i = begin; i < end; ++i) {
      double* d = out + (i - begin) * in;
      const Eigen::Vector3d p = x_[i] - xref_;
      const Eigen::Vector3d mp = mt[i] * p;
      const Eigen::Vector3d& q = restCentered_[i];
      d[0] = mp.x();
      d[1] = mp.y();
      d[2] = mp.z();
      for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) d[3 + 3 * a + b] = mp[a] * q[b];
      if (passDamping_) {
        const Eigen::Vector3d mv = mt[i] * v_[i];
        const Eigen::Vector3d l = p.cross(mv);
        d[12] = mv.x(); d[13] = mv.y(); d[14] = mv.z();
        d[15] = l.x(); d[16] = l.y(); d[17] = l.z();
        d[18] = mp.x() * p.x(); d[19] = mp.y() * p.y(); d[20] = mp.z() * p.z();
        d[21] = mp.x() * p.y(); d[22] = mp.x() * p.z(); d[23] = mp.y() * p.z();
      }
    }
  });
}

static_assert(sizeof(Eigen::Vector3d) == 3 * sizeof(double), "rest centres as 3 doubles");

void Solver::regionData(std::size_t begin, std::size_t end, const double* sums, double* out) {
  detail::RegionBatchArgs args;
  args.begin = begin;
  args.end = end;
  args.in = gatherChannels();
  args.outK = scatterChannels();
  args.damping = passDamping_;
  args.sums = sums;
  args.mass = regionMass_.data();
  args.invMass = regionInvMass_.data();
  args.weight = regionWeight_.data();
  args.restCenter = regionRestCenter_.data()->data();
  args.quat = rotations_.data()->coeffs().data();
  args.out = out;
  args.angleTolerance = PolarOptions().angleTolerance;
  args.inertiaRankTolerance = kInertiaRankTolerance;
  detail::regionKernels().regionBatch(args);
}

void Solver::particleResult(std::size_t begin, std::size_t end, const double* sums) {
  detail::withSimd([&] {
    const int outK = scatterChannels();
    ExplicitStep* const step = integrating_;
    for (std::size_t i = begin; i < end; ++i) {
      const double* s = sums + (i - begin) * outK;
      const Eigen::Vector3d& q = restCentered_[i];
      Eigen::Vector3d g(s[9], s[10], s[11]);
      for (int a = 0; a < 3; ++a) g[a] += s[3 * a] * q.x() + s[3 * a + 1] * q.y() + s[3 * a + 2] * q.z();
      g = g * invWeightSum_[i] + xref_;
      if (step == nullptr)
        (*goalsOut_)[i] = g;
      else
        step->update(i, g, s);
    }
  });
}

// Ambient damping is mass-proportional (Rayleigh) damping, C = c M, of the motion relative to the
// object's own rigid motion: every vibration mode of angular frequency omega gets the damping
// ratio c / (2 omega), and a falling, thrown or spinning object keeps its momentum (a vibration
// mode of a free object has neither linear nor angular momentum, so its rigid part is zero).
// The rigid motion keeps the object's linear and angular momentum: v_obj(x) = V + W x (x - xref),
// V the centre-of-mass velocity moved to xref, W = I^+ L about the centre of mass. An object the
// world can hold (pinned, dragged or attached, or with colliders in the scene to rest on) is
// damped relative to the world's rigid motion, zero: drag towards rest, as before, so that it
// settles on its supports.
bool Solver::heldByWorld() const { return pinnedCount_ > 0 || !drags_.empty() || !colliders_->map().empty(); }

Solver::RigidMotion Solver::rigidMotion() {
  const auto& m = lattice_->masses();
  xref_ = x_[anchor_];
  double M = 0.0;
  Eigen::Vector3d mx = Eigen::Vector3d::Zero(), mv = Eigen::Vector3d::Zero(), l = Eigen::Vector3d::Zero();
  Eigen::Matrix3d mxx = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < x_.size(); ++i) {
    const Eigen::Vector3d p = x_[i] - xref_;
    M += m[i];
    mx += m[i] * p;
    mv += m[i] * v_[i];
    l += m[i] * p.cross(v_[i]);
    mxx.noalias() += m[i] * p * p.transpose();
  }
  const Eigen::Vector3d c = mx / M, V = mv / M;
  const Eigen::Vector3d L = l - c.cross(mv);                 // about the centre of mass
  const Eigen::Matrix3d P = mxx - M * c * c.transpose();     // second moment about it
  const Eigen::Matrix3d I = P.trace() * Eigen::Matrix3d::Identity() - P;
  RigidMotion rigid;
  rigid.spin = solveInertia(I, L);
  rigid.velocity = V - rigid.spin.cross(c);
  return rigid;
}

// What both integrators do after their velocity update: contact, the prescribed particles, the
// timed forces' countdown and the clock.
void Solver::endSubstep(double h, double elapsed) {
  contactPass(h);
  finishSubstep(h);
  for (TimedForce& f : forces_) f.remaining -= elapsed;
  forces_.erase(std::remove_if(forces_.begin(), forces_.end(),
                               [](const TimedForce& f) { return f.remaining <= 0.0; }),
                forces_.end());
  time_ += elapsed;
  ++substeps_;
}

// The particles the integrator leaves alone: hard-dragged ones follow their target (the
// velocity that reaches it in one sub-step), pinned ones stay.
void Solver::finishSubstep(double h) {
  for (auto& entry : drags_) {
    Drag& drag = entry.second;
    const Eigen::Isometry3d& frame = drag.frame;
    if (drag.stiffness > 0.0) continue;
    for (std::size_t e = 0; e < drag.particles.size(); ++e) {
      const std::uint32_t p = drag.particles[e];
      if (pinned_[p] != 0) continue;
      v_[p] = (frame * drag.offsets[e] - x_[p]) / h;
      x_[p] += h * v_[p];
      // the implicit step counted its impulse from the solve's residual (ImplicitStep::end())
      if (integrating_ != nullptr) integrating_->countDragImpulse(drag, p);
    }
  }
  if (pinnedListStale_) {  // capacity #P, reserved at construction: no allocation here
    pinnedList_.clear();
    for (std::size_t i = 0; i < pinned_.size(); ++i)
      if (pinned_[i] != 0) pinnedList_.push_back(static_cast<std::uint32_t>(i));
    pinnedListStale_ = false;
  }
  for (std::uint32_t p : pinnedList_) {
    v_[p].setZero();
    x_[p] = pinPosition_[p];
  }
}

void Solver::computeGoals(std::vector<Eigen::Vector3d>& goals) {
  goals.resize(x_.size());
  goalsOut_ = &goals;
  regionPass(false);
  goalsOut_ = nullptr;
}

}  // namespace deformable_flsm
