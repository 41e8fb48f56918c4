// The solver's material calibration: the region weights beta_r, the Poisson term on the lattice
// stencil, and the cap on alpha that keeps the sub-step stable (see computeRegionWeights()).
#include "deformable_flsm/core/solver.h"

#include "simd_dispatch.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

namespace {

/// Largest region weight beta_r (physical mode). The isotropic weight restores the energy of a
/// region clipped by the surface; a region resolved along one axis only (a rod or sheet a cell
/// thick) would get a weight that stiffens what the lattice cannot represent anyway.
constexpr double kMaxRegionWeight = 4.0;
/// Symplectic Euler on u'' = -omega^2 u whose velocity keeps the factor `keep` each sub-step
/// (v' = keep v - omega^2 h x, x' = x + h v') is stable for (omega h)^2 < 2 (1 + keep), keep in
/// (-1, 1]: 4 undamped, 2 where the damping takes all the velocity, less where two dampings
/// together take more than all of it (the characteristic polynomial
/// z^2 - (1 + keep - (omega h)^2) z + keep; Jury's conditions).
double symplecticEulerLimit(double keep) { return 2.0 * (1.0 + keep); }
/// Fraction of the stability limit the cap on alpha allows (physical mode): (omega h)^2 <= 1 + keep
/// (2 undamped) for the stiffest mode of the linearised update. Half, for what the linearisation
/// does not see (large rotations, drags, contact) and because the bound is on the linearised
/// stiffness at rest.
constexpr double kStabilityMargin = 0.5;
/// Largest volumetric strain |e_i| the Poisson term acts on: the linear law is meant for small
/// strain; beyond, its force stays bounded (a region crushed to a point or stretched tenfold is
/// brought back by shape matching, as in classic FastLSM).
constexpr double kMaxVolumetricStrain = 0.5;

}  // namespace

// Region weights (physical mode only; classic FastLSM has beta_r = 1). Under a uniform strain eps
// region r holds k/2 beta_r sum_{i in r} m~_i q_i^T eps^2 q_i, q_i = x0_i - c0_r, i.e.
// k/2 beta_r tr(eps P_r eps) with P_r = sum m~ q q^T the region's second moment. An interior region
// has P_r = m dx^2 sigma^2 I, sigma^2 = w(w+1)/3 (the calibration behind youngsModulus); a region
// clipped by the surface has less along the clipped axes, which makes material near the surface
// softer than inside. beta_r = m_r dx^2 sigma^2 / p_max, p_max the largest eigenvalue of P_r,
// restores the energy along the region's best-resolved axis (the length of a bar) and never
// inflates a region for the axes the surface cuts short (a weight from the trace of P_r would:
// clipped across a slender section, the bar would come out too stiff in stretching). Capped at
// kMaxRegionWeight for regions resolved along no axis (a lone particle).
// The forces f_i = k m~_i sum_{r contains i} beta_r (T_r x0_i - x_i) still sum to zero, with zero
// torque, over every region: momentum is conserved as in classic shape matching. Per particle
// that is v += alpha s_i (g_i - x_i) / h with g_i the beta-weighted mean goal,
// s_i = (sum_r beta_r) / n_i.
//
// Poisson's ratio: shape matching alone is a material with lambda = 0; it carries the shear
// modulus (2 mu = E / (1 + nu), through requestedAlpha()). With nu > 0 computeVolumetricForces()
// adds lambda / 2 (tr eps)^2 per cell on the lattice's own stencil (so that a bent section feels
// the volumetric strain varying across it, which a region-wide fit would average away). beta_r
// restores only the best-resolved axis, so a region clipped by the surface lacks
// D_ra = m_r dx^2 sigma^2 - beta_r P_r,aa of an interior region's resistance to the normal strain
// along lattice axis a. Without lambda that hardly shows (a loaded bar does not strain across
// itself); with it, the sides resist the lateral contraction too little, and a bar under uniaxial
// stress thins more than -nu eps and yields. So with nu > 0 each particle's stencil also carries
// k/2 sum_a D_ia e_aa^2 (e_aa the Green strain along a, k = alpha / h^2): the normal-strain energy
// of every region is then an interior region's (the stretch with and without it:
// docs/method.md). Rotation invariant, momentum exact, like the lambda term.
//
// The cap on alpha follows the stability of the sub-step. Linearised about rest, shape matching's
// update is symplectic Euler on M u'' = -K u with (omega h)^2 <= alpha s_i for the modes a particle
// takes part in (Gershgorin on M^-1 K h^2 = alpha (I - goal operator) scaled by s_i), and the
// Poisson term adds (omega h)^2 <= alpha Lambda_i (its own Gershgorin row sum, see below).
// Symplectic Euler is stable for omega h < 2: alpha (s_i + Lambda_i) < 4 for every particle;
// with damping keeping the factor keep of the velocity, alpha (s_i + Lambda_i) < 2 (1 + keep).
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
  if (physical) weighRegions(deficit);
  if (volumetric_) buildStencils(deficit);
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
  capPhysicalAlpha(requested, deficit);
}

// beta_r: each region's weight that gives it an interior region's second moment (see above);
// with nu > 0, D_ra into `deficit`.
void Solver::weighRegions(std::vector<double>& deficit) {
  const Lattice& L = *lattice_;
  const std::size_t n = L.size();
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

// The Poisson term's stencils: each particle's neighbours along the lattice axes and its
// stencil's mass; `deficit` scaled to it.
void Solver::buildStencils(std::vector<double>& deficit) {
  const Lattice& L = *lattice_;
  const std::size_t n = L.size();
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

// The cap on alpha with the material's modulus (the Poisson term and the surface term in the
// bound), alpha_, and the stencils' weights at alpha_.
void Solver::capPhysicalAlpha(double requested, const std::vector<double>& deficit) {
  const Lattice& L = *lattice_;
  const std::size_t n = L.size();
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
  // alpha (s_i + Lambda_i) <= stiffness * margin * 2 (1 + keep) for every particle (4 undamped).
  // A free object's sub-step keeps keep = exp(-c h) - kd of the velocity of its stiffest modes:
  // ambient damping c keeps exp(-c h) of the motion relative to the object's rigid motion, and
  // region damping removes kd = 1 - exp(-damping h) of it on top (those modes have no part in
  // their regions' rigid motions, towards which it damps; solver.cpp). A held object's,
  // exp(-c h) (1 - kd), is never lower. Under the undamped cap a 1 MPa bar at one sub-step of
  // 1/60 s grew without bound with c = 200 /s (keep 0.036 - 0.15), and with c = 200 /s and
  // damping 100 /s (keep -0.78).
  const double kd = params_.damping > 0.0 ? 1.0 - std::exp(-params_.damping * h) : 0.0;
  const double keep = std::exp(-params_.ambientDamping * h) - kd;
  alphaCap_ = params_.stiffness * kStabilityMargin * symplecticEulerLimit(keep) / maxBound;
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
  detail::withSimd([&] {
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
  });
}

bool Solver::stiffnessSaturated() const {
  return params_.requestedAlpha(lattice_->spacing()) > alphaCap_;
}

}  // namespace deformable_flsm
