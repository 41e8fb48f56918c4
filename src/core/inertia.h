// The inverse of an inertia tensor that may be singular (a body or region with its particles on
// one line cannot spin about that line), shared by the step, the implicit step's rigid-mode
// correction and the co-rotated Hessian. Internal to the core.
#pragma once

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

namespace deformable_flsm {

/// Inertia eigenvalues below this fraction of the largest are treated as zero, so that
/// omega = I^+ L stays finite and exact.
constexpr double kInertiaRankTolerance = 1e-10;

/// The eigen-decomposition of a symmetric positive semi-definite inertia tensor, with the
/// inverses of its eigenvalues (0 for those below kInertiaRankTolerance of the largest).
struct InertiaInverse {
  explicit InertiaInverse(const Eigen::Matrix3d& I) {
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
    eig.computeDirect(I);
    const Eigen::Vector3d& lambda = eig.eigenvalues();
    const double cutoff = kInertiaRankTolerance * lambda.cwiseAbs().maxCoeff();
    for (int k = 0; k < 3; ++k) inverse[k] = lambda[k] > cutoff ? 1.0 / lambda[k] : 0.0;
    vectors = eig.eigenvectors();
  }
  /// I^+ L
  Eigen::Vector3d solve(const Eigen::Vector3d& L) const { return vectors * inverse.asDiagonal() * (vectors.transpose() * L); }
  /// I^+
  Eigen::Matrix3d matrix() const { return vectors * inverse.asDiagonal() * vectors.transpose(); }

  Eigen::Matrix3d vectors;
  Eigen::Vector3d inverse;
};

}  // namespace deformable_flsm
