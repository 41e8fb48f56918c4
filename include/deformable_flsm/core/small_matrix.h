/// @file small_matrix.h
/// Closed-form 3x3 symmetric solves for the per-region hot loops, where Eigen's general
/// decompositions cost more than the arithmetic they do.
#pragma once

#include <Eigen/Core>

namespace deformable_flsm {

/// Solves H x = b for a symmetric H when H is clearly positive definite, i.e. every pivot of its
/// LDL^T factorisation (ratio of successive leading principal minors) exceeds `minPivot`.
/// @param[in]  H         3x3 symmetric matrix (only used as given; symmetry is assumed)
/// @param[in]  b         right-hand side
/// @param[in]  minPivot  smallest acceptable pivot (same units as H), >= 0
/// @param[out] x         the solution, untouched when false is returned
/// @return false when some pivot is <= minPivot (H singular, indefinite or ill-conditioned)
inline bool solveSymmetricPositive3(const Eigen::Matrix3d& H, const Eigen::Vector3d& b, double minPivot,
                                    Eigen::Vector3d& x) {
  const double d1 = H(0, 0);
  if (!(d1 > minPivot)) return false;
  const double d2 = H(0, 0) * H(1, 1) - H(0, 1) * H(0, 1);
  if (!(d2 > minPivot * d1)) return false;
  // adjugate (symmetric) and determinant by the first row's cofactors
  const double c00 = H(1, 1) * H(2, 2) - H(1, 2) * H(1, 2);
  const double c01 = H(0, 2) * H(1, 2) - H(0, 1) * H(2, 2);
  const double c02 = H(0, 1) * H(1, 2) - H(0, 2) * H(1, 1);
  const double d3 = H(0, 0) * c00 + H(0, 1) * c01 + H(0, 2) * c02;
  if (!(d3 > minPivot * d2)) return false;
  const double c11 = H(0, 0) * H(2, 2) - H(0, 2) * H(0, 2);
  const double c12 = H(0, 1) * H(0, 2) - H(0, 0) * H(1, 2);
  const double inv = 1.0 / d3;
  x.x() = (c00 * b.x() + c01 * b.y() + c02 * b.z()) * inv;
  x.y() = (c01 * b.x() + c11 * b.y() + c12 * b.z()) * inv;
  x.z() = (c02 * b.x() + c12 * b.y() + d2 * b.z()) * inv;
  return true;
}

}  // namespace deformable_flsm
