#include "deformable_flsm/core/solver.h"

#include "deformable_flsm/core/polar.h"
#include "deformable_flsm/core/small_matrix.h"
#include "lanes.h"

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
/// Largest region weight beta_r (physical mode). The isotropic weight restores the energy of a
/// region clipped by the surface; a region resolved along one axis only (a rod or sheet a cell
/// thick) would get a weight that stiffens what the lattice cannot represent anyway.
constexpr double kMaxRegionWeight = 4.0;
/// Inertia eigenvalues below this fraction of the largest are treated as zero (a collinear
/// region cannot spin about its own line), so that omega = I^+ L stays finite and exact.
constexpr double kInertiaRankTolerance = 1e-10;
/// Symplectic Euler on u'' = -omega^2 u is stable for (omega h)^2 < 4.
constexpr double kSymplecticEulerLimit = 4.0;
/// Fraction of the stability limit the cap on alpha allows (physical mode): (omega h)^2 <= 2 for the
/// stiffest mode of the linearised update. Half, for what the linearisation does not see (large
/// rotations, drags, contact) and because the bound is on the linearised stiffness at rest.
constexpr double kStabilityMargin = 0.5;
/// Largest volumetric strain |e_i| the Poisson term acts on: the linear law is meant for small
/// strain; beyond, its force stays bounded (a region crushed to a point or stretched tenfold is
/// brought back by shape matching, as in classic FastLSM).
constexpr double kMaxVolumetricStrain = 0.5;

/// omega = I^+ L through the eigen-decomposition: the general case of solveInertia().
[[gnu::noinline]] Eigen::Vector3d solveInertiaByEigen(const Eigen::Matrix3d& I, const Eigen::Vector3d& L) {
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  eig.computeDirect(I);
  const Eigen::Vector3d& lambda = eig.eigenvalues();
  const double cutoff = kInertiaRankTolerance * lambda.cwiseAbs().maxCoeff();
  Eigen::Vector3d inv;
  for (int k = 0; k < 3; ++k) inv[k] = lambda[k] > cutoff ? 1.0 / lambda[k] : 0.0;
  const Eigen::Matrix3d& V = eig.eigenvectors();
  return V * inv.asDiagonal() * (V.transpose() * L);
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

/// Threads to use: `requested`, or every hardware thread for 0.
int resolveThreadCount(int requested) {
  if (requested > 0) return requested;
  return std::max(1, static_cast<int>(std::thread::hardware_concurrency()));
}

/// A rigid transform's rotation is orthonormal with determinant 1 up to round-off; looser than
/// this is a scaled, sheared or mirrored frame, which a rigid body cannot have.
constexpr double kRigidTolerance = 1e-6;

bool isRigid(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  return T.matrix().allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < kRigidTolerance &&
         std::abs(R.determinant() - 1.0) < kRigidTolerance;
}

Eigen::Vector3d centroidOf(const std::vector<Eigen::Vector3d>& x,
                           const std::vector<std::uint32_t>& particles) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::uint32_t p : particles) c += x[p];
  return c / static_cast<double>(particles.size());
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

// Region weights (physical mode only; classic FastLSM has beta_r = 1). Under a uniform strain eps
// region r holds k/2 beta_r sum_{i in r} m~_i q_i^T eps^2 q_i, q_i = x0_i - c0_r, i.e.
// k/2 beta_r tr(eps P_r eps) with P_r = sum m~ q q^T the region's second moment. An interior region
// has P_r = m dx^2 sigma^2 I, sigma^2 = w(w+1)/3 (the calibration behind youngsModulus); a region
// clipped by the surface has less along the clipped axes, which makes material near the surface
// softer than inside. beta_r = m_r dx^2 sigma^2 / p_max, p_max the largest eigenvalue of P_r,
// restores the energy along the region's best-resolved axis (the length of a bar) and never
// inflates a region for the axes the surface cuts short (a trace-based weight did: clipped across
// a slender section it made the bar up to 1.6x too stiff in stretching). Capped at
// kMaxRegionWeight for regions resolved along no axis (a lone particle).
// The forces f_i = k m~_i sum_{r contains i} beta_r (T_r x0_i - x_i) still sum to zero, with zero
// torque, over every region: momentum is conserved as in classic shape matching. Per particle
// that is v += alpha s_i (g_i - x_i) / h with g_i the beta-weighted mean goal,
// s_i = (sum_r beta_r) / n_i.
//
// Poisson's ratio: shape matching alone is a material with lambda = 0; it carries the shear
// modulus (2 mu = E / (1 + nu), through requestedAlpha()). With nu > 0 computeVolumetricForces() adds lambda / 2 (tr eps)^2 per
// cell on the lattice's own stencil (so that a bent section feels the volumetric strain varying
// across it, which a region-wide fit would average away). beta_r restores only the best-resolved
// axis, so a region clipped by the surface lacks D_ra = m_r dx^2 sigma^2 - beta_r P_r,aa of an
// interior region's resistance to the normal strain along lattice axis a. Without lambda that
// hardly shows (a loaded bar does not strain across itself); with it, the sides resist the
// lateral contraction too little, the bar thins more than -nu eps and yields (uniaxial stress
// 1.09 / 1.13 / 1.24 of sigma / E at w = 1 / 2 / 3, nu = 0.3, a bar 4 cells across). So with nu > 0
// each particle's stencil also carries k/2 sum_a D_ia e_aa^2 (e_aa the Green strain along a,
// k = alpha / h^2): the normal-strain energy of every region is then an interior region's, and
// the stretch yields 1.00 / 1.01 / 1.04. Rotation invariant, momentum exact, like the lambda term.
//
// The cap on alpha follows the stability of the sub-step. Linearised about rest, shape matching's
// update is symplectic Euler on M u'' = -K u with (omega h)^2 <= alpha s_i for the modes a particle
// takes part in (Gershgorin on M^-1 K h^2 = alpha (I - goal operator) scaled by s_i), and the
// Poisson term adds (omega h)^2 <= alpha Lambda_i (its own Gershgorin row sum, see below).
// Symplectic Euler is stable for omega h < 2: alpha (s_i + Lambda_i) < 4 for every particle.
// kStabilityMargin keeps a factor from that edge for what linearisation does not see (large
// rotations, contact, drags).
void Solver::computeRegionWeights() {
  const Lattice& L = *lattice_;
  const std::size_t n = L.size();
  regionWeight_.assign(n, 1.0);
  const bool physical = params_.youngsModulus > 0.0;
  volumetric_ = physical && params_.poissonsRatio > 0.0;
  // D_ra = m_r dx^2 sigma^2 - beta_r P_r,aa: what region r lacks of an interior region's second
  // moment along lattice axis a (nu > 0 only, see above)
  std::vector<double> deficit(volumetric_ ? 3 * n : 0, 0.0);
  if (physical) {
    const auto& mt = L.regionMassFractions();
    std::vector<double> second(6 * n), secondSum;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d& q = restCentered_[i];
      double* d = &second[6 * i];
      d[0] = mt[i] * q.x() * q.x();
      d[1] = mt[i] * q.y() * q.y();
      d[2] = mt[i] * q.z() * q.z();
      d[3] = mt[i] * q.x() * q.y();
      d[4] = mt[i] * q.x() * q.z();
      d[5] = mt[i] * q.y() * q.z();
    }
    summer_->gather(second, 6, secondSum);
    const double w = params_.regionHalfWidth;
    const double interior = L.spacing() * L.spacing() * w * (w + 1.0) / 3.0;
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    for (std::size_t r = 0; r < n; ++r) {
      const double* S = &secondSum[6 * r];
      const Eigen::Vector3d& c0 = regionRestCenter_[r];
      const double M = regionMass_[r];
      Eigen::Matrix3d P;
      P << S[0], S[3], S[4], S[3], S[1], S[5], S[4], S[5], S[2];
      P -= M * c0 * c0.transpose();
      eig.computeDirect(P);
      const double pmax = eig.eigenvalues().maxCoeff();
      const double target = L.masses()[r] * interior;
      // pmax <= 0 only for a region of one particle, which has no shape to keep.
      if (pmax > 1e-12 * target) regionWeight_[r] = std::min(kMaxRegionWeight, target / pmax);
      if (volumetric_)
        for (int a = 0; a < 3; ++a) deficit[3 * r + a] = std::max(0.0, target - regionWeight_[r] * P(a, a));
    }
  }
  if (volumetric_) {
    stencil_.resize(n);
    stencilForce_.resize(n);
    volumetricAccel_.assign(n, Eigen::Vector3d::Zero());
    for (std::size_t i = 0; i < n; ++i) {
      VolumetricStencil& st = stencil_[i];
      for (int a = 0; a < 3; ++a) {
        const std::int32_t p = L.neighbor(i, a, true), m = L.neighbor(i, a, false);
        const auto self = static_cast<std::uint32_t>(i);
        st.plus[a] = p != Lattice::kNone ? static_cast<std::uint32_t>(p) : self;
        st.minus[a] = m != Lattice::kNone ? static_cast<std::uint32_t>(m) : self;
        const int span = (p != Lattice::kNone) + (m != Lattice::kNone);
        st.invDistance[a] = span == 0 ? 0.0 : 1.0 / (span * L.spacing());
      }
      // A stencil acts on its members with a force proportional to its weight, and a member's
      // acceleration is that over its own mass: a full cell's stencil would shake a neighbour
      // that is a sliver of a cell (fill fraction ~0.01 at a curved surface) and force the cap
      // on alpha down by as much. So each stencil weighs with its lightest member's mass: the
      // stiffness per unit mass stays an interior cell's, and the energy (and with it momentum
      // and rotation invariance) stays exact; only the cells next to slivers are softer.
      double lightest = L.masses()[i];
      for (int a = 0; a < 3; ++a)
        lightest = std::min({lightest, L.masses()[st.plus[a]], L.masses()[st.minus[a]]});
      st.mass = lightest;
      for (int a = 0; a < 3; ++a) deficit[3 * i + a] *= lightest / L.masses()[i];
    }
  }
  std::vector<double> weightSum;
  summer_->scatter(regionWeight_, 1, weightSum);
  invWeightSum_.resize(n);
  stiffnessFactor_.resize(n);
  double maxFactor = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    invWeightSum_[i] = 1.0 / weightSum[i];
    stiffnessFactor_[i] = weightSum[i] * invCount_[i];
    maxFactor = std::max(maxFactor, stiffnessFactor_[i]);
  }
  const double requested = params_.requestedAlpha(L.spacing());
  if (!physical) {
    // classic FastLSM: alpha = stiffness, s_i = 1
    alphaCap_ = params_.stiffness / maxFactor;
    alpha_ = std::min(alphaCap_, requested);
    return;
  }
  // Gershgorin row sums of the Poisson term's h^2 M^-1 K at rest, per unit alpha: with
  // lambda_eff = lambda alpha / requested (the cap softens both terms alike, nu is kept),
  // h^2 lambda_eff V_i' |dE/dx| sums to alpha Lambda_j, Lambda_j = lambda h^2 / (requested m_j)
  // max_a sum_{i' : j in the stencil of i' along a} V_i' / d_i'a * sum_b 2 / d_i'b.
  // The surface term k/2 D_ia e_aa^2 adds 2 k D_ia / d_ia^2 to the rows of both ends of the
  // stencil, h^2 k = alpha: alpha times deficitRow_j / m_j.
  std::vector<double> lambdaRow(3 * n, 0.0), deficitRow(3 * n, 0.0);
  if (volumetric_) {
    for (std::size_t i = 0; i < n; ++i) {
      const VolumetricStencil& st = stencil_[i];
      const double span = 2.0 * (st.invDistance[0] + st.invDistance[1] + st.invDistance[2]);
      const double V = st.mass / params_.density;
      for (int a = 0; a < 3; ++a) {
        if (st.invDistance[a] == 0.0) continue;
        lambdaRow[3 * st.plus[a] + a] += V * st.invDistance[a] * span;
        lambdaRow[3 * st.minus[a] + a] += V * st.invDistance[a] * span;
        const double d = 2.0 * deficit[3 * i + a] * st.invDistance[a] * st.invDistance[a];
        deficitRow[3 * st.plus[a] + a] += d;
        deficitRow[3 * st.minus[a] + a] += d;
      }
    }
  }
  const double h = params_.substepLength();
  const double lambdaScale = params_.lameLambda() * h * h / requested;
  double maxBound = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    double row = 0.0;
    for (int a = 0; a < 3; ++a) row = std::max(row, lambdaScale * lambdaRow[3 * i + a] + deficitRow[3 * i + a]);
    maxBound = std::max(maxBound, stiffnessFactor_[i] + row / L.masses()[i]);
  }
  // alpha (s_i + Lambda_i) <= stiffness * margin * 4 for every particle
  alphaCap_ = params_.stiffness * kStabilityMargin * kSymplecticEulerLimit / maxBound;
  alpha_ = std::min(alphaCap_, requested);
  if (volumetric_) {
    const double lambdaEff = params_.lameLambda() * alpha_ / requested;
    const double k = alpha_ / (h * h);
    for (std::size_t i = 0; i < n; ++i) {
      stencil_[i].weight = lambdaEff * stencil_[i].mass / params_.density;
      // (an axis without neighbours has invDistance 0, which zeroes its force)
      for (int a = 0; a < 3; ++a) stencil_[i].deficit[a] = k * deficit[3 * i + a];
    }
  }
}

// Poisson term on the lattice stencil: E_vol = sum_i lambda/2 V_i e_i^2 with e_i the trace of the
// Green strain (F^T F - I) / 2 at particle i, F_i's column a the central (one-sided at the surface)
// difference of the neighbours along a. Rotation invariant, so the forces conserve linear and
// angular momentum exactly; f_j = -sum_{i,a} G_ia ([plus(i,a) = j] - [minus(i,a) = j]),
// G_ia = lambda V_i e_i F_ia / d_ia.
void Solver::computeVolumetricForces() {
  const std::size_t n = x_.size();
  for (std::size_t i = 0; i < n; ++i) {
    const VolumetricStencil& st = stencil_[i];
    Eigen::Vector3d F[3];
    double e = 0.0, eaa[3] = {0.0, 0.0, 0.0};
    for (int a = 0; a < 3; ++a) {
      F[a] = (x_[st.plus[a]] - x_[st.minus[a]]) * st.invDistance[a];
      if (st.invDistance[a] > 0.0) eaa[a] = 0.5 * (F[a].squaredNorm() - 1.0);
      e += eaa[a];
    }
    e = std::clamp(e, -kMaxVolumetricStrain, kMaxVolumetricStrain);
    for (int a = 0; a < 3; ++a) {
      const double ea = std::clamp(eaa[a], -kMaxVolumetricStrain, kMaxVolumetricStrain);
      stencilForce_[i][a] = ((st.weight * e + st.deficit[a] * ea) * st.invDistance[a]) * F[a];
    }
  }
  std::fill(volumetricAccel_.begin(), volumetricAccel_.end(), Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    const VolumetricStencil& st = stencil_[i];
    for (int a = 0; a < 3; ++a) {
      volumetricAccel_[st.plus[a]] -= stencilForce_[i][a];
      volumetricAccel_[st.minus[a]] += stencilForce_[i][a];
    }
  }
  const auto& m = lattice_->masses();
  for (std::size_t i = 0; i < n; ++i) volumetricAccel_[i] /= m[i];
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
}

bool Solver::stiffnessSaturated() const {
  return params_.requestedAlpha(lattice_->spacing()) > alphaCap_;
}

void Solver::reset() {
  x_ = lattice_->restPositions();
  std::fill(v_.begin(), v_.end(), Eigen::Vector3d::Zero());
  std::fill(rotations_.begin(), rotations_.end(), Eigen::Quaterniond::Identity());
  pinPosition_ = x_;
  drags_.clear();
  dragFrames_.clear();
  markHardDrags();
  forces_.clear();
  std::fill(impulseDv_.begin(), impulseDv_.end(), Eigen::Vector3d::Zero());
  impulsePending_ = false;
  frameRotation_.setIdentity();
  for (ContactBody& body : contactBodies_) body.wrench = ContactWrench();
  time_ = 0.0;
  substeps_ = 0;
}

void Solver::setPositions(const std::vector<Eigen::Vector3d>& x) {
  if (x.size() != x_.size()) throw std::invalid_argument("solver: setPositions with the wrong size");
  x_ = x;
}

void Solver::setVelocities(const std::vector<Eigen::Vector3d>& v) {
  if (v.size() != v_.size()) throw std::invalid_argument("solver: setVelocities with the wrong size");
  v_ = v;
}

void Solver::makeSummers() {
  singleSummer_.reset();
  governor_ = ThreadGovernor();
  if (params_.kind == SolverKind::Fast) {
    if (threads_ > 1) {
      // Each used only when the governor says so, possibly first in the middle of a run: no
      // allocation then.
      const int Kg = kShapeChannels + kDampingChannels, Ks = kTransformChannels + kVelocityFieldChannels;
      auto threaded = std::make_unique<SliceStreamSummer>(*lattice_, threads_);
      threaded->reserve(Kg, Ks);
      summer_ = std::move(threaded);
      auto single = std::make_unique<SliceStreamSummer>(*lattice_, 1);
      single->reserve(Kg, Ks);
      singleSummer_ = std::move(single);
    } else {
      summer_ = std::make_unique<SliceStreamSummer>(*lattice_, threads_);
    }
  } else {
    summer_ = std::make_unique<NaiveSummer>(*lattice_);
  }
  activeSummer_ = summer_.get();
}

Eigen::Vector3d Drag::centroidTarget() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& o : offsets) c += o;
  if (!offsets.empty()) c /= static_cast<double>(offsets.size());
  return pose * c;
}

void Solver::step() {
  const double h = params_.timeStep / params_.substeps;
  // With threads, each step runs on the threads or on one thread, whichever has been faster
  // lately (ThreadGovernor): the same sums in the same order either way, so the results do not
  // depend on the choice.
  const bool timed = singleSummer_ != nullptr;
  activeSummer_ = timed && !governor_.threaded() ? singleSummer_.get() : summer_.get();
  const auto t0 = timed ? std::chrono::steady_clock::now() : std::chrono::steady_clock::time_point();
  beginContactStep();
  for (int s = 0; s < params_.substeps; ++s) {
    interpolateDragFrames(static_cast<double>(s + 1) / params_.substeps);
    if (params_.integrator == Integrator::Implicit)
      implicitSubstep(h);
    else
      substep(h);
  }
  endContactStep();
  if (timed) {
    governor_.record(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    activeSummer_ = summer_.get();
  }
  for (auto& entry : drags_) entry.second.reached = entry.second.pose;
}

// A drag frame moved by moveDrag() between two steps goes there over the sub-steps of the next
// step: translation linearly and rotation along the shortest arc (slerp), i.e. at a constant
// linear and angular velocity, the velocity a body moving from one pose to the next has.
void Solver::interpolateDragFrames(double s) {
  std::size_t k = 0;
  for (const auto& entry : drags_) {
    const Drag& drag = entry.second;
    Eigen::Isometry3d& frame = dragFrames_[k++];
    if (s >= 1.0) {
      frame = drag.pose;
      continue;
    }
    const Eigen::Quaterniond from(drag.reached.linear()), to(drag.pose.linear());
    frame.linear() = from.slerp(s, to).toRotationMatrix();
    frame.translation() = drag.reached.translation() + s * (drag.pose.translation() - drag.reached.translation());
  }
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
}

static_assert(kRotationBatch == kLanes, "one region per SIMD lane");

void Solver::regionData(std::size_t begin, std::size_t end, const double* sums, double* out) {
  const int in = gatherChannels(), outK = scatterChannels();
  // Regions in batches of kRotationBatch, one SIMD lane each: the rotations are extracted
  // together, and the damping field's inertia solve runs in the lanes too.
  for (std::size_t r0 = begin; r0 < end; r0 += kRotationBatch) {
    const int count = static_cast<int>(std::min<std::size_t>(kRotationBatch, end - r0));
    double A[kRotationBatch * 9], R[kRotationBatch * 9];
    Lanes c[3] = {}, c0[3] = {}, beta = {}, M = {}, iM = {};
    for (int l = 0; l < count; ++l) {
      const std::size_t r = r0 + static_cast<std::size_t>(l);
      const double* s = sums + (r - begin) * in;
      M[l] = regionMass_[r];
      iM[l] = regionInvMass_[r];
      beta[l] = regionWeight_[r];
      for (int i = 0; i < 3; ++i) {
        c[i][l] = s[i] * iM[l];
        c0[i][l] = regionRestCenter_[r][i];
      }
      // A = sum m~ p q^T - M c c0^T (row-major)
      for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) A[9 * l + 3 * i + j] = s[3 + 3 * i + j] - M[l] * c[i][l] * c0[j][l];
    }
    extractRotationBatch(count, A, rotations_.data() + r0, R);
    for (int l = 0; l < count; ++l) {
      double* t = out + (r0 + static_cast<std::size_t>(l) - begin) * outK;
      const double* Rl = R + 9 * l;
      for (int i = 0; i < 3; ++i) {
        for (int j = 0; j < 3; ++j) t[3 * i + j] = beta[l] * Rl[3 * i + j];
        t[9 + i] = beta[l] * (c[i][l] - (Rl[3 * i] * c0[0][l] + Rl[3 * i + 1] * c0[1][l] + Rl[3 * i + 2] * c0[2][l]));
      }
    }
    if (!passDamping_) continue;
    // Rigid velocity field u + w x p of each region: v_r = sum m~ v / M, angular momentum about c
    // L_r = sum p x m~ v - c x sum m~ v, second moment about c P = sum m~ p p^T - M c c^T,
    // inertia I = tr(P) 1 - P, w = I^+ L_r (solveInertia(): the cofactor solve here, lanes that
    // are not clearly positive definite go to the general routine), u = v_r - w x c.
    Lanes mv[3] = {}, l[3] = {}, pp[6] = {};
    for (int k = 0; k < count; ++k) {
      const double* s = sums + (r0 + static_cast<std::size_t>(k) - begin) * in;
      for (int i = 0; i < 3; ++i) {
        mv[i][k] = s[12 + i];
        l[i][k] = s[15 + i];
      }
      for (int i = 0; i < 6; ++i) pp[i][k] = s[18 + i];
    }
    Lanes vr[3], L[3];
    for (int i = 0; i < 3; ++i) vr[i] = mv[i] * iM;
    L[0] = l[0] - (c[1] * mv[2] - c[2] * mv[1]);
    L[1] = l[1] - (c[2] * mv[0] - c[0] * mv[2]);
    L[2] = l[2] - (c[0] * mv[1] - c[1] * mv[0]);
    const Lanes p00 = pp[0] - M * c[0] * c[0], p11 = pp[1] - M * c[1] * c[1], p22 = pp[2] - M * c[2] * c[2];
    const Lanes p01 = pp[3] - M * c[0] * c[1], p02 = pp[4] - M * c[0] * c[2], p12 = pp[5] - M * c[1] * c[2];
    const Lanes h00 = p11 + p22, h11 = p00 + p22, h22 = p00 + p11, h01 = -p01, h02 = -p02, h12 = -p12;
    const Lanes trace = h00 + h11 + h22;
    const Lanes tol = kInertiaRankTolerance * trace;
    const Lanes zero = {};
    Lanes w[3];
    LaneMask positive;
    solveSymmetricPositive3(h00, h11, h22, h01, h02, h12, L, tol, w, positive);
    const LaneMask fast = (trace > zero) & positive;
    for (int k = 0; k < count; ++k) {
      if (fast[k] != 0) continue;
      Eigen::Matrix3d I;
      I << h00[k], h01[k], h02[k], h01[k], h11[k], h12[k], h02[k], h12[k], h22[k];
      const Eigen::Vector3d wk = solveInertia(I, Eigen::Vector3d(L[0][k], L[1][k], L[2][k]));
      for (int i = 0; i < 3; ++i) w[i][k] = wk[i];
    }
    Lanes u[3];
    u[0] = vr[0] - (w[1] * c[2] - w[2] * c[1]);
    u[1] = vr[1] - (w[2] * c[0] - w[0] * c[2]);
    u[2] = vr[2] - (w[0] * c[1] - w[1] * c[0]);
    for (int k = 0; k < count; ++k) {
      double* t = out + (r0 + static_cast<std::size_t>(k) - begin) * outK;
      for (int i = 0; i < 3; ++i) {
        t[12 + i] = u[i][k];
        t[15 + i] = w[i][k];
      }
    }
  }
}

void Solver::particleResult(std::size_t begin, std::size_t end, const double* sums) {
  const int outK = scatterChannels();
  const StepConstants& k = step_;
  for (std::size_t i = begin; i < end; ++i) {
    const double* s = sums + (i - begin) * outK;
    const Eigen::Vector3d& q = restCentered_[i];
    Eigen::Vector3d g(s[9], s[10], s[11]);
    for (int a = 0; a < 3; ++a) g[a] += s[3 * a] * q.x() + s[3 * a + 1] * q.y() + s[3 * a + 2] * q.z();
    g = g * invWeightSum_[i] + xref_;
    if (!k.integrate) {
      (*goalsOut_)[i] = g;
      continue;
    }
    // v <- v_obj + keep (v - v_obj) + alpha s_i (g - x) / h + h (gravity + f / m) + kd (v_rigid - v);
    // x <- x + h v
    // (a pinned or hard-dragged particle is left to finishSubstep())
    if (pinned_[i] != 0 || hardDragged_[i] != 0) continue;
    Eigen::Vector3d a = params_.gravity;
    if (k.forced) a += forceAccel_[i];
    if (volumetric_) a += volumetricAccel_[i];
    Eigen::Vector3d dv = k.pull * stiffnessFactor_[i] * (g - x_[i]) + k.h * a;
    if (passDamping_) {
      const Eigen::Vector3d p = x_[i] - xref_;
      const Eigen::Vector3d target =
          (Eigen::Vector3d(s[12], s[13], s[14]) + Eigen::Vector3d(s[15], s[16], s[17]).cross(p)) * invCount_[i];
      dv += k.kd * (target - v_[i]);
    }
    if (k.relative) {
      // ambient damping of the motion relative to the object's rigid motion (computeRigidMotion())
      const Eigen::Vector3d rigid = rigidVelocity_ + rigidSpin_.cross(x_[i] - xref_);
      v_[i] = rigid + k.keep * (v_[i] - rigid) + dv;
    } else {
      v_[i] = (v_[i] + dv) * k.keep;  // held by the world: drag towards rest
    }
    x_[i] += k.h * v_[i];
  }
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
bool Solver::heldByWorld() const { return pinnedCount_ > 0 || !drags_.empty() || !colliders_.empty(); }

void Solver::computeRigidMotion() {
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
  rigidSpin_ = solveInertia(I, L);
  rigidVelocity_ = V - rigidSpin_.cross(c);
}

void Solver::accumulateForces(double h) {
  // Clear only what the last sub-step wrote: with no force and no spring drag (the usual case)
  // this costs nothing.
  for (std::uint32_t p : forcedParticles_) forceAccel_[p].setZero();
  forcedParticles_.clear();
  const auto& m = lattice_->masses();
  for (const TimedForce& f : forces_) {
    double M = 0.0;
    for (std::uint32_t p : f.particles) M += m[p];
    // The last sub-step of a force applies only its remaining fraction, so that the delivered
    // impulse is exactly force * duration.
    const Eigen::Vector3d a = f.force / M * std::min(1.0, f.remaining / h);
    for (std::uint32_t p : f.particles) forceAccel_[p] += a;
    forcedParticles_.insert(forcedParticles_.end(), f.particles.begin(), f.particles.end());
  }
  std::size_t k = 0;
  for (const auto& entry : drags_) {
    const Drag& drag = entry.second;
    const Eigen::Isometry3d& frame = dragFrames_[k++];
    if (drag.stiffness <= 0.0) continue;
    double M = 0.0;
    for (std::uint32_t p : drag.particles) M += m[p];
    // total stiffness k shared by mass: particle force k m_i / M (target_i - x_i)
    const double k = drag.stiffness / M;
    for (std::size_t e = 0; e < drag.particles.size(); ++e) {
      const std::uint32_t p = drag.particles[e];
      forceAccel_[p] += k * (frame * drag.offsets[e] - x_[p]);
    }
    forcedParticles_.insert(forcedParticles_.end(), drag.particles.begin(), drag.particles.end());
  }
}

// One sub-step of FastLSM dynamics (Rivers & James 2007, eq. 7):
//   v <- v + alpha (g - x) / h + h f / m,   damping,   x <- x + h v.
// Shape matching and both dampings act on the state at the start of the sub-step:
//   v <- v_obj + keep (v - v_obj) + alpha s_i (g - x) / h + h f / m + kd (v_rigid(v) - v)
// with v_obj the object's rigid motion; v <- (v + ...) keep when held by the world (see
// computeRigidMotion()).
// The update of each particle is the last step of the region pass (particleResult()), done as
// soon as its goal is known: the state is read and written in one sweep over the lattice.
void Solver::substep(double h) {
  const std::size_t n = x_.size();
  if (impulsePending_) {
    for (std::size_t i = 0; i < n; ++i) v_[i] += impulseDv_[i];
    std::fill(impulseDv_.begin(), impulseDv_.end(), Eigen::Vector3d::Zero());
    impulsePending_ = false;
  }
  accumulateForces(h);
  step_.integrate = true;
  step_.h = h;
  step_.kd = 1.0 - std::exp(-params_.damping * h);
  step_.pull = alpha_ / h;
  step_.keep = std::exp(-params_.ambientDamping * h);
  step_.relative = params_.ambientDamping > 0.0 && !heldByWorld();
  step_.forced = !forcedParticles_.empty();
  if (step_.relative) computeRigidMotion();
  if (volumetric_) computeVolumetricForces();
  regionPass(step_.kd > 0.0);
  step_.integrate = false;
  contactPass(h);
  finishSubstep(h);
  for (TimedForce& f : forces_) f.remaining -= h;
  forces_.erase(std::remove_if(forces_.begin(), forces_.end(),
                               [](const TimedForce& f) { return f.remaining <= 0.0; }),
                forces_.end());
  time_ += h;
  ++substeps_;
}

// The particles particleResult() leaves alone: hard-dragged ones follow their target (the
// velocity that reaches it in one sub-step), pinned ones stay.
void Solver::finishSubstep(double h) {
  std::size_t k = 0;
  for (const auto& entry : drags_) {
    const Drag& drag = entry.second;
    const Eigen::Isometry3d& frame = dragFrames_[k++];
    if (drag.stiffness > 0.0) continue;
    for (std::size_t e = 0; e < drag.particles.size(); ++e) {
      const std::uint32_t p = drag.particles[e];
      if (pinned_[p] != 0) continue;
      v_[p] = (frame * drag.offsets[e] - x_[p]) / h;
      x_[p] += h * v_[p];
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

std::size_t Solver::pinBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, bool pinned) {
  const auto& x0 = lattice_->restPositions();
  std::size_t count = 0;
  for (std::size_t i = 0; i < x0.size(); ++i) {
    if ((x0[i].array() >= lo.array()).all() && (x0[i].array() <= hi.array()).all()) {
      setPinned(static_cast<std::uint32_t>(i), pinned);
      ++count;
    }
  }
  return count;
}

void Solver::setPinned(std::uint32_t particle, bool pinned) {
  if (particle >= pinned_.size()) throw std::out_of_range("solver: particle index out of range");
  if (pinned && !pinned_[particle]) {
    pinPosition_[particle] = x_[particle];
    v_[particle].setZero();
  }
  if (pinned != (pinned_[particle] != 0)) pinned ? ++pinnedCount_ : --pinnedCount_;
  pinned_[particle] = pinned ? 1 : 0;
  pinnedListStale_ = true;
}

std::size_t Solver::pinnedCount() const {
  return static_cast<std::size_t>(std::count(pinned_.begin(), pinned_.end(), 1));
}

void Solver::grab(const std::string& id, const std::vector<std::uint32_t>& particles,
                  const Eigen::Vector3d& target, double stiffness) {
  if (!target.allFinite()) throw std::invalid_argument("solver: drag target must be finite");
  if (particles.empty()) throw std::invalid_argument("solver: a drag needs at least one particle");
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  // The drag frame sits at the centroid, unrotated: offsets are relative to the centroid, and
  // the frame glides from there to `target` over the first step.
  const Eigen::Isometry3d frame(Eigen::Translation3d(centroidOf(x_, particles)));
  addDrag(id, particles, frame, Eigen::Isometry3d(Eigen::Translation3d(target)), stiffness);
}

void Solver::attach(const std::string& id, const std::vector<std::uint32_t>& particles,
                    const Eigen::Isometry3d& frame, double stiffness) {
  if (!isRigid(frame))
    throw std::invalid_argument("solver: the frame to attach to must be finite and rigid (a rotation "
                                "and a translation)");
  addDrag(id, particles, frame, frame, stiffness);
}

void Solver::addDrag(const std::string& id, const std::vector<std::uint32_t>& particles,
                     const Eigen::Isometry3d& frame, const Eigen::Isometry3d& pose, double stiffness) {
  if (particles.empty()) throw std::invalid_argument("solver: a drag needs at least one particle");
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  if (!std::isfinite(stiffness) || stiffness < 0.0)
    throw std::invalid_argument("solver: drag stiffness must be finite and >= 0");
  Drag drag;
  drag.particles = particles;
  const Eigen::Isometry3d toFrame = frame.inverse(Eigen::Isometry);
  drag.offsets.reserve(particles.size());
  for (std::uint32_t p : particles) drag.offsets.push_back(toFrame * x_[p]);
  drag.pose = pose;
  drag.reached = frame;
  drag.stiffness = stiffness;
  drags_[id] = std::move(drag);
  dragFrames_.resize(drags_.size());
  markHardDrags();
  reserveForcedParticles();
}

// accumulateForces() lists the particles it touches; reserving here, when a command arrives,
// keeps the step itself free of allocation.
void Solver::reserveForcedParticles() {
  std::size_t total = 0;
  for (const TimedForce& f : forces_) total += f.particles.size();
  for (const auto& entry : drags_) total += entry.second.particles.size();
  forcedParticles_.reserve(total);
}

bool Solver::moveDrag(const std::string& id, const Eigen::Isometry3d& pose) {
  auto it = drags_.find(id);
  if (it == drags_.end()) return false;
  if (!isRigid(pose))
    throw std::invalid_argument("solver: a drag pose must be finite and rigid (a rotation and a "
                                "translation)");
  it->second.pose = pose;
  return true;
}

bool Solver::moveDrag(const std::string& id, const Eigen::Vector3d& target) {
  auto it = drags_.find(id);
  if (it == drags_.end()) return false;
  if (!target.allFinite()) throw std::invalid_argument("solver: drag target must be finite");
  it->second.pose.translation() = target;
  return true;
}

bool Solver::release(const std::string& id) {
  const bool found = drags_.erase(id) > 0;
  dragFrames_.resize(drags_.size());
  markHardDrags();
  return found;
}

void Solver::releaseAll() {
  drags_.clear();
  dragFrames_.clear();
  markHardDrags();
}

void Solver::markHardDrags() {
  std::fill(hardDragged_.begin(), hardDragged_.end(), 0);
  for (const auto& entry : drags_)
    if (entry.second.stiffness <= 0.0)
      for (std::uint32_t p : entry.second.particles) hardDragged_[p] = 1;
}

void Solver::applyImpulse(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& impulse) {
  if (particles.empty()) throw std::invalid_argument("solver: an impulse needs at least one particle");
  if (!impulse.allFinite()) throw std::invalid_argument("solver: impulse must be finite");
  const auto& m = lattice_->masses();
  double M = 0.0;
  for (std::uint32_t p : particles) {
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
    M += m[p];
  }
  for (std::uint32_t p : particles) impulseDv_[p] += impulse / M;
  impulsePending_ = true;
}

void Solver::applyForce(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& force,
                        double duration) {
  if (particles.empty()) throw std::invalid_argument("solver: a force needs at least one particle");
  if (!force.allFinite()) throw std::invalid_argument("solver: force must be finite");
  if (!(duration > 0.0) || !std::isfinite(duration))
    throw std::invalid_argument("solver: force duration must be finite and > 0");
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  forces_.push_back(TimedForce{particles, force, duration});
  reserveForcedParticles();
}

std::vector<std::uint32_t> Solver::nearestParticles(const Eigen::Vector3d& point, std::size_t count) const {
  std::vector<std::uint32_t> idx(x_.size());
  std::iota(idx.begin(), idx.end(), 0u);
  count = std::min(count, idx.size());
  auto closer = [&](std::uint32_t a, std::uint32_t b) {
    return (x_[a] - point).squaredNorm() < (x_[b] - point).squaredNorm();
  };
  std::partial_sort(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(count), idx.end(), closer);
  idx.resize(count);
  return idx;
}

std::vector<std::uint32_t> Solver::particlesWithin(const Eigen::Vector3d& point, double radius) const {
  std::vector<std::uint32_t> out;
  const double r2 = radius * radius;
  for (std::size_t i = 0; i < x_.size(); ++i)
    if ((x_[i] - point).squaredNorm() <= r2) out.push_back(static_cast<std::uint32_t>(i));
  return out;
}

double Solver::kineticEnergy() const {
  const auto& m = lattice_->masses();
  double e = 0.0;
  for (std::size_t i = 0; i < v_.size(); ++i) e += 0.5 * m[i] * v_[i].squaredNorm();
  return e;
}

Eigen::Vector3d Solver::linearMomentum() const {
  const auto& m = lattice_->masses();
  Eigen::Vector3d P = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < v_.size(); ++i) P += m[i] * v_[i];
  return P;
}

Eigen::Vector3d Solver::angularMomentum() const {
  const auto& m = lattice_->masses();
  Eigen::Vector3d L = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < v_.size(); ++i) L += m[i] * x_[i].cross(v_[i]);
  return L;
}

double Solver::maxDisplacement() const {
  const auto& x0 = lattice_->restPositions();
  double d = 0.0;
  for (std::size_t i = 0; i < x_.size(); ++i) d = std::max(d, (x_[i] - x0[i]).squaredNorm());
  return std::sqrt(d);
}

Eigen::Isometry3d Solver::rigidFrame() const {
  const auto& m = lattice_->masses();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < x_.size(); ++i) c += m[i] * x_[i];
  c /= lattice_->totalMass();
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < x_.size(); ++i) A.noalias() += m[i] * (x_[i] - c) * restCentered_[i].transpose();
  const Eigen::Matrix3d R = extractRotation(A, frameRotation_);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = c - R * restCom_;
  return T;
}

double Solver::shapeError() const {
  const Eigen::Isometry3d T = rigidFrame();
  const auto& x0 = lattice_->restPositions();
  double e = 0.0;
  for (std::size_t i = 0; i < x_.size(); ++i) e += (x_[i] - T * x0[i]).squaredNorm();
  return std::sqrt(e / static_cast<double>(x_.size()));
}

bool Solver::hasPendingCommands() const { return !drags_.empty() || !forces_.empty() || impulsePending_; }

}  // namespace deformable_flsm
