#include "deformable_flsm/core/embedding.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <unordered_map>

namespace deformable_flsm {

namespace {

/// Shells searched around an empty cell for its nearest particle before a full scan; a render
/// vertex is within one cell of the occupied ones except where voxelization dropped a sliver.
constexpr int kGhostSearchShells = 3;

std::int64_t cellKey(const Eigen::Vector3i& c) {
  constexpr std::int64_t kOffset = 1 << 20;
  return ((c.z() + kOffset) << 42) | ((c.y() + kOffset) << 21) | (c.x() + kOffset);
}

/// Nearest particle (by rest position) to the centre of empty cell `c`.
std::uint32_t nearestParticle(const Lattice& lattice, const Eigen::Vector3i& c) {
  const Eigen::Vector3d center =
      lattice.origin() + lattice.spacing() * (c.cast<double>() + Eigen::Vector3d::Constant(0.5));
  const auto& x0 = lattice.restPositions();
  double best = std::numeric_limits<double>::infinity();
  std::int32_t bestIndex = Lattice::kNone;
  // A particle in Chebyshev shell s is at most s*sqrt(3) h away and one in shell s+2 at least
  // (s+2) h > s*sqrt(3) h for s <= 2: after the first hit in shell s, shell s+1 may still hold a
  // nearer one, shells beyond it (for the small s used here) cannot.
  int stopAfter = kGhostSearchShells;
  for (int s = 1; s <= stopAfter; ++s) {
    for (int dz = -s; dz <= s; ++dz)
      for (int dy = -s; dy <= s; ++dy)
        for (int dx = -s; dx <= s; ++dx) {
          if (std::max({std::abs(dx), std::abs(dy), std::abs(dz)}) != s) continue;
          const std::int32_t p = lattice.particleAt(c + Eigen::Vector3i(dx, dy, dz));
          if (p == Lattice::kNone) continue;
          const double d = (x0[p] - center).squaredNorm();
          if (d < best) {
            best = d;
            bestIndex = p;
          }
        }
    if (bestIndex != Lattice::kNone) stopAfter = std::min(stopAfter, s + 1);
  }
  if (bestIndex != Lattice::kNone) return static_cast<std::uint32_t>(bestIndex);
  for (std::size_t p = 0; p < x0.size(); ++p) {
    const double d = (x0[p] - center).squaredNorm();
    if (d < best) {
      best = d;
      bestIndex = static_cast<std::int32_t>(p);
    }
  }
  return static_cast<std::uint32_t>(bestIndex);
}

}  // namespace

Embedding::Embedding(const Lattice& lattice, const std::vector<Eigen::Vector3d>& restVertices)
    : particleCount_(lattice.size()) {
  const double h = lattice.spacing();
  const auto& x0 = lattice.restPositions();
  std::unordered_map<std::int64_t, std::uint32_t> ghostIndex;
  corners_.resize(restVertices.size());
  weights_.resize(restVertices.size());
  for (std::size_t v = 0; v < restVertices.size(); ++v) {
    if (!restVertices[v].allFinite()) throw std::invalid_argument("embedding: non-finite rest vertex");
    // Lattice coordinates in which cell centres are the integers.
    const Eigen::Vector3d u = (restVertices[v] - lattice.origin()) / h - Eigen::Vector3d::Constant(0.5);
    const Eigen::Vector3d fl = u.array().floor();
    const Eigen::Vector3i base = fl.cast<int>();
    const Eigen::Vector3d f = u - fl;
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3i d((k & 1), (k >> 1) & 1, (k >> 2) & 1);
      const Eigen::Vector3i cell = base + d;
      weights_[v][k] = (d.x() ? f.x() : 1.0 - f.x()) * (d.y() ? f.y() : 1.0 - f.y()) *
                       (d.z() ? f.z() : 1.0 - f.z());
      const std::int32_t p = lattice.particleAt(cell);
      if (p != Lattice::kNone) {
        corners_[v][k] = static_cast<std::uint32_t>(p);
        continue;
      }
      auto it = ghostIndex.find(cellKey(cell));
      if (it == ghostIndex.end()) {
        const std::uint32_t anchor = nearestParticle(lattice, cell);
        const Eigen::Vector3d ghostRest =
            lattice.origin() + h * (cell.cast<double>() + Eigen::Vector3d::Constant(0.5));
        ghostAnchor_.push_back(anchor);
        ghostOffset_.push_back(ghostRest - x0[anchor]);
        it = ghostIndex.emplace(cellKey(cell), static_cast<std::uint32_t>(ghostAnchor_.size() - 1)).first;
      }
      corners_[v][k] = static_cast<std::uint32_t>(particleCount_ + it->second);
    }
  }
}

void Embedding::deform(const std::vector<Eigen::Vector3d>& positions,
                       const std::vector<Eigen::Quaterniond>& rotations,
                       std::vector<Eigen::Vector3d>& vertices) const {
  if (positions.size() != particleCount_ || rotations.size() != particleCount_)
    throw std::invalid_argument("embedding: positions/rotations do not match the lattice");
  // per thread: the publishers and the cameras deform on threads of their own (allocates when
  // a thread first deforms a mesh with more ghost nodes than it did before)
  thread_local std::vector<Eigen::Vector3d> nodes;
  nodes.resize(ghostAnchor_.size());
  for (std::size_t g = 0; g < ghostAnchor_.size(); ++g) {
    const std::uint32_t a = ghostAnchor_[g];
    nodes[g] = positions[a] + rotations[a] * ghostOffset_[g];
  }
  vertices.resize(corners_.size());
  for (std::size_t v = 0; v < corners_.size(); ++v) {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    for (int k = 0; k < 8; ++k) {
      const std::uint32_t idx = corners_[v][k];
      x += weights_[v][k] * (idx < particleCount_ ? positions[idx] : nodes[idx - particleCount_]);
    }
    vertices[v] = x;
  }
}

}  // namespace deformable_flsm
