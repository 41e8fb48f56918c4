/// @file voxelizer.h
/// Voxelization of a triangle mesh into the occupied cells of a regular lattice.
#pragma once

#include "deformable_flsm/core/mesh.h"

#include <Eigen/Core>

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {

/// Thrown when voxelization options are invalid or the lattice would exceed its budget.
class VoxelizationError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// How fine the lattice is. Exactly one of `spacing` and `resolution` must be positive.
struct VoxelizeOptions {
  /// Cell edge length (m); 0 to use `resolution` instead.
  double spacing = 0.0;
  /// Number of cells along the mesh's longest bounding-box axis; 0 to use `spacing`.
  int resolution = 0;
  /// Refuse lattices with more occupied cells than this (the error names a resolution that fits).
  std::size_t maxParticles = 200000;

  /// @throws VoxelizationError naming the offending field.
  void validate() const;
};

/// Result of voxelizing a mesh: the occupied cells of a lattice.
///
/// Cell (i, j, k) spans [origin + h (i, j, k), origin + h (i+1, j+1, k+1)]; its centre is
/// origin + h (i + 1/2, j + 1/2, k + 1/2). Cells are listed sorted by (k, j, i), so that runs
/// along x are contiguous.
struct Voxelization {
  /// Lower corner of cell (0, 0, 0) (m)
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  /// Cell edge length h (m)
  double spacing = 0.0;
  /// Number of cells of the lattice along x, y, z; every listed cell lies in [0, dims)
  Eigen::Vector3i dims = Eigen::Vector3i::Zero();
  /// #P occupied cells, sorted by (k, j, i)
  std::vector<Eigen::Vector3i> cells;
  /// #P fraction of each cell's volume inside the solid, in (0, 1]; 1 for interior cells and
  /// for every cell of an open mesh (whose inside is not defined)
  std::vector<double> fillFraction;
  /// true when the mesh is closed and its interior was filled
  bool closed = false;
  /// Problems the caller should report (open or leaky mesh, ...); empty when all went well
  std::vector<std::string> warnings;

  /// Centre of a cell (m).
  Eigen::Vector3d cellCenter(const Eigen::Vector3i& cell) const {
    return origin + spacing * (cell.cast<double>() + Eigen::Vector3d::Constant(0.5));
  }
};

/// Voxelizes a mesh.
///
/// The lattice is centred on the mesh's bounding box. For a closed mesh a cell is occupied when
/// part of its volume lies inside the solid: interior cells are found by ray parity along x
/// through cell centres, cells touching the surface (exact triangle/box overlap test, Akenine-
/// Moeller 2001) get their inside fraction from a sub-cell sample, and cells whose contact with
/// the surface has no volume (a face lying on a cell boundary) are not occupied. For an open or
/// leaky mesh, the surface cells plus whatever a flood fill from outside cannot reach are
/// occupied, each with fraction 1, and a warning says so.
///
/// @param[in] mesh     surface to voxelize (m); must pass validateMesh()
/// @param[in] options  lattice spacing or resolution, and the particle budget
/// @throws MeshError when the mesh fails validateMesh().
/// @throws VoxelizationError on invalid options, or when more than options.maxParticles cells
///         would be occupied (the message names a resolution that fits).
Voxelization voxelize(const TriMesh& mesh, const VoxelizeOptions& options);

/// A solid box of dims.x() x dims.y() x dims.z() full cells of edge `spacing`, the lower corner of
/// cell (0, 0, 0) at `origin`: closed, every fill fraction 1, cells in (k, j, i) order. The block
/// of tests and benchmarks.
Voxelization boxVoxels(const Eigen::Vector3i& dims, double spacing,
                       const Eigen::Vector3d& origin = Eigen::Vector3d::Zero());

namespace detail {

/// Separating-axis test of a triangle against an axis-aligned box (Akenine-Moeller 2001, "Fast
/// 3D triangle-box overlap testing"): the two are disjoint iff their projections are disjoint on
/// one of 13 axes, namely the 3 box normals, the triangle normal and the 9 cross products of a
/// box normal with a triangle edge. Touching counts as overlapping.
/// @param[in] boxCenter    3 by 1 centre of the box (m)
/// @param[in] boxHalfSize  3 by 1 half edge lengths of the box (m), >= 0
/// @param[in] a, b, c      3 by 1 triangle corners (m); a degenerate triangle is a segment or point
/// @return true when the closed triangle and the closed box share a point.
bool triangleBoxOverlap(const Eigen::Vector3d& boxCenter, const Eigen::Vector3d& boxHalfSize,
                        const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        const Eigen::Vector3d& c);

}  // namespace detail

}  // namespace deformable_flsm
