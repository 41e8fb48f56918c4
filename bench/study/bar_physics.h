/// @file bar_physics.h
/// The physical references of the study's bar scenarios (the cantilever and the column): the
/// displacements of the bar's centre line from the FEM oracle on the bar's voxels, and a run's
/// error against such a reference.
#pragma once

#include "deformable_flsm/core/voxelizer.h"
#include "study/scenarios.h"
#include "study/setting.h"
#include "support/fem_oracle.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {
namespace study {

/// The physical answer to the cantilever: the deflection (m, downward) of the bar's centre line
/// at each probe (StudyObject::probes), from the FEM oracle on the bar's voxels and from
/// Timoshenko's beam, and the tips; and to the column: the shortening (m, along -x) at each
/// probe from the FEM oracle and from uniaxial stress (nu = 0, free sides).
struct Physics {
  std::vector<double> fem, timoshenko;
  double femTip = 0.0, timoshenkoTip = 0.0, eulerBernoulliTip = 0.0;  // / L
  double femCheckTip = 0.0;                                           // / L, coarser oracle
  double femSeconds = 0.0;
  std::vector<double> columnFem, columnUniaxial;
  double columnFemTop = 0.0, columnUniaxialTop = 0.0;  // / L
};

/// Axis along which a bar scenario's load acts (the displacement that is compared).
inline int loadAxis(Scenario s) { return s == Scenario::Column ? 0 : 2; }

/// Displacement (m) against the load (downward for the cantilever, along -x for the column) of
/// the centre line at each probe of `bar` from a static FEM solve of `scenario` on
/// the bar's voxels at `resolution`, clamped as the scenario clamps (cells with centres within
/// L / 20 of the fixed end): the node displacements along the centre line (a node line when the
/// section has an even number of elements), interpolated linearly in x.
inline std::vector<double> femProbeDeflections(const StudyObject& bar, Scenario scenario, int resolution, int subdivision) {
  VoxelizeOptions options;
  options.resolution = resolution;
  const Voxelization voxels = voxelize(bar.mesh, options);
  FemOracle fem(voxels, FemMaterial{bar.youngsModulus, kStudyPoissonRatio, kStudyDensity}, subdivision);
  const double inf = std::numeric_limits<double>::infinity();
  const double cut = bar.mesh.boundsMin().x() + kBarClampFraction * (bar.mesh.boundsMax().x() - bar.mesh.boundsMin().x());
  fem.clampCellsInBox(Eigen::Vector3d(-inf, -inf, -inf), Eigen::Vector3d(cut, inf, inf));
  const FemSolution u = fem.solveStatic(scenarioGravity(scenario));
  const int axis = loadAxis(scenario);
  const Eigen::Vector3d& probe0 = bar.probes.front();
  const double tol = 1e-6 * voxels.spacing;
  std::vector<std::pair<double, double>> line;  // (x, downward deflection)
  for (std::size_t n = 0; n < fem.nodePositions().size(); ++n) {
    const Eigen::Vector3d& x = fem.nodePositions()[n];
    if (std::abs(x.y() - probe0.y()) < tol && std::abs(x.z() - probe0.z()) < tol)
      line.emplace_back(x.x(), -u.nodeDisplacements[n][axis]);
  }
  if (line.size() < 2)
    throw std::runtime_error("FEM oracle: no node line on the bar's centre line at resolution " +
                             std::to_string(resolution) + " (use an even number of elements across the section)");
  std::sort(line.begin(), line.end());
  std::vector<double> out;
  for (const Eigen::Vector3d& p : bar.probes) {
    auto hi = std::lower_bound(line.begin(), line.end(), std::make_pair(p.x(), -inf));
    if (hi == line.end()) hi = line.end() - 1;
    if (hi == line.begin()) hi = line.begin() + 1;
    const auto lo = hi - 1;
    const double t = (p.x() - lo->first) / (hi->first - lo->first);
    out.push_back(lo->second + t * (hi->second - lo->second));
  }
  return out;
}

/// A cantilever or column run against physics: tip displacement over the reference's minus 1
/// (negative: too stiff), and the RMS over the probes of the displacement difference over the
/// reference tip's.
struct PhysicalError {
  double tip = std::numeric_limits<double>::quiet_NaN();
  double profile = std::numeric_limits<double>::quiet_NaN();
};

inline PhysicalError physicalError(const StudyObject& bar, Scenario scenario,
                                   const std::vector<Eigen::Vector3d>& finalPoints,
                                   const std::vector<double>& reference) {
  const int axis = loadAxis(scenario);
  PhysicalError e;
  const std::size_t np = bar.probes.size(), first = finalPoints.size() - np;
  double sum = 0.0;
  for (std::size_t k = 0; k < np; ++k) {
    const double w = bar.probes[k][axis] - finalPoints[first + k][axis];
    sum += (w - reference[k]) * (w - reference[k]);
    if (k + 1 == np) e.tip = w / reference[k] - 1.0;
  }
  e.profile = std::sqrt(sum / double(np)) / reference.back();
  return e;
}

}  // namespace study
}  // namespace deformable_flsm
