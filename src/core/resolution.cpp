#include "deformable_flsm/core/resolution.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace deformable_flsm {

namespace {

/// Resolution of the first, cheap voxelization that calibrates the cubic growth of the count.
constexpr int kCalibrationResolution = 8;
/// Slack when flooring a predicted resolution, so that an exact ratio such as 16 * cbrt(1/8) =
/// 7.999... is not lost; every prediction is verified by voxelizing anyway.
constexpr double kPredictionSlack = 1e-9;

Voxelization voxelizeAt(const TriMesh& mesh, int resolution) {
  VoxelizeOptions options;
  options.resolution = resolution;
  // The budget is enforced by the search, which must see the count of a lattice that is too
  // fine rather than an exception (whose own search for a fitting resolution would cost more
  // voxelizations).
  options.maxParticles = std::numeric_limits<std::size_t>::max();
  return voxelize(mesh, options);
}

}  // namespace

ResolutionChoice finestResolutionWithin(const TriMesh& mesh, std::size_t budget,
                                        int maxResolution) {
  if (budget < 1) {
    throw VoxelizationError("particle budget must be >= 1, got 0");
  }
  if (maxResolution < 1) {
    throw VoxelizationError("maximum resolution must be >= 1, got " +
                            std::to_string(maxResolution));
  }
  validateMesh(mesh, "mesh passed to finestResolutionWithin");

  ResolutionChoice choice;
  // Invariant: every r <= fits has been seen to fit (0 trivially), every r >= tooFine to exceed
  // the budget (maxResolution + 1 by definition). Each sample shrinks (fits, tooFine).
  int fits = 0;
  int tooFine = maxResolution + 1;
  int r = std::min(kCalibrationResolution, maxResolution);
  while (fits + 1 < tooFine) {
    Voxelization voxels = voxelizeAt(mesh, r);
    ++choice.voxelizations;
    const std::size_t count = voxels.cells.size();
    if (count <= budget) {
      fits = r;
      choice.resolution = r;
      choice.voxels = std::move(voxels);
    } else {
      tooFine = r;
    }
    // Next sample: where c r^3 = budget according to this one, kept strictly inside the open
    // interval, so that the search ends at the boundary after a step of one resolution.
    const double predicted =
        count == 0 ? static_cast<double>(tooFine - 1)
                   : std::floor(r * std::cbrt(static_cast<double>(budget) / count) +
                                kPredictionSlack);
    r = static_cast<int>(std::clamp(predicted, static_cast<double>(fits + 1),
                                    static_cast<double>(tooFine - 1)));
  }
  if (fits == 0) {
    // Resolution 1 is a single cell: only a budget of 0 (refused above) cannot hold it.
    throw VoxelizationError("no resolution of the mesh fits a budget of " +
                            std::to_string(budget) + " particles");
  }
  return choice;
}

ResolutionChoice nearestResolution(const TriMesh& mesh, std::size_t target, int maxResolution) {
  ResolutionChoice within = finestResolutionWithin(mesh, target, maxResolution);
  if (within.resolution >= maxResolution) return within;
  Voxelization above = voxelizeAt(mesh, within.resolution + 1);
  ++within.voxelizations;
  const double below = static_cast<double>(target - within.voxels.cells.size());
  if (static_cast<double>(above.cells.size() - target) < below) {
    within.resolution += 1;
    within.voxels = std::move(above);
  }
  return within;
}

}  // namespace deformable_flsm
