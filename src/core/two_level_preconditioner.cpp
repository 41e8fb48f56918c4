#include "deformable_flsm/core/two_level_preconditioner.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

namespace {

/// Rest moments per parity class: m~, m~ q (3), m~ q q^T (6, upper triangle).
constexpr int kMoments = 10;
/// Gather width (a channel count the region summer takes): two parity classes per pass, four
/// passes for eight.
constexpr int kChannels = 24;
constexpr int kClassesPerPass = kChannels / kMoments;
/// A parity class of a region with less than this fraction of the region's mass is empty (the
/// lightest particle is ~1/(2w+1)^3 of a region's mass; the running sums' round-off ~1e-16).
constexpr double kEmptyClass = 1e-9;
/// An aggregate rotates unless its free particles' rest inertia about c_a has an eigenvalue below
/// this fraction of its largest (collinear particles, or one): a rotation that moves none of them
/// would leave A_c singular.
constexpr double kRotationRankTolerance = 1e-6;

Eigen::Matrix3d crossMatrix(const Eigen::Vector3d& v) {
  Eigen::Matrix3d X;
  X << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return X;
}

int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

/// The aggregates: cubes of s cells from the lattice's lowest corner, numbered in the order their
/// first particle comes.
struct AggregateGrid {
  int s = 0, count = 0;
  Eigen::Vector3i lo = Eigen::Vector3i::Zero(), dims = Eigen::Vector3i::Zero();
  std::vector<int> grid;  // per cube: its aggregate, -1 when empty
  int at(const Eigen::Vector3i& c) const {
    return grid[static_cast<std::size_t>(c.x() + dims.x() * (c.y() + dims.y() * c.z()))];
  }
};

/// The finest aggregates (s >= 2w: a region's 2w + 1 cells meet at most two per axis) within the
/// budget of maxAggregates.
AggregateGrid aggregateGrid(const std::vector<Eigen::Vector3i>& cells, int w, int maxAggregates) {
  AggregateGrid g;
  Eigen::Vector3i hi = Eigen::Vector3i::Zero();
  if (!cells.empty()) g.lo = hi = cells[0];
  for (const Eigen::Vector3i& c : cells) {
    g.lo = g.lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  for (g.s = std::max(2, 2 * w);; ++g.s) {
    g.dims = (hi - g.lo) / g.s + Eigen::Vector3i::Ones();
    g.grid.assign(static_cast<std::size_t>(g.dims.prod()), -1);
    g.count = 0;
    for (const Eigen::Vector3i& c : cells) {
      const Eigen::Vector3i q = (c - g.lo) / g.s;
      int& slot = g.grid[static_cast<std::size_t>(q.x() + g.dims.x() * (q.y() + g.dims.y() * q.z()))];
      if (slot < 0) slot = g.count++;
    }
    if (g.count <= maxAggregates) return g;
  }
}

/// The aggregates' rest centres (mass-weighted) and the particle nearest each: its region's
/// rotation turns the aggregate.
void centresAndRepresentatives(const std::vector<int>& aggregate, const std::vector<double>& massFractions,
                               const std::vector<Eigen::Vector3d>& restCentered, int count,
                               std::vector<Eigen::Vector3d>& center, std::vector<int>& representative) {
  const std::size_t n = aggregate.size(), m = static_cast<std::size_t>(count);
  center.assign(m, Eigen::Vector3d::Zero());
  std::vector<double> mass(m, 0.0), nearest(m, 0.0);
  for (std::size_t i = 0; i < n; ++i) {
    center[static_cast<std::size_t>(aggregate[i])] += massFractions[i] * restCentered[i];
    mass[static_cast<std::size_t>(aggregate[i])] += massFractions[i];
  }
  for (std::size_t a = 0; a < m; ++a) center[a] /= mass[a];
  representative.assign(m, -1);
  for (std::size_t i = 0; i < n; ++i) {
    const std::size_t a = static_cast<std::size_t>(aggregate[i]);
    const double d = (restCentered[i] - center[a]).squaredNorm();
    if (representative[a] < 0 || d < nearest[a]) {
      representative[a] = static_cast<int>(i);
      nearest[a] = d;
    }
  }
}

}  // namespace

TwoLevelPreconditioner::TwoLevelPreconditioner(const Lattice& lattice, const std::vector<double>& massFractions,
                                               const std::vector<Eigen::Vector3d>& restCentered,
                                               const std::vector<double>& regionMass,
                                               const std::vector<Eigen::Vector3d>& regionRestCenter,
                                               int maxAggregates)
    : massFractions_(massFractions),
      restCentered_(restCentered),
      regionMass_(regionMass),
      regionRestCenter_(regionRestCenter) {
  if (maxAggregates < 1)
    throw std::invalid_argument("TwoLevelPreconditioner: maxAggregates must be >= 1, got " +
                                std::to_string(maxAggregates));
  const std::vector<Eigen::Vector3i>& cells = lattice.cells();
  const std::size_t n = cells.size();
  const int w = lattice.regionHalfWidth();
  const AggregateGrid g = aggregateGrid(cells, w, maxAggregates);
  s_ = g.s;
  count_ = g.count;
  aggregate_.resize(n);
  parity_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3i c = (cells[i] - g.lo) / s_;
    aggregate_[i] = g.at(c);
    parity_[i] = static_cast<char>((c.x() & 1) | ((c.y() & 1) << 1) | ((c.z() & 1) << 2));
  }
  centresAndRepresentatives(aggregate_, massFractions, restCentered, count_, center_, representative_);
  rotates_.assign(static_cast<std::size_t>(count_), 0);
  aggregateRotation_.assign(static_cast<std::size_t>(count_), Eigen::Matrix3d::Identity());
  offset_.assign(n, Eigen::Vector3d::Zero());
  // region r spans cells c_r - w .. c_r + w: on each axis the aggregate of parity bit b is the
  // lower one, floor((c_r - w - lo) / s), or the next
  regionAggregate_.assign(n * kPerRegion, -1);
  for (std::size_t r = 0; r < n; ++r) {
    Eigen::Vector3i first;
    for (int a = 0; a < 3; ++a) first[a] = floorDiv(cells[r][a] - w - g.lo[a], s_);
    for (int k = 0; k < kPerRegion; ++k) {
      Eigen::Vector3i c;
      for (int a = 0; a < 3; ++a) c[a] = ((first[a] & 1) == ((k >> a) & 1)) ? first[a] : first[a] + 1;
      if ((c.array() < 0).any() || (c.array() >= g.dims.array()).any()) continue;
      regionAggregate_[r * kPerRegion + k] = g.at(c);
    }
  }
  regionAggMass_.assign(n * kPerRegion, 0.0);
  regionAggMoment_.assign(n * kPerRegion, Eigen::Vector3d::Zero());
  regionAggSecond_.assign(n * kPerRegion, Eigen::Matrix3d::Zero());
  fixed_.assign(n, 0);
  gatherIn_.assign(n * kChannels, 0.0);
  gatherOut_.assign(n * kChannels, 0.0);
  const Eigen::Index N = kModes * count_;
  coarse_ = Eigen::MatrixXd::Zero(N, N);
  llt_ = Eigen::LLT<Eigen::MatrixXd>(N);
  coarseRhs_ = Eigen::VectorXd::Zero(N);
}

void TwoLevelPreconditioner::setFixed(RegionSummer& summer, const std::vector<char>& pinned,
                                      const std::vector<char>& hardDragged) {
  bool changed = !gathered_;
  for (std::size_t i = 0; i < fixed_.size(); ++i) {
    const char f = (pinned[i] != 0 || hardDragged[i] != 0) ? 1 : 0;
    if (f != fixed_[i]) {
      fixed_[i] = f;
      changed = true;
    }
  }
  if (changed) {
    gatherMoments(summer);
    fixedChanged_ = true;
  }
}

bool TwoLevelPreconditioner::needsAssembly(const std::vector<Eigen::Vector3d>& diagonal,
                                           const CorotatedHessian& hessian, double maxTurn, int maxAge) {
  ++age_;
  if (fixedChanged_ || !factorized_ || age_ > maxAge || assembledDiagonal_.size() != diagonal.size()) return true;
  for (std::size_t i = 0; i < diagonal.size(); ++i)
    if (diagonal[i] != assembledDiagonal_[i]) return true;
  for (std::size_t r = 0; r < assembledCoefficient_.size(); ++r)
    if (hessian.regionCoefficient(r) != assembledCoefficient_[r]) return true;
  // the angle of R_then^T R_now from its trace: 1 + 2 cos(angle)
  const double minTrace = 1.0 + 2.0 * std::cos(maxTurn);
  for (std::size_t a = 0; a < aggregateRotation_.size(); ++a) {
    const Eigen::Matrix3d& now = hessian.regionRotation(static_cast<std::size_t>(representative_[a]));
    if (aggregateRotation_[a].cwiseProduct(now).sum() < minTrace) return true;
  }
  return false;
}

void TwoLevelPreconditioner::gatherMoments(RegionSummer& summer) {
  const std::size_t n = fixed_.size();
  for (int pass = 0; pass * kClassesPerPass < kPerRegion; ++pass) {
    const int firstClass = pass * kClassesPerPass;
    std::fill(gatherIn_.begin(), gatherIn_.end(), 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const int slot = parity_[i] - firstClass;
      if (fixed_[i] != 0 || slot < 0 || slot >= kClassesPerPass) continue;
      double* d = &gatherIn_[i * kChannels + kMoments * static_cast<std::size_t>(slot)];
      const double m = massFractions_[i];
      const Eigen::Vector3d& q = restCentered_[i];
      d[0] = m;
      d[1] = m * q.x();
      d[2] = m * q.y();
      d[3] = m * q.z();
      d[4] = m * q.x() * q.x();
      d[5] = m * q.y() * q.y();
      d[6] = m * q.z() * q.z();
      d[7] = m * q.x() * q.y();
      d[8] = m * q.x() * q.z();
      d[9] = m * q.y() * q.z();
    }
    summer.gather(gatherIn_.data(), kChannels, gatherOut_.data());
    for (std::size_t r = 0; r < n; ++r)
      for (int k = firstClass; k < std::min(kPerRegion, firstClass + kClassesPerPass); ++k) {
        const double* S = &gatherOut_[r * kChannels + kMoments * static_cast<std::size_t>(k - firstClass)];
        const std::size_t e = r * kPerRegion + static_cast<std::size_t>(k);
        // the summer's running sums leave round-off where a class is empty
        const bool empty = regionAggregate_[e] < 0 || S[0] <= kEmptyClass * regionMass_[r];
        regionAggMass_[e] = empty ? 0.0 : S[0];
        regionAggMoment_[e] = empty ? Eigen::Vector3d::Zero() : Eigen::Vector3d(S[1], S[2], S[3]);
        Eigen::Matrix3d second;
        second << S[4], S[7], S[8], S[7], S[5], S[9], S[8], S[9], S[6];
        regionAggSecond_[e] = empty ? Eigen::Matrix3d::Zero() : second;
      }
  }
  // which aggregates rotate: their free particles' rest inertia about c_a has full rank
  const std::size_t count = static_cast<std::size_t>(count_);
  std::vector<Eigen::Matrix3d> second(count, Eigen::Matrix3d::Zero());
  for (std::size_t i = 0; i < n; ++i) {
    if (fixed_[i] != 0) continue;
    const std::size_t a = static_cast<std::size_t>(aggregate_[i]);
    const Eigen::Vector3d d = restCentered_[i] - center_[a];
    second[a].noalias() += massFractions_[i] * d * d.transpose();
  }
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  for (std::size_t a = 0; a < count; ++a) {
    const Eigen::Matrix3d I = second[a].trace() * Eigen::Matrix3d::Identity() - second[a];
    eig.computeDirect(I);
    const Eigen::Vector3d& lambda = eig.eigenvalues();
    rotates_[a] = lambda.maxCoeff() > 0.0 && lambda.minCoeff() > kRotationRankTolerance * lambda.maxCoeff() ? 1 : 0;
  }
  gathered_ = true;
}

Eigen::Matrix<double, 3, TwoLevelPreconditioner::kModes> TwoLevelPreconditioner::prolongation(std::size_t i) const {
  Columns P = Columns::Zero();
  if (fixed_[i] != 0) return P;
  P.leftCols<3>().setIdentity();
  if (rotates_[static_cast<std::size_t>(aggregate_[i])] != 0) P.rightCols<3>() = -crossMatrix(offset_[i]);
  return P;
}

void TwoLevelPreconditioner::beginAssembly(const std::vector<Eigen::Vector3d>& diagonal,
                                           const CorotatedHessian& hessian) {
  for (std::size_t a = 0; a < aggregateRotation_.size(); ++a)
    aggregateRotation_[a] = hessian.regionRotation(static_cast<std::size_t>(representative_[a]));
  assembledDiagonal_ = diagonal;  // sized once (the copy allocates on the first assembly only)
  assembledCoefficient_.resize(regionMass_.size());
  for (std::size_t r = 0; r < assembledCoefficient_.size(); ++r) assembledCoefficient_[r] = hessian.regionCoefficient(r);
  fixedChanged_ = false;
  age_ = 0;
  coarse_.setZero();
  for (std::size_t i = 0; i < diagonal.size(); ++i) {
    const std::size_t a = static_cast<std::size_t>(aggregate_[i]);
    offset_[i] = aggregateRotation_[a] * (restCentered_[i] - center_[a]);
    if (fixed_[i] != 0) continue;
    const Columns P = prolongation(i);
    addBlock(static_cast<int>(a), static_cast<int>(a), P.transpose() * diagonal[i].asDiagonal() * P);
  }
}

// Per region, the blocks c_r [delta_ab G_ra - T_ra^T T_rb / M_r - L_ra^T J_r L_rb] of the class
// comment, from the rest moments (m, f, S) of the region's part in each aggregate.
void TwoLevelPreconditioner::addRegions(const CorotatedHessian& hessian) {
  const std::size_t n = regionAggMass_.size() / kPerRegion;
  int agg[kPerRegion];
  Columns T[kPerRegion], L[kPerRegion], JL[kPerRegion];
  Eigen::Matrix3d G[kPerRegion];  // the rotation block tr(Q) 1 - Q of G_ra
  for (std::size_t r = 0; r < n; ++r) {
    const double c = hessian.regionCoefficient(r);
    if (c == 0.0) continue;
    const Eigen::Matrix3d& Rr = hessian.regionRotation(r);
    const Eigen::Matrix3d J = hessian.rotatedInertiaInverse(r);
    const Eigen::Vector3d& c0 = regionRestCenter_[r];
    int m = 0;
    for (int k = 0; k < kPerRegion; ++k) {
      const std::size_t e = r * kPerRegion + static_cast<std::size_t>(k);
      const double mass = regionAggMass_[e];
      if (!(mass > 0.0)) continue;
      const std::size_t a = static_cast<std::size_t>(regionAggregate_[e]);
      const Eigen::Vector3d& f = regionAggMoment_[e];
      const Eigen::Matrix3d& S = regionAggSecond_[e];
      const Eigen::Vector3d& ca = center_[a];
      agg[m] = static_cast<int>(a);
      T[m].leftCols<3>() = mass * Eigen::Matrix3d::Identity();
      L[m].leftCols<3>() = crossMatrix(Rr * (f - mass * c0));
      if (rotates_[a] != 0) {
        const Eigen::Matrix3d& Ra = aggregateRotation_[a];
        T[m].rightCols<3>() = -crossMatrix(Ra * (f - mass * ca));
        const Eigen::Matrix3d Q = Ra * (S - f * ca.transpose() - ca * f.transpose() + mass * ca * ca.transpose()) *
                                  Ra.transpose();
        G[m] = Q.trace() * Eigen::Matrix3d::Identity() - Q;
        const Eigen::Matrix3d X = Ra * (S - f * c0.transpose() - ca * f.transpose() + mass * ca * c0.transpose()) *
                                  Rr.transpose();
        L[m].rightCols<3>() = X.trace() * Eigen::Matrix3d::Identity() - X;
      } else {
        T[m].rightCols<3>().setZero();
        G[m].setZero();
        L[m].rightCols<3>().setZero();
      }
      JL[m].noalias() = J * L[m];
      ++m;
    }
    const double invM = 1.0 / regionMass_[r];
    for (int a = 0; a < m; ++a) {
      Block diag;
      diag.noalias() = -invM * T[a].transpose() * T[a];
      diag.noalias() -= L[a].transpose() * JL[a];
      // delta_ab G_ra: G's translation and coupling blocks are T's
      diag.topRows<3>() += T[a];
      diag.bottomLeftCorner<3, 3>() -= T[a].topRightCorner<3, 3>();  // [Y]x = -(-[Y]x)
      diag.bottomRightCorner<3, 3>() += G[a];
      addBlock(agg[a], agg[a], c * diag);
      for (int b = a + 1; b < m; ++b) {
        Block off;
        off.noalias() = -invM * T[a].transpose() * T[b];
        off.noalias() -= L[a].transpose() * JL[b];
        off *= c;
        addBlock(agg[a], agg[b], off);
        addBlock(agg[b], agg[a], off.transpose());
      }
    }
  }
}

void TwoLevelPreconditioner::addOuter(const std::uint32_t* particles, const Eigen::Vector3d* g, int count,
                                      double weight) {
  constexpr int kMax = 8;
  using Vector = Eigen::Matrix<double, kModes, 1>;
  int agg[kMax];
  Vector v[kMax];
  int m = 0;
  for (int k = 0; k < count && k < kMax; ++k) {
    const int a = aggregateOf(particles[k]);
    if (a < 0) continue;
    const Vector pg = prolongation(particles[k]).transpose() * g[k];
    int j = 0;
    while (j < m && agg[j] != a) ++j;
    if (j == m) {
      agg[m] = a;
      v[m++] = pg;
    } else {
      v[j] += pg;
    }
  }
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) addBlock(agg[a], agg[b], weight * v[a] * v[b].transpose());
}

// k/2 |p_i - p_j|^2 at p = P u: the blocks k P_s^T P_t over the ends s, t, signed (+ i, - j).
void TwoLevelPreconditioner::addEdge(std::uint32_t i, std::uint32_t j, double k) {
  const int agg[2] = {aggregateOf(i), aggregateOf(j)};
  const Columns P[2] = {prolongation(i), -prolongation(j)};
  for (int s = 0; s < 2; ++s)
    for (int t = 0; t < 2; ++t)
      if (agg[s] >= 0 && agg[t] >= 0) addBlock(agg[s], agg[t], k * P[s].transpose() * P[t]);
}

bool TwoLevelPreconditioner::factorize() {
  // an unknown that moves no particle (an aggregate of fixed particles only, the rotation of one
  // that does not rotate) has a zero row and column: decouple it
  for (Eigen::Index d = 0; d < coarse_.rows(); ++d)
    if (coarse_(d, d) == 0.0) coarse_(d, d) = 1.0;
  llt_.compute(coarse_);
  factorized_ = llt_.info() == Eigen::Success;
  return factorized_;
}

void TwoLevelPreconditioner::apply(const std::vector<Eigen::Vector3d>& invDiagonal,
                                   const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
  const std::size_t n = r.size();
  const Eigen::Vector3d* const rv = r.data();
  const Eigen::Vector3d* const inv = invDiagonal.data();
  Eigen::Vector3d* const zv = z.data();
  if (!factorized_) {
    for (std::size_t i = 0; i < n; ++i) zv[i] = inv[i].cwiseProduct(rv[i]);
    return;
  }
  const int* const aggregate = aggregate_.data();
  const char* const fixed = fixed_.data();
  const Eigen::Vector3d* const offset = offset_.data();
  coarseRhs_.setZero();
  double* const rhs = coarseRhs_.data();
  // P^T r: per aggregate sum r_i and sum y_i x r_i; the Jacobi part z_i = D^-1 r_i in the same pass
  for (std::size_t i = 0; i < n; ++i) {
    zv[i] = inv[i].cwiseProduct(rv[i]);
    if (fixed[i] != 0) continue;
    double* const u = rhs + kModes * aggregate[i];
    Eigen::Map<Eigen::Vector3d>(u) += rv[i];
    Eigen::Map<Eigen::Vector3d>(u + 3) += offset[i].cross(rv[i]);
  }
  for (std::size_t a = 0; a < rotates_.size(); ++a)
    if (rotates_[a] == 0) coarseRhs_.segment<3>(kModes * static_cast<Eigen::Index>(a) + 3).setZero();
  llt_.solveInPlace(coarseRhs_);
  // then z_i += u_a + w_a x y_i
  for (std::size_t i = 0; i < n; ++i) {
    if (fixed[i] != 0) continue;
    const double* const u = rhs + kModes * aggregate[i];
    zv[i] += Eigen::Map<const Eigen::Vector3d>(u) + Eigen::Map<const Eigen::Vector3d>(u + 3).cross(offset[i]);
  }
}

}  // namespace deformable_flsm
