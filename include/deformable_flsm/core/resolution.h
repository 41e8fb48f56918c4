/// @file resolution.h
/// The finest lattice that fits a particle budget.
#pragma once

#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/voxelizer.h"

#include <cstddef>

namespace deformable_flsm {

/// What finestResolutionWithin() chose.
struct ResolutionChoice {
  /// Cells along the mesh's longest bounding-box axis (VoxelizeOptions::resolution)
  int resolution = 0;
  /// The voxelization at that resolution (its cells.size() is the particle count)
  Voxelization voxels;
  /// How many voxelizations the search ran (each a full voxelize())
  int voxelizations = 0;
};

/// The finest lattice whose particle count stays within `budget`: the largest resolution r
/// (cells along the longest axis, r <= maxResolution) such that voxelize() at r occupies at most
/// `budget` cells while r + 1 occupies more.
///
/// Occupied cells grow like c r^3 (c = the solid's volume over the cube of its longest extent),
/// so the search starts from a coarse voxelization, jumps to the resolution that scaling predicts
/// and then steps by one resolution to the boundary: typically 3 to 5 voxelizations. The count
/// is not strictly monotone in r (cells straddle the surface differently at each spacing), so
/// "finest" means the boundary found from that prediction, where r fits and r + 1 does not.
///
/// @param[in] mesh           surface to voxelize (m); must pass validateMesh()
/// @param[in] budget         largest particle count accepted (>= 1)
/// @param[in] maxResolution  finest resolution considered (>= 1); returned when it fits
/// @throws VoxelizationError when budget is 0 or maxResolution < 1.
/// @throws MeshError when the mesh fails validateMesh().
ResolutionChoice finestResolutionWithin(const TriMesh& mesh, std::size_t budget,
                                        int maxResolution = 1000);

/// The lattice whose particle count is nearest to `target` (for comparisons at a given count):
/// of finestResolutionWithin(mesh, target) and the resolution above it, the one nearer to the
/// target (the one within on a tie).
/// @throws as finestResolutionWithin().
ResolutionChoice nearestResolution(const TriMesh& mesh, std::size_t target, int maxResolution = 1000);

}  // namespace deformable_flsm
