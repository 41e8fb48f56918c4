#include "deformable_flsm/core/lattice.h"

#include "deformable_flsm/core/window_sums.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace deformable_flsm {

std::int64_t Lattice::key(const Eigen::Vector3i& c) {
  // 21 bits per axis: lattices are far below 2^20 cells per axis.
  constexpr std::int64_t kBits = 21;
  constexpr std::int64_t kMask = (std::int64_t{1} << kBits) - 1;
  return ((std::int64_t{c.z()} & kMask) << (2 * kBits)) | ((std::int64_t{c.y()} & kMask) << kBits) |
         (std::int64_t{c.x()} & kMask);
}

Lattice::Lattice(const Voxelization& voxels, double density, int regionHalfWidth)
    : w_(regionHalfWidth), spacing_(voxels.spacing), origin_(voxels.origin), cells_(voxels.cells) {
  if (cells_.empty()) throw std::invalid_argument("lattice: the voxelization has no occupied cells");
  if (!(density > 0.0) || !std::isfinite(density))
    throw std::invalid_argument("lattice: density must be a finite number > 0");
  if (w_ < 1) throw std::invalid_argument("lattice: region half-width must be >= 1");
  if (voxels.fillFraction.size() != cells_.size())
    throw std::invalid_argument("lattice: fillFraction and cells differ in size");

  const std::size_t n = cells_.size();
  const double cellVolume = spacing_ * spacing_ * spacing_;
  restPositions_.resize(n);
  masses_.resize(n);
  index_.reserve(2 * n);
  for (std::size_t p = 0; p < n; ++p) {
    restPositions_[p] = voxels.cellCenter(cells_[p]);
    masses_[p] = density * cellVolume * voxels.fillFraction[p];
    totalMass_ += masses_[p];
    index_.emplace(key(cells_[p]), static_cast<std::int32_t>(p));
  }
  restMin_ = restMax_ = restPositions_.front();
  for (const auto& x : restPositions_) {
    restMin_ = restMin_.cwiseMin(x);
    restMax_ = restMax_.cwiseMax(x);
  }

  neighbors_.resize(n);
  for (std::size_t p = 0; p < n; ++p) {
    for (int axis = 0; axis < 3; ++axis) {
      Eigen::Vector3i e = Eigen::Vector3i::Zero();
      e[axis] = 1;
      neighbors_[p][2 * axis] = particleAt(cells_[p] - e);
      neighbors_[p][2 * axis + 1] = particleAt(cells_[p] + e);
    }
  }

  // Runs: start at every particle without a negative neighbour and walk in the positive direction.
  for (int axis = 0; axis < 3; ++axis) {
    auto& order = runOrder_[axis];
    auto& starts = runStarts_[axis];
    order.reserve(n);
    for (std::size_t p = 0; p < n; ++p) {
      if (neighbors_[p][2 * axis] != kNone) continue;
      starts.push_back(static_cast<std::uint32_t>(order.size()));
      for (std::int32_t q = static_cast<std::int32_t>(p); q != kNone; q = neighbors_[q][2 * axis + 1])
        order.push_back(static_cast<std::uint32_t>(q));
    }
    starts.push_back(static_cast<std::uint32_t>(order.size()));
  }

  // n_i = number of regions containing i: the scatter of a 1 from every region.
  std::vector<double> ones(n, 1.0), counts(n), tmp(n);
  windowPass(*this, 2, ones.data(), 1, tmp.data());
  windowPass(*this, 1, tmp.data(), 1, counts.data());
  windowPass(*this, 0, counts.data(), 1, tmp.data());
  regionCounts_.resize(n);
  for (std::size_t p = 0; p < n; ++p) regionCounts_[p] = static_cast<int>(std::lround(tmp[p]));
  massFractions_.resize(n);
  for (std::size_t p = 0; p < n; ++p) massFractions_[p] = masses_[p] / regionCounts_[p];
}

std::int32_t Lattice::particleAt(const Eigen::Vector3i& c) const {
  if ((c.array() < 0).any()) return kNone;
  auto it = index_.find(key(c));
  return it == index_.end() ? kNone : it->second;
}

namespace {

/// Appends p and its linked neighbours along `axis` within distance w (p first, then outwards).
template <typename NeighborFn>
void appendRun(std::uint32_t p, int axis, int w, NeighborFn neighbor, std::vector<std::uint32_t>& out) {
  out.push_back(p);
  for (bool positive : {false, true}) {
    std::int32_t q = static_cast<std::int32_t>(p);
    for (int d = 1; d <= w; ++d) {
      q = neighbor(static_cast<std::uint32_t>(q), axis, positive);
      if (q == Lattice::kNone) break;
      out.push_back(static_cast<std::uint32_t>(q));
    }
  }
}

}  // namespace

void Lattice::regionMembers(std::size_t r, std::vector<std::uint32_t>& members) const {
  auto nb = [this](std::uint32_t p, int axis, bool positive) { return neighbor(p, axis, positive); };
  std::vector<std::uint32_t> zRun, yRun;
  zRun.reserve(2 * w_ + 1);
  yRun.reserve(2 * w_ + 1);
  members.clear();
  appendRun(static_cast<std::uint32_t>(r), 2, w_, nb, zRun);
  for (std::uint32_t a : zRun) {
    yRun.clear();
    appendRun(a, 1, w_, nb, yRun);
    for (std::uint32_t b : yRun) appendRun(b, 0, w_, nb, members);
  }
}

}  // namespace deformable_flsm
