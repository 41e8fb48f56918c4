#include "deformable_flsm/core/polar.h"

#include "deformable_flsm/core/small_matrix.h"
#include "lanes.h"
#include "simd_dispatch.h"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace deformable_flsm {

namespace {

/// Newton converges quadratically: after a step of length |theta| the error left is about
/// c |theta|^2, with c of order one for a well-conditioned H. Stopping once c |theta|^2 is below
/// the tolerance (c taken as this margin) saves the iteration that would only confirm it.
constexpr double kQuadraticMargin = 100.0;
/// Relative tolerance for "H is positive semi-definite" (scaled by |A|): Newton's fixed point
/// must be a maximum of tr(R^T A), not a saddle; round-off of order 1e-12 |A| is not a saddle.
constexpr double kSaddleTolerance = 1e-9;

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

namespace {

/// Newton steps a lane takes before handing over to the general routine.
constexpr int kFastIterations = 8;

/// Row-major rotation matrices of unit quaternions (w, x, y, z), one per SIMD lane.
inline void quaternionToMatrix(const Lanes& w, const Lanes& x, const Lanes& y, const Lanes& z, Lanes* r) {
  const Lanes xx = x * x, yy = y * y, zz = z * z, xy = x * y, xz = x * z, yz = y * z;
  const Lanes wx = w * x, wy = w * y, wz = w * z;
  r[0] = 1.0 - 2.0 * (yy + zz);
  r[1] = 2.0 * (xy - wz);
  r[2] = 2.0 * (xz + wy);
  r[3] = 2.0 * (xy + wz);
  r[4] = 1.0 - 2.0 * (xx + zz);
  r[5] = 2.0 * (yz - wx);
  r[6] = 2.0 * (xz - wy);
  r[7] = 2.0 * (yz + wx);
  r[8] = 1.0 - 2.0 * (xx + yy);
}

/// S = R^T A, per lane (row-major 3 x 3).
[[gnu::always_inline]] inline void transposeTimes(const Lanes* R, const Lanes* A, Lanes* S) {
  const Lanes r0 = R[0], r1 = R[1], r2 = R[2], r3 = R[3], r4 = R[4], r5 = R[5], r6 = R[6], r7 = R[7], r8 = R[8];
  S[0] = r0 * A[0] + r3 * A[3] + r6 * A[6];
  S[1] = r0 * A[1] + r3 * A[4] + r6 * A[7];
  S[2] = r0 * A[2] + r3 * A[5] + r6 * A[8];
  S[3] = r1 * A[0] + r4 * A[3] + r7 * A[6];
  S[4] = r1 * A[1] + r4 * A[4] + r7 * A[7];
  S[5] = r1 * A[2] + r4 * A[5] + r7 * A[8];
  S[6] = r2 * A[0] + r5 * A[3] + r8 * A[6];
  S[7] = r2 * A[1] + r5 * A[4] + r8 * A[7];
  S[8] = r2 * A[2] + r5 * A[5] + r8 * A[8];
}

}  // namespace

static_assert(kRotationBatch == kLanes, "one matrix per SIMD lane");

namespace {

/// extractRotationBatch()'s work, compiled for each SIMD level (withSimd()).
void rotationBatch(int count, const double* a, Eigen::Quaterniond* quat, double* r) {
  constexpr int L = kRotationBatch;
  const Lanes zero = {}, one = zero + 1.0;
  // structure of arrays, lane l = matrix l; unused lanes hold the identity (converged at once)
  Lanes A[9], qw = one, qx = zero, qy = zero, qz = zero, tol = zero;
  LaneMask fallback = {}, done = {};
  for (int k = 0; k < 9; ++k) A[k] = k % 4 == 0 ? one : zero;
  for (int l = 0; l < count; ++l) {
    double m = 0.0;
    for (int k = 0; k < 9; ++k) {
      A[k][l] = a[9 * l + k];
      m = std::max(m, std::abs(a[9 * l + k]));
    }
    qw[l] = quat[l].w();
    qx[l] = quat[l].x();
    qy[l] = quat[l].y();
    qz[l] = quat[l].z();
    tol[l] = kSaddleTolerance * m;
    const double qn = qw[l] * qw[l] + qx[l] * qx[l] + qy[l] * qy[l] + qz[l] * qz[l];
    // NaN or infinity in A fails the pivot test below
    if (!(m > 0.0 && m <= std::numeric_limits<double>::max() && std::abs(qn - 1.0) < 1e-12))
      fallback[l] = done[l] = -1;
  }
  const double angleTolerance = PolarOptions().angleTolerance;
  const Lanes tol2 = zero + angleTolerance * angleTolerance;
  const Lanes tolQ = zero + angleTolerance / kQuadraticMargin;
  for (int it = 0; it < kFastIterations; ++it) {
    bool all = true;
    for (int l = 0; l < L; ++l) all = all && done[l] != 0;
    if (all) break;
    const Lanes w = qw, x = qx, y = qy, z = qz;
    Lanes rm[9];
    quaternionToMatrix(w, x, y, z, rm);
    Lanes S[9];
    transposeTimes(rm, A, S);
    const Lanes s0 = S[0], s1 = S[1], s2 = S[2], s3 = S[3], s4 = S[4], s5 = S[5], s6 = S[6], s7 = S[7], s8 = S[8];
    const Lanes gx = s7 - s5, gy = s2 - s6, gz = s3 - s1;
    const Lanes tr = s0 + s4 + s8;
    const Lanes h00 = tr - s0, h11 = tr - s4, h22 = tr - s8;
    const Lanes h01 = -0.5 * (s1 + s3), h02 = -0.5 * (s2 + s6), h12 = -0.5 * (s5 + s7);
    // H theta = g, in the lanes where H is clearly positive definite (a maximum)
    const Lanes g[3] = {gx, gy, gz};
    Lanes theta[3];
    LaneMask positive;
    solveSymmetricPositive3(h00, h11, h22, h01, h02, h12, g, tol, theta, positive);
    const Lanes tx = theta[0], ty = theta[1], tz = theta[2];
    const Lanes angle2 = tx * tx + ty * ty + tz * tz;
    // q <- q * (1, theta / 2), normalised
    const Lanes hx = 0.5 * tx, hy = 0.5 * ty, hz = 0.5 * tz;
    const Lanes nw = w - (x * hx + y * hy + z * hz);
    const Lanes nx = x + w * hx + (y * hz - z * hy);
    const Lanes ny = y + w * hy + (z * hx - x * hz);
    const Lanes nz = z + w * hz + (x * hy - y * hx);
    const Lanes norm2 = nw * nw + nx * nx + ny * ny + nz * nz;
    Lanes ninv;
    for (int l = 0; l < L; ++l) ninv[l] = 1.0 / std::sqrt(norm2[l]);
    const LaneMask active = done == 0;
    const LaneMask fail = active & ~positive;
    const LaneMask still = active & positive & ~(angle2 < tol2);
    fallback |= fail;
    qw = still ? nw * ninv : w;
    qx = still ? nx * ninv : x;
    qy = still ? ny * ninv : y;
    qz = still ? nz * ninv : z;
    done |= fail | ~still | (angle2 < tolQ);
  }
  Lanes R[9];
  quaternionToMatrix(qw, qx, qy, qz, R);
  for (int l = 0; l < count; ++l) {
    if (fallback[l] != 0 || done[l] == 0) {
      // the general routine, from the unchanged warm start (quat[l] has not been written yet)
      const Eigen::Matrix3d A = Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>>(a + 9 * l);
      Eigen::Map<Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> out(r + 9 * l);
      out = extractRotation(A, quat[l]);
      continue;
    }
    quat[l] = Eigen::Quaterniond(qw[l], qx[l], qy[l], qz[l]);
    for (int k = 0; k < 9; ++k) r[9 * l + k] = R[k][l];
  }
}

}  // namespace

void extractRotationBatch(int count, const double* a, Eigen::Quaterniond* quat, double* r) {
  detail::withSimd([&] { rotationBatch(count, a, quat, r); });
}

Eigen::Matrix3d extractRotation(const Eigen::Matrix3d& A) {
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  return extractRotation(A, q);
}

}  // namespace deformable_flsm
