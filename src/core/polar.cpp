#include "deformable_flsm/core/polar.h"

#include "deformable_flsm/core/small_matrix.h"
#include "lanes.h"
#include "region_kernels.h"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>

namespace deformable_flsm {

using detail::kQuadraticMargin;
using detail::kSaddleTolerance;

namespace {

/// Closest proper rotation to A through the SVD A = U Sigma V^T: R = U diag(1, 1, det(U V^T)) V^T.
Eigen::Matrix3d rotationBySvd(const Eigen::Matrix3d& A) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  const Eigen::Matrix3d& V = svd.matrixV();
  if ((U * V.transpose()).determinant() < 0.0) U.col(2) = -U.col(2);
  return U * V.transpose();
}

/// true when symmetric H is positive semi-definite up to `tol` (all principal minors >= -tol^k).
bool isPositiveSemiDefinite(const Eigen::Matrix3d& H, double tol) {
  if (H(0, 0) < -tol || H(1, 1) < -tol || H(2, 2) < -tol) return false;
  const double tol2 = tol * std::max(tol, H.diagonal().cwiseAbs().maxCoeff());
  if (H(0, 0) * H(1, 1) - H(0, 1) * H(1, 0) < -tol2) return false;
  if (H(0, 0) * H(2, 2) - H(0, 2) * H(2, 0) < -tol2) return false;
  if (H(1, 1) * H(2, 2) - H(1, 2) * H(2, 1) < -tol2) return false;
  return H.determinant() >= -tol2 * std::max(tol, H.diagonal().cwiseAbs().maxCoeff());
}

}  // namespace

Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& A, Eigen::Quaterniond& q,
                                const PolarOptions& opts, PolarStats* stats) {
  if (stats != nullptr) *stats = PolarStats();
  if (!A.allFinite()) return q.toRotationMatrix();
  const double scale = A.cwiseAbs().maxCoeff();
  if (!(q.norm() > 0.0) || !q.coeffs().allFinite()) q.setIdentity();
  q.normalize();
  if (scale == 0.0) return q.toRotationMatrix();

  const double tol = kSaddleTolerance * scale;
  Eigen::Matrix3d R = q.toRotationMatrix();
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  bool converged = false;
  bool newton = false;  // the last step was a Newton step (H positive definite)
  int it = 0;
  for (; it < opts.maxIterations; ++it) {
    const Eigen::Matrix3d S = R.transpose() * A;
    // f(theta) = tr((R exp[theta])^T A) ~ tr S + g.theta - 1/2 theta^T H theta
    const Eigen::Vector3d g(S(2, 1) - S(1, 2), S(0, 2) - S(2, 0), S(1, 0) - S(0, 1));
    H = Eigen::Matrix3d::Identity() * S.trace() - 0.5 * (S + S.transpose());
    Eigen::Vector3d theta;
    newton = solveSymmetricPositive3(H, g, tol, theta);
    if (!newton) {
      // Not a concave neighbourhood: gradient step of Mueller et al. 2016 (bounded length).
      theta = g / (std::abs(S.trace()) + scale);
    }
    const double angle = theta.norm();
    if (!std::isfinite(angle)) break;
    if (angle < opts.angleTolerance) {
      converged = true;
      break;
    }
    // q <- q * dq with dq = (1, theta/2) normalised: the rotation by 2 atan(|theta|/2) about theta,
    // equal to exp(theta) to second order; the fixed point (g = 0) is unchanged and large steps
    // are shortened, never lengthened.
    const Eigen::Quaterniond dq(1.0, 0.5 * theta.x(), 0.5 * theta.y(), 0.5 * theta.z());
    q = (q * dq).normalized();
    R = q.toRotationMatrix();
    if (newton && kQuadraticMargin * angle * angle < opts.angleTolerance) {
      converged = true;
      ++it;
      break;
    }
  }
  if (stats != nullptr) stats->iterations = it;
  // A Newton step means H was positive definite there: a maximum. Otherwise check for a saddle.
  if (converged && (newton || isPositiveSemiDefinite(H, tol))) return R;

  // A saddle of tr(R^T A) (e.g. A = -I from the identity) or no convergence: take the SVD answer,
  // unless it is no better than where Newton ended (A's null directions leave a choice).
  const Eigen::Matrix3d Rsvd = rotationBySvd(A);
  if (stats != nullptr) stats->usedSvd = true;
  if ((Rsvd.transpose() * A).trace() > (R.transpose() * A).trace() + tol) {
    q = Eigen::Quaterniond(Rsvd);
    q.normalize();
  }
  return q.toRotationMatrix();
}

static_assert(kRotationBatch == kLanes, "one matrix per SIMD lane");
static_assert(sizeof(Eigen::Quaterniond) == 4 * sizeof(double), "quaternions as 4 doubles (x, y, z, w)");

void extractRotationBatch(int count, const double* a, Eigen::Quaterniond* quat, double* r) {
  if (count <= 0) return;  // nothing to read, and quat may be null
  detail::regionKernels().rotationBatch(count, a, quat->coeffs().data(), r, PolarOptions().angleTolerance);
}

void detail::extractRotationGeneral(const double* a, double* q, double* r) {
  const Eigen::Matrix3d A = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(a);
  Eigen::Map<Eigen::Quaterniond> quat(q);
  Eigen::Quaterniond warm = quat;
  Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> rotation(r);
  rotation = extractRotation(A, warm);
  quat = warm;
}

Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& A) {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  return extractRotation(A, q);
}

}  // namespace deformable_flsm
