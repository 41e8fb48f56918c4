/// @file indentation.h
/// The study's indentation case, what a finger meets: a bonded flat punch pressed into a block
/// held by its base, read as the force that holds the punch, against the FEM oracle's punch on
/// the same voxels. Every method of the study runs it through the Method interface.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/voxelizer.h"
#include "study/method.h"
#include "study/scenarios.h"
#include "study/setting.h"
#include "support/fem_oracle.h"
#include "support/indentation.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <vector>

namespace deformable_flsm {
namespace study {

/// The block: a cube of this side (m), its Young's modulus (Pa), the study's nu and density.
constexpr double kBlockSize = 0.05;
constexpr double kBlockYoungsModulus = 2e4;
/// The punch: as wide as this fraction of the side (the odd number of cells nearest to it, so
/// that it sits centred on the middle cell: 3 of 9, 5 of 13, 7 of 17), pressed this deep (m,
/// 2 % of the side: linear elasticity is the reference) over kPunchPress (s), then held to
/// kPunchEnd (s); the force is the mean over the last kPunchAverage (s), where the block rests.
constexpr double kPunchWidthFraction = 0.385;
constexpr double kPunchDepth = 1e-3;
constexpr double kPunchPress = 0.5, kPunchEnd = 2.0, kPunchAverage = 0.5;
constexpr double kPunchFrameStep = 1.0 / 60.0;
/// Ambient damping (1/s) of the punch for every method: the block's lowest mode (~150 rad/s)
/// settles within the hold without changing the rest state.
constexpr double kPunchAmbientDamping = 20.0;

/// A block of n^3 cells, its base on z = 0 and centred on the z axis; its lattice has w = 1 (the
/// node's regions for a local case); the particles of its bottom layer and those of its top
/// layer under the punch, the punch's width in cells and its starting centroid.
struct Block {
  Voxelization voxels;
  std::shared_ptr<const Lattice> lattice;
  std::vector<std::uint32_t> base, under;
  int punchCells = 0;
  Eigen::Vector3d start = Eigen::Vector3d::Zero();
};

inline Block makeBlock(int n) {
  Block b;
  Voxelization& v = b.voxels;
  v.spacing = kBlockSize / n;
  v.dims = Eigen::Vector3i::Constant(n);
  v.origin = Eigen::Vector3d(-0.5 * kBlockSize, -0.5 * kBlockSize, 0.0);
  v.closed = true;
  for (int k = 0; k < n; ++k)
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        v.cells.emplace_back(i, j, k);
        v.fillFraction.push_back(1.0);
      }
  b.lattice = std::make_shared<const Lattice>(v, kStudyDensity, 1);
  b.punchCells = 2 * static_cast<int>(std::lround((kPunchWidthFraction * n - 1.0) / 2.0)) + 1;
  const int half = b.punchCells / 2, mid = n / 2;
  for (std::uint32_t i = 0; i < b.lattice->size(); ++i) {
    const Eigen::Vector3i& c = b.lattice->cells()[i];
    if (c.z() == 0) b.base.push_back(i);
    if (c.z() == n - 1 && std::abs(c.x() - mid) <= half && std::abs(c.y() - mid) <= half) {
      b.under.push_back(i);
      b.start += b.lattice->restPositions()[i];
    }
  }
  b.start /= static_cast<double>(b.under.size());
  return b;
}

/// The oracle's force (N) on the same voxels (one linear hexahedron per cell): the base face's
/// nodes fixed, the top face's nodes over the punch's cells moved kPunchDepth down and held
/// sideways (bonded; indentation::femPunch()).
inline double oraclePunchForce(const Block& b, double youngsModulus, double nu) {
  return indentation::femPunch(b.voxels, b.punchCells, kPunchDepth, FemMaterial{youngsModulus, nu, kStudyDensity},
                               true);
}

/// The setting of a punch run (no load, kPunchAmbientDamping).
inline Setting punchSetting(int resolution, int substeps, double nu) {
  Setting s;
  s.resolution = resolution;
  s.substeps = substeps;
  s.frameStep = kPunchFrameStep;
  s.youngsModulus = kBlockYoungsModulus;
  s.poissonRatio = nu;
  s.ambientDamping = kPunchAmbientDamping;
  s.gravity.setZero();
  return s;
}

/// What a punch run measured.
struct PunchRecord {
  /// the punch's force (N, pressing down), the mean over the last kPunchAverage
  double force = 0.0;
  bool blewUp = false;
  /// CPU time of the stepping thread per simulated second (s/s)
  double cpuPerSimSecond = 0.0;
};

/// Presses the block that `method` simulates (built on b.lattice): its base layer pinned (the
/// base face for corner nodes), the top particles under the punch grabbed (their top face),
/// lowered kPunchDepth over kPunchPress, held to kPunchEnd.
inline PunchRecord runPunch(const Block& b, Method& method) {
  PunchRecord r;
  method.pinFace(b.base, -Eigen::Vector3d::UnitZ());
  method.grabFace(b.under, b.start, Eigen::Vector3d::UnitZ());
  const int frames = static_cast<int>(std::lround(kPunchEnd / kPunchFrameStep));
  const int pressFrames = static_cast<int>(std::lround(kPunchPress / kPunchFrameStep));
  const int averaged = static_cast<int>(std::lround(kPunchAverage / kPunchFrameStep));
  double cpu = 0.0, sum = 0.0;
  for (int f = 1; f <= frames; ++f) {
    method.moveGrab(b.start - Eigen::Vector3d(0, 0, kPunchDepth * std::min(1.0, double(f) / pressFrames)));
    const double c0 = threadCpuSeconds();
    method.step();
    cpu += threadCpuSeconds() - c0;
    if (!allFinite(method.positions())) {
      r.blewUp = true;
      break;
    }
    if (f > frames - averaged) sum -= method.grabForce().z();
  }
  r.force = r.blewUp ? std::numeric_limits<double>::quiet_NaN() : sum / averaged;
  r.cpuPerSimSecond = cpu / kPunchEnd;
  return r;
}

}  // namespace study
}  // namespace deformable_flsm
