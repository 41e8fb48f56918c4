/// @file metrics.h
/// The accuracy measures of the study: shape error against the rest shape, volume of a closed
/// mesh, RMS distance, the Euler-Bernoulli cantilever profile, and the rotations that let the
/// render mesh be embedded in the particles of methods that have no regions of their own.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/polar.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

namespace deformable_flsm {
namespace study {

/// Median of v (mean of the middle two for an even count); NaN when v is empty.
inline double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  std::sort(v.begin(), v.end());
  const std::size_t n = v.size();
  return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// true when every coordinate is finite.
inline bool allFinite(const std::vector<Eigen::Vector3d>& x) {
  for (const auto& xi : x)
    if (!xi.allFinite()) return false;
  return true;
}

/// RMS distance (m) between x and the best rigid fit of the rest shape: the mass-weighted
/// least-squares rotation R = polar(sum m (x - c)(x0 - c0)^T) and translation, then
/// sqrt(mean |x_i - (R (x0_i - c0) + c)|^2). The same measure as Solver::shapeError(), computed
/// here from positions alone so that every method is judged by the same code.
/// @param[in] masses  #P particle masses (kg)
/// @param[in] rest    #P rest positions x0 (m)
/// @param[in] x       #P current positions (m)
/// @return the error (m); infinity when x holds a non-finite coordinate
inline double rigidFitError(const std::vector<double>& masses, const std::vector<Eigen::Vector3d>& rest,
                            const std::vector<Eigen::Vector3d>& x) {
  if (!allFinite(x)) return std::numeric_limits<double>::infinity();
  double M = 0.0;
  Eigen::Vector3d c = Eigen::Vector3d::Zero(), c0 = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < x.size(); ++i) {
    M += masses[i];
    c += masses[i] * x[i];
    c0 += masses[i] * rest[i];
  }
  c /= M;
  c0 /= M;
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < x.size(); ++i)
    A.noalias() += masses[i] * (x[i] - c) * (rest[i] - c0).transpose();
  const Eigen::Matrix3d R = extractRotation(A);
  double e = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) e += (x[i] - c - R * (rest[i] - c0)).squaredNorm();
  return std::sqrt(e / static_cast<double>(x.size()));
}

/// Volume (m^3) enclosed by a closed, consistently oriented triangle mesh, by the divergence
/// theorem: V = (1/6) sum over triangles (a . (b x c)). Positive for counter-clockwise-outside
/// triangles; for an open mesh the number depends on the origin and means nothing.
/// @param[in] vertices   #V positions (m)
/// @param[in] triangles  #T index triples
inline double closedMeshVolume(const std::vector<Eigen::Vector3d>& vertices,
                               const std::vector<std::array<std::uint32_t, 3>>& triangles) {
  // Relative to the first vertex, so that a mesh far from the origin loses no digits.
  if (vertices.empty()) return 0.0;
  const Eigen::Vector3d o = vertices[0];
  double v = 0.0;
  for (const auto& t : triangles)
    v += (vertices[t[0]] - o).dot((vertices[t[1]] - o).cross(vertices[t[2]] - o));
  return v / 6.0;
}

/// Root mean square of |a_i - b_i| (m); a and b have the same size.
inline double rmsDistance(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double e = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) e += (a[i] - b[i]).squaredNorm();
  return a.empty() ? 0.0 : std::sqrt(e / static_cast<double>(a.size()));
}

/// Normalised deflection of a uniformly loaded (self-weight) Euler-Bernoulli cantilever,
/// clamped at s = 0 and free at s = 1:
///   y(x) / y(L) = x^2 (6 L^2 - 4 L x + x^2) / (3 L^4) = s^2 (6 - 4 s + s^2) / 3,  s = x / L
/// (from E I y'''' = q with y(0) = y'(0) = 0, y''(L) = y'''(L) = 0: y = q x^2 (6L^2 - 4Lx + x^2)
/// / (24 E I), y(L) = q L^4 / (8 E I); e.g. Gere & Goodno, Mechanics of Materials, table G-1).
/// @param[in] s  position along the beam over its length, in [0, 1]
inline double eulerBernoulliProfile(double s) { return s * s * (6.0 - 4.0 * s + s * s) / 3.0; }

/// For methods without shape-matching regions (mass-spring, Bullet): a rotation per particle,
/// the polar factor of the deformation of its 3 x 3 x 3 lattice neighbourhood,
/// R_i = polar(sum_j (x_j - c_i)(x0_j - c0_i)^T) over the occupied cells j around i (Mueller et
/// al. 2005 shape matching with equal weights). The embedding uses these only to carry the ghost
/// nodes of surface cells (Embedding), so every method's render mesh is made the same way.
/// @param[in]     lattice  particles (rest positions, cells)
/// @param[in]     x        #P current positions (m)
/// @param[in,out] q        #P rotations: warm start in (resized to identity if the size
///                         differs), the neighbourhood rotations out
inline void neighbourhoodRotations(const Lattice& lattice, const std::vector<Eigen::Vector3d>& x,
                                   std::vector<Eigen::Quaterniond>& q) {
  const std::size_t n = lattice.size();
  if (q.size() != n) q.assign(n, Eigen::Quaterniond::Identity());
  const auto& x0 = lattice.restPositions();
  const auto& cells = lattice.cells();
  std::array<std::int32_t, 27> members{};
  for (std::size_t i = 0; i < n; ++i) {
    int count = 0;
    Eigen::Vector3d c = Eigen::Vector3d::Zero(), c0 = Eigen::Vector3d::Zero();
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const std::int32_t j = lattice.particleAt(cells[i] + Eigen::Vector3i(dx, dy, dz));
          if (j == Lattice::kNone) continue;
          members[count++] = j;
          c += x[j];
          c0 += x0[j];
        }
    c /= count;
    c0 /= count;
    Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
    for (int k = 0; k < count; ++k) A.noalias() += (x[members[k]] - c) * (x0[members[k]] - c0).transpose();
    extractRotation(A, q[i]);
  }
}

}  // namespace study
}  // namespace deformable_flsm
