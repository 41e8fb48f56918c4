/// @file fixtures.h
/// Small lattices built directly, without meshes, for the core tests.
#pragma once

#include "deformable_flsm/core/voxelizer.h"

#include <Eigen/Core>

#include <algorithm>
#include <functional>
#include <tuple>
#include <vector>

namespace deformable_flsm {
namespace test {

/// Voxelization holding the cells of a dims-sized lattice for which `keep(i, j, k)` is true,
/// sorted by (k, j, i) as voxelize() produces them, every cell full.
inline Voxelization makeVoxels(const Eigen::Vector3i& dims, double spacing,
                               const std::function<bool(int, int, int)>& keep) {
  Voxelization v;
  v.origin = Eigen::Vector3d::Zero();
  v.spacing = spacing;
  v.dims = dims;
  v.closed = true;
  for (int k = 0; k < dims.z(); ++k)
    for (int j = 0; j < dims.y(); ++j)
      for (int i = 0; i < dims.x(); ++i)
        if (keep(i, j, k)) {
          v.cells.emplace_back(i, j, k);
          v.fillFraction.push_back(1.0);
        }
  return v;
}

/// A full box of nx x ny x nz cells.
inline Voxelization makeBox(int nx, int ny, int nz, double spacing) {
  return makeVoxels(Eigen::Vector3i(nx, ny, nz), spacing, [](int, int, int) { return true; });
}

}  // namespace test
}  // namespace deformable_flsm
