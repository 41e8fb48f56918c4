/// @file lattice.h
/// The particle lattice (one particle per occupied cell) and its shape-matching regions.
#pragma once

#include "deformable_flsm/core/voxelizer.h"

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <unordered_map>
#include <vector>

namespace deformable_flsm {

/// Particles at the centres of the occupied cells of a voxelization, with the lattice links
/// between face-adjacent particles and the regions of half-width w.
///
/// Region of particle r (Rivers & James 2007, sec. 3 and 4): the particles j within Chebyshev
/// lattice distance w of r that are reached from r by a straight run of linked particles along z,
/// then one along y, then one along x, every step inside the cube. Every member is therefore
/// connected to r through lattice links inside the cube, so a region never bridges an empty cell
/// (such as the gap between the bunny's ears). This is exactly the set FastLSM's separable
/// x/y/z bar summation adds up, so the fast and naive solvers share one definition.
///
/// Mass fractions: particle i belongs to n_i regions and contributes m~_i = m_i / n_i to each,
/// which makes the shape-matching impulses conserve linear momentum.
class Lattice {
 public:
  /// Marker for "no particle" in neighbour tables.
  static constexpr std::int32_t kNone = -1;

  /// @param[in] voxels           occupied cells (see voxelize())
  /// @param[in] density          mass density (kg/m^3); m_i = density * fillFraction_i * h^3
  /// @param[in] regionHalfWidth  w >= 1 (cells)
  /// @throws std::invalid_argument when voxels has no cells, density <= 0 or w < 1
  Lattice(const Voxelization& voxels, double density, int regionHalfWidth);

  std::size_t size() const { return restPositions_.size(); }
  int regionHalfWidth() const { return w_; }
  double spacing() const { return spacing_; }
  const Eigen::Vector3d& origin() const { return origin_; }

  /// #P lattice coordinates of the particles, sorted by (k, j, i)
  const std::vector<Eigen::Vector3i>& cells() const { return cells_; }
  /// #P rest positions x0 (cell centres, m)
  const std::vector<Eigen::Vector3d>& restPositions() const { return restPositions_; }
  /// #P masses m (kg)
  const std::vector<double>& masses() const { return masses_; }
  /// #P number of regions n_i that contain particle i (>= 1: i is in its own region)
  const std::vector<int>& regionCounts() const { return regionCounts_; }
  /// #P region mass fractions m~_i = m_i / n_i (kg)
  const std::vector<double>& regionMassFractions() const { return massFractions_; }
  /// Total mass (kg)
  double totalMass() const { return totalMass_; }

  /// Index of the particle in cell `c`, or kNone.
  std::int32_t particleAt(const Eigen::Vector3i& c) const;
  /// Neighbour of particle p along `axis` (0, 1, 2) in direction +1 (`positive`) or -1, or kNone.
  std::int32_t neighbor(std::size_t p, int axis, bool positive) const {
    return neighbors_[p][2 * axis + (positive ? 1 : 0)];
  }

  /// Runs of linked particles along `axis`: `runOrder(axis)` lists every particle once, run by run
  /// and in increasing coordinate within a run; run q spans [runStarts(axis)[q], runStarts(axis)[q+1]).
  const std::vector<std::uint32_t>& runOrder(int axis) const { return runOrder_[axis]; }
  const std::vector<std::uint32_t>& runStarts(int axis) const { return runStarts_[axis]; }

  /// Members of region r, listed by the z-then-y-then-x walk that defines them (r first).
  void regionMembers(std::size_t r, std::vector<std::uint32_t>& members) const;

  /// Axis-aligned bounds of the rest positions (cell centres) (m).
  const Eigen::Vector3d& restMin() const { return restMin_; }
  const Eigen::Vector3d& restMax() const { return restMax_; }
  /// Length of the diagonal of the rest bounding box of the occupied cells (m); the object size
  /// that tolerances are expressed in.
  double objectSize() const { return (restMax_ - restMin_ + Eigen::Vector3d::Constant(spacing_)).norm(); }

 private:
  static std::int64_t key(const Eigen::Vector3i& c);

  int w_;
  double spacing_;
  Eigen::Vector3d origin_;
  std::vector<Eigen::Vector3i> cells_;
  std::vector<Eigen::Vector3d> restPositions_;
  Eigen::Vector3d restMin_, restMax_;
  std::vector<double> masses_;
  std::vector<int> regionCounts_;
  std::vector<double> massFractions_;
  double totalMass_ = 0.0;
  std::unordered_map<std::int64_t, std::int32_t> index_;
  std::vector<std::array<std::int32_t, 6>> neighbors_;
  std::array<std::vector<std::uint32_t>, 3> runOrder_;
  std::array<std::vector<std::uint32_t>, 3> runStarts_;
};

}  // namespace deformable_flsm
