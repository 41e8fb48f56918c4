#include "deformable_flsm/core/two_level_preconditioner.h"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

namespace {

/// Gather width: six parity classes of four channels (m~, m~ q) per pass, two passes for eight.
constexpr int kChannels = 24;
constexpr int kClassesPerPass = kChannels / 4;
/// A parity class of a region with less than this fraction of the region's mass is empty (the
/// lightest particle is ~1/(2w+1)^3 of a region's mass; the running sums' round-off ~1e-16).
constexpr double kEmptyClass = 1e-9;

int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }

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
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(0), hi = Eigen::Vector3i::Constant(0);
  if (n > 0) lo = hi = cells[0];
  for (const Eigen::Vector3i& c : cells) {
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  // the finest aggregates (s >= 2w: a region's 2w + 1 cells meet at most two per axis) within
  // the budget
  std::vector<int> grid;
  Eigen::Vector3i dims;
  for (s_ = std::max(2, 2 * w);; ++s_) {
    dims = (hi - lo) / s_ + Eigen::Vector3i::Ones();
    grid.assign(static_cast<std::size_t>(dims.prod()), -1);
    count_ = 0;
    for (const Eigen::Vector3i& c : cells) {
      const Eigen::Vector3i g = (c - lo) / s_;
      int& slot = grid[static_cast<std::size_t>(g.x() + dims.x() * (g.y() + dims.y() * g.z()))];
      if (slot < 0) slot = count_++;
    }
    if (count_ <= maxAggregates) break;
  }
  aggregate_.resize(n);
  parity_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3i g = (cells[i] - lo) / s_;
    aggregate_[i] = grid[static_cast<std::size_t>(g.x() + dims.x() * (g.y() + dims.y() * g.z()))];
    parity_[i] = static_cast<char>((g.x() & 1) | ((g.y() & 1) << 1) | ((g.z() & 1) << 2));
  }
  // region r spans cells c_r - w .. c_r + w: on each axis the aggregate of parity bit b is the
  // lower one, floor((c_r - w - lo) / s), or the next
  regionAggregate_.assign(n * kPerRegion, -1);
  for (std::size_t r = 0; r < n; ++r) {
    Eigen::Vector3i first;
    for (int a = 0; a < 3; ++a) first[a] = floorDiv(cells[r][a] - w - lo[a], s_);
    for (int k = 0; k < kPerRegion; ++k) {
      Eigen::Vector3i g;
      for (int a = 0; a < 3; ++a) g[a] = ((first[a] & 1) == ((k >> a) & 1)) ? first[a] : first[a] + 1;
      if ((g.array() < 0).any() || (g.array() >= dims.array()).any()) continue;
      regionAggregate_[r * kPerRegion + k] = grid[static_cast<std::size_t>(g.x() + dims.x() * (g.y() + dims.y() * g.z()))];
    }
  }
  regionAggMass_.assign(n * kPerRegion, 0.0);
  regionAggMoment_.assign(n * kPerRegion, Eigen::Vector3d::Zero());
  regionActive_.assign(n, 0);
  fixed_.assign(n, 0);
  gatherIn_.assign(n * kChannels, 0.0);
  gatherOut_.assign(n * kChannels, 0.0);
  const Eigen::Index N = 3 * count_;
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
  if (changed) gatherMoments(summer);
}

void TwoLevelPreconditioner::gatherMoments(RegionSummer& summer) {
  const std::size_t n = fixed_.size();
  for (int pass = 0; pass * kClassesPerPass < kPerRegion; ++pass) {
    const int firstClass = pass * kClassesPerPass;
    std::fill(gatherIn_.begin(), gatherIn_.end(), 0.0);
    for (std::size_t i = 0; i < n; ++i) {
      const int slot = parity_[i] - firstClass;
      if (fixed_[i] != 0 || slot < 0 || slot >= kClassesPerPass) continue;
      double* d = &gatherIn_[i * kChannels + 4 * static_cast<std::size_t>(slot)];
      d[0] = massFractions_[i];
      d[1] = massFractions_[i] * restCentered_[i].x();
      d[2] = massFractions_[i] * restCentered_[i].y();
      d[3] = massFractions_[i] * restCentered_[i].z();
    }
    summer.gather(gatherIn_.data(), kChannels, gatherOut_.data());
    for (std::size_t r = 0; r < n; ++r)
      for (int k = firstClass; k < std::min(kPerRegion, firstClass + kClassesPerPass); ++k) {
        const double* S = &gatherOut_[r * kChannels + 4 * static_cast<std::size_t>(k - firstClass)];
        const std::size_t e = r * kPerRegion + static_cast<std::size_t>(k);
        // the summer's running sums leave round-off where a class is empty
        const bool empty = regionAggregate_[e] < 0 || S[0] <= kEmptyClass * regionMass_[r];
        regionAggMass_[e] = empty ? 0.0 : S[0];
        regionAggMoment_[e] = empty ? Eigen::Vector3d::Zero()
                                    : Eigen::Vector3d(Eigen::Vector3d(S[1], S[2], S[3]) - S[0] * regionRestCenter_[r]);
      }
  }
  // A region adds to A_c unless its particles are all free and in one aggregate.
  for (std::size_t r = 0; r < n; ++r) {
    int nonEmpty = 0;
    double mass = 0.0;
    for (int k = 0; k < kPerRegion; ++k) {
      const double m = regionAggMass_[r * kPerRegion + static_cast<std::size_t>(k)];
      if (m > 0.0) ++nonEmpty;
      mass += m;
    }
    regionActive_[r] = nonEmpty > 1 || (nonEmpty == 1 && mass < regionMass_[r] * (1.0 - kEmptyClass)) ? 1 : 0;
  }
  gathered_ = true;
}

void TwoLevelPreconditioner::addBlock(int a, int b, const Eigen::Matrix3d& block) {
  coarse_.block<3, 3>(3 * a, 3 * b) += block;
}

void TwoLevelPreconditioner::beginAssembly(const std::vector<Eigen::Vector3d>& diagonal) {
  coarse_.setZero();
  for (std::size_t i = 0; i < diagonal.size(); ++i) {
    if (fixed_[i] != 0) continue;
    const int a = aggregate_[i];
    for (int c = 0; c < 3; ++c) coarse_(3 * a + c, 3 * a + c) += diagonal[i][c];
  }
}

void TwoLevelPreconditioner::addRegions(const CorotatedHessian& hessian) {
  const std::size_t n = regionActive_.size();
  const auto cross = [](const Eigen::Vector3d& v) {
    Eigen::Matrix3d X;
    X << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
    return X;
  };
  int agg[kPerRegion];
  double mass[kPerRegion];
  Eigen::Matrix3d X[kPerRegion], H[kPerRegion];
  for (std::size_t r = 0; r < n; ++r) {
    if (regionActive_[r] == 0) continue;
    const double c = hessian.regionCoefficient(r);
    if (c == 0.0) continue;
    const Eigen::Matrix3d& R = hessian.regionRotation(r);
    const Eigen::Matrix3d J = hessian.rotatedInertiaInverse(r);
    int m = 0;
    for (int k = 0; k < kPerRegion; ++k) {
      const std::size_t e = r * kPerRegion + static_cast<std::size_t>(k);
      if (!(regionAggMass_[e] > 0.0)) continue;
      agg[m] = regionAggregate_[e];
      mass[m] = regionAggMass_[e];
      X[m] = cross(R * regionAggMoment_[e]);
      H[m] = J * X[m];
      ++m;
    }
    const double invM = 1.0 / regionMass_[r];
    for (int a = 0; a < m; ++a) {
      Eigen::Matrix3d diag = X[a] * H[a];
      diag.diagonal().array() += mass[a] - mass[a] * mass[a] * invM;
      addBlock(agg[a], agg[a], c * diag);
      for (int b = a + 1; b < m; ++b) {
        Eigen::Matrix3d off = X[a] * H[b];
        off.diagonal().array() -= mass[a] * mass[b] * invM;
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
  int agg[kMax];
  Eigen::Vector3d v[kMax];
  int m = 0;
  for (int k = 0; k < count && k < kMax; ++k) {
    const int a = aggregateOf(particles[k]);
    if (a < 0) continue;
    int j = 0;
    while (j < m && agg[j] != a) ++j;
    if (j == m) {
      agg[m] = a;
      v[m++] = g[k];
    } else {
      v[j] += g[k];
    }
  }
  for (int a = 0; a < m; ++a)
    for (int b = 0; b < m; ++b) addBlock(agg[a], agg[b], weight * v[a] * v[b].transpose());
}

void TwoLevelPreconditioner::addEdge(std::uint32_t i, std::uint32_t j, double k) {
  const int a = aggregateOf(i), b = aggregateOf(j);
  if (a == b) return;
  const Eigen::Matrix3d K = k * Eigen::Matrix3d::Identity();
  if (a >= 0) addBlock(a, a, K);
  if (b >= 0) addBlock(b, b, K);
  if (a >= 0 && b >= 0) {
    addBlock(a, b, -K);
    addBlock(b, a, -K);
  }
}

bool TwoLevelPreconditioner::factorize() {
  // an aggregate of fixed particles only has a zero row and column: decouple it
  for (Eigen::Index d = 0; d < coarse_.rows(); ++d)
    if (coarse_(d, d) == 0.0) coarse_(d, d) = 1.0;
  llt_.compute(coarse_);
  factorized_ = llt_.info() == Eigen::Success;
  return factorized_;
}

void TwoLevelPreconditioner::apply(const std::vector<Eigen::Vector3d>& invDiagonal,
                                   const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
  const std::size_t n = r.size();
  for (std::size_t i = 0; i < n; ++i) z[i] = invDiagonal[i].cwiseProduct(r[i]);
  if (!factorized_) return;
  coarseRhs_.setZero();
  for (std::size_t i = 0; i < n; ++i) {
    if (fixed_[i] != 0) continue;
    coarseRhs_.segment<3>(3 * aggregate_[i]) += r[i];
  }
  llt_.solveInPlace(coarseRhs_);
  for (std::size_t i = 0; i < n; ++i) {
    if (fixed_[i] != 0) continue;
    z[i] += coarseRhs_.segment<3>(3 * aggregate_[i]);
  }
}

}  // namespace deformable_flsm
