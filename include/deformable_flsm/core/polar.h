/// @file polar.h
/// Rotation extraction: the rotational factor of the polar decomposition A = R S.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace deformable_flsm {

/// Tuning of extractRotation().
struct PolarOptions {
  /// Newton iterations at most before the SVD fallback is taken.
  int maxIterations = 20;
  /// Converged when the rotation update is below this angle (rad).
  double angleTolerance = 1e-13;
};

/// Statistics of one call, for tests and benchmarks.
struct PolarStats {
  int iterations = 0;
  bool usedSvd = false;
};

/// The proper rotation R (det R = +1) that maximises tr(R^T A), i.e. the rotational factor of
/// the polar decomposition A = R S when det A > 0, and the closest rotation otherwise.
///
/// Warm-started from `q` (the previous step's rotation), it maximises f(theta) = tr((R e^[theta])^T A)
/// by Newton steps theta = H^-1 g, with g = axial(S - S^T), H = tr(S) I - sym(S), S = R^T A
/// (the method of Mueller et al. 2016, "A Robust Method to Extract the Rotational Part of
/// Deformations", with the exact Hessian, so that it converges quadratically near the answer).
/// Robust for any A: zero, collinear or planar A keep the warm start in the directions A does not
/// determine; an inverted A gives the closest proper rotation; when the iteration ends at a saddle
/// (H not positive semi-definite) or does not converge, a 3x3 SVD with reflection fix decides.
/// Never produces NaN for finite A.
///
/// @param[in]     A      3x3 matrix (any)
/// @param[in,out] q      unit quaternion: warm start in, the rotation out
/// @param[in]     opts   iteration limits
/// @param[out]    stats  optional statistics
/// @return R = q as a matrix
Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& A, Eigen::Quaterniond& q,
                                const PolarOptions& opts = PolarOptions(),
                                PolarStats* stats = nullptr);

/// Regions per call of extractRotationBatch().
constexpr int kRotationBatch = 8;

/// extractRotation() for `count` <= kRotationBatch matrices at once (the solver's per-region
/// loop), each one's Newton iteration in its own SIMD lane: a lane's result depends only on its
/// own A and q (a lane that has converged is left as it is while the others go on), and equals
/// what extractRotation() gives up to round-off. The usual case (finite A, a unit warm start, H
/// clearly positive definite at every Newton step, converged within a few steps) stays in the
/// lanes; any other matrix goes to extractRotation() from its unchanged warm start.
/// @param[in]     a  count x 9 doubles, matrix i row-major at a + 9 i
/// @param[in,out] q  count unit quaternions
/// @param[out]    r  count x 9 doubles, rotation i row-major at r + 9 i
void extractRotationBatch(int count, const double* a, Eigen::Quaterniond* q, double* r);

/// Convenience overload with the identity as warm start.
Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& A);

}  // namespace deformable_flsm
