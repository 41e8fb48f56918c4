/// @file mesh_distance_field.h
/// Signed distance to a closed triangle mesh, sampled once on a regular grid and interpolated:
/// the acceleration structure of a mesh collider.
#pragma once

#include "deformable_flsm/core/mesh.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

/// Signed distance phi (negative inside) of a closed triangle mesh on the nodes of a regular grid
/// that covers the mesh with a margin, interpolated trilinearly in between.
///
/// Construction (Bridson's level-set construction, as in his SDFGen / makelevelset3): exact
/// point-triangle distances on the nodes within one cell of each triangle, then fast sweeping
/// in the 8 diagonal directions that hands each node its neighbours' closest triangle when that
/// is closer (twice), then the sign from the parity of the mesh crossings along x through each
/// row of nodes (ray crossings with a consistent tie-break, so a ray through a shared edge counts
/// once). Cost O(#T + nodes) at build; a query is one trilinear interpolation.
///
/// Accuracy: exact on the nodes; between them the error grows with the curvature of phi (zero on
/// a face, up to about a cell next to edges and corners). Features thinner than a cell are lost.
/// Beyond the grid, phi is the value at the nearest grid point plus the distance to it.
class MeshDistanceField {
 public:
  /// @param[in] mesh        closed triangle mesh (m), see validateMesh() and countBoundaryEdges()
  /// @param[in] resolution  cells along the mesh's longest bounding-box axis (>= 4)
  /// @throws MeshError for an invalid or open mesh, std::invalid_argument for resolution < 4.
  MeshDistanceField(const TriMesh& mesh, int resolution = kDefaultResolution);

  /// Cells along the longest axis used by Solver::setCollider() when it builds the field.
  static constexpr int kDefaultResolution = 48;

  /// Signed distance (m, negative inside) and outward unit normal (the normalised gradient of the
  /// interpolant; the direction to the grid when outside it).
  /// @param[in]  p       3 by 1 point in the mesh's frame (m)
  /// @param[out] normal  3 by 1 unit vector
  double distance(const Eigen::Vector3d& p, Eigen::Vector3d& normal) const;

  /// Grid cell edge (m).
  double cellSize() const { return dx_; }
  /// Nodes along x, y, z.
  const Eigen::Vector3i& dims() const { return n_; }
  /// Axis-aligned bounds of the mesh (m).
  const Eigen::Vector3d& meshMin() const { return meshMin_; }
  const Eigen::Vector3d& meshMax() const { return meshMax_; }

 private:
  double at(int i, int j, int k) const { return phi_[nodeIndex(i, j, k)]; }
  std::size_t nodeIndex(int i, int j, int k) const { return (static_cast<std::size_t>(k) * n_.y() + j) * n_.x() + i; }
  Eigen::Vector3d nodeAt(int i, int j, int k) const { return origin_ + dx_ * Eigen::Vector3i(i, j, k).cast<double>(); }
  /// The build's stages: exact distances within a band of each triangle (with each node's closest
  /// triangle) and the crossing counts of the rows along x; fast sweeping (a node takes a
  /// neighbour's closest triangle when it is closer); the sign from the crossings.
  void exactBand(const TriMesh& mesh, std::vector<std::int32_t>& closest, std::vector<std::int32_t>& crossings);
  void sweep(const TriMesh& mesh, std::vector<std::int32_t>& closest);
  void applySign(const std::vector<std::int32_t>& crossings);

  Eigen::Vector3d origin_ = Eigen::Vector3d::Zero();  // node (0, 0, 0)
  double dx_ = 0.0;
  Eigen::Vector3i n_ = Eigen::Vector3i::Zero();
  Eigen::Vector3d meshMin_ = Eigen::Vector3d::Zero(), meshMax_ = Eigen::Vector3d::Zero();
  std::vector<double> phi_;  // n_.x() * n_.y() * n_.z(), x fastest
};

}  // namespace deformable_flsm
