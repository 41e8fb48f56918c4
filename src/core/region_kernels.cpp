// The region pass's per-region kernels (region_kernels.h), compiled once for the build's own
// level and, in a build for the x86-64 baseline, once more for x86-64-v3 and for x86-64-v4
// (CMakeLists.txt: FLSM_KERNEL_LEVEL names the copy). Everything but the entries has internal
// linkage, and nothing here is Eigen's or the standard library's beyond <cmath>'s built-in
// functions and <limits>' constants: see the header.
#include "region_kernels.h"

#include "lanes.h"

#include <cmath>
#include <limits>

#ifndef FLSM_KERNEL_LEVEL
#define FLSM_KERNEL_LEVEL Own
#endif
#define FLSM_KERNEL_PASTE(name, level) name##level
#define FLSM_KERNEL_NAME(name, level) FLSM_KERNEL_PASTE(name, level)

namespace deformable_flsm {
namespace detail {

namespace {

constexpr int L = kLanes;

/// Newton steps a lane takes before handing over to the general routine.
constexpr int kFastIterations = 8;

inline double larger(double a, double b) { return a < b ? b : a; }

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

/// A full batch's count as a constant: its lane loops unroll with fixed lanes.
struct FullBatch {
  constexpr operator int() const { return kLanes; }
};

template <class Count>
void rotationBatch(Count count, const double* a, double* quat, double* r, double angleTolerance) {
  const Lanes zero = {}, one = zero + 1.0;
  // structure of arrays, lane l = matrix l; unused lanes hold the identity (converged at once)
  Lanes A[9], qw = one, qx = zero, qy = zero, qz = zero, tol = zero;
  LaneMask fallback = {}, done = {};
  for (int k = 0; k < 9; ++k) A[k] = k % 4 == 0 ? one : zero;
  for (int l = 0; l < count; ++l) {
    double m = 0.0;
    for (int k = 0; k < 9; ++k) {
      A[k][l] = a[9 * l + k];
      m = larger(m, std::abs(a[9 * l + k]));
    }
    const double* q = quat + 4 * l;
    qw[l] = q[3];
    qx[l] = q[0];
    qy[l] = q[1];
    qz[l] = q[2];
    tol[l] = kSaddleTolerance * m;
    const double qn = qw[l] * qw[l] + qx[l] * qx[l] + qy[l] * qy[l] + qz[l] * qz[l];
    // NaN or infinity in A fails the pivot test below
    if (!(m > 0.0 && m <= std::numeric_limits<double>::max() && std::abs(qn - 1.0) < 1e-12))
      fallback[l] = done[l] = -1;
  }
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
    double* q = quat + 4 * l;
    if (fallback[l] != 0 || done[l] == 0) {
      // the general routine, from the unchanged warm start (q has not been written yet)
      extractRotationGeneral(a + 9 * l, q, r + 9 * l);
      continue;
    }
    q[0] = qx[l];
    q[1] = qy[l];
    q[2] = qz[l];
    q[3] = qw[l];
    for (int k = 0; k < 9; ++k) r[9 * l + k] = R[k][l];
  }
}

/// The damping field's rigid velocity of regions [first, first + count) of a batch (lane k the
/// region first + k of `sums`, `in` channels each), their centres c, masses M and inverses iM in
/// the lanes; u and w into channels 12..17 of `out` (`outK` channels a region).
template <class Count>
void regionVelocityField(const double* sums, std::size_t first, Count count, int in, const Lanes c[3],
                         const Lanes& M, const Lanes& iM, double* out, int outK, double rankTolerance) {
  // Rigid velocity field u + w x p of each region: v_r = sum m~ v / M, angular momentum about c
  // L_r = sum p x m~ v - c x sum m~ v, second moment about c P = sum m~ p p^T - M c c^T,
  // inertia I = tr(P) 1 - P, w = I^+ L_r (solveInertia(): the cofactor solve here, lanes that
  // are not clearly positive definite go to the general routine), u = v_r - w x c.
  Lanes mv[3] = {}, l[3] = {}, pp[6] = {};
  for (int k = 0; k < count; ++k) {
    const double* s = sums + (first + static_cast<std::size_t>(k)) * in;
    for (int i = 0; i < 3; ++i) {
      mv[i][k] = s[12 + i];
      l[i][k] = s[15 + i];
    }
    for (int i = 0; i < 6; ++i) pp[i][k] = s[18 + i];
  }
  Lanes vr[3], Lr[3];
  for (int i = 0; i < 3; ++i) vr[i] = mv[i] * iM;
  Lr[0] = l[0] - (c[1] * mv[2] - c[2] * mv[1]);
  Lr[1] = l[1] - (c[2] * mv[0] - c[0] * mv[2]);
  Lr[2] = l[2] - (c[0] * mv[1] - c[1] * mv[0]);
  const Lanes p00 = pp[0] - M * c[0] * c[0], p11 = pp[1] - M * c[1] * c[1], p22 = pp[2] - M * c[2] * c[2];
  const Lanes p01 = pp[3] - M * c[0] * c[1], p02 = pp[4] - M * c[0] * c[2], p12 = pp[5] - M * c[1] * c[2];
  const Lanes h00 = p11 + p22, h11 = p00 + p22, h22 = p00 + p11, h01 = -p01, h02 = -p02, h12 = -p12;
  const Lanes trace = h00 + h11 + h22;
  const Lanes tol = rankTolerance * trace;
  const Lanes zero = {};
  Lanes w[3];
  LaneMask positive;
  solveSymmetricPositive3(h00, h11, h22, h01, h02, h12, Lr, tol, w, positive);
  const LaneMask fast = (trace > zero) & positive;
  for (int k = 0; k < count; ++k) {
    if (fast[k] != 0) continue;
    const double I[9] = {h00[k], h01[k], h02[k], h01[k], h11[k], h12[k], h02[k], h12[k], h22[k]};
    const double Lk[3] = {Lr[0][k], Lr[1][k], Lr[2][k]};
    double wk[3];
    solveInertiaGeneral(I, Lk, wk);
    for (int i = 0; i < 3; ++i) w[i][k] = wk[i];
  }
  Lanes u[3];
  u[0] = vr[0] - (w[1] * c[2] - w[2] * c[1]);
  u[1] = vr[1] - (w[2] * c[0] - w[0] * c[2]);
  u[2] = vr[2] - (w[0] * c[1] - w[1] * c[0]);
  for (int k = 0; k < count; ++k) {
    double* t = out + (first + static_cast<std::size_t>(k)) * outK;
    for (int i = 0; i < 3; ++i) {
      t[12 + i] = u[i][k];
      t[15 + i] = w[i][k];
    }
  }
}

template <class Count>
void regionBatchOf(Count count, const RegionBatchArgs& g, std::size_t r0) {
  const std::size_t begin = g.begin;
  const int in = g.in, outK = g.outK;
  double A[L * 9], R[L * 9];
  if (count != L)  // a part batch: rotationBatch() reads no lane past count, but GCC cannot tell
    for (double& x : A) x = 0.0;
  Lanes c[3] = {}, c0[3] = {}, beta = {}, M = {}, iM = {};
  for (int l = 0; l < count; ++l) {
    const std::size_t r = r0 + static_cast<std::size_t>(l);
    const double* s = g.sums + (r - begin) * in;
    M[l] = g.mass[r];
    iM[l] = g.invMass[r];
    beta[l] = g.weight[r];
    for (int i = 0; i < 3; ++i) {
      c[i][l] = s[i] * iM[l];
      c0[i][l] = g.restCenter[3 * r + i];
    }
    // A = sum m~ p q^T - M c c0^T (row-major)
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j) A[9 * l + 3 * i + j] = s[3 + 3 * i + j] - M[l] * c[i][l] * c0[j][l];
  }
  rotationBatch(count, A, g.quat + 4 * r0, R, g.angleTolerance);
  for (int l = 0; l < count; ++l) {
    double* t = g.out + (r0 + static_cast<std::size_t>(l) - begin) * outK;
    const double* Rl = R + 9 * l;
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) t[3 * i + j] = beta[l] * Rl[3 * i + j];
      t[9 + i] = beta[l] * (c[i][l] - (Rl[3 * i] * c0[0][l] + Rl[3 * i + 1] * c0[1][l] + Rl[3 * i + 2] * c0[2][l]));
    }
  }
  if (g.damping) regionVelocityField(g.sums, r0 - begin, count, in, c, M, iM, g.out, outK, g.inertiaRankTolerance);
}

void regionBatch(const RegionBatchArgs& g) {
  // Regions in batches of kLanes, one SIMD lane each: the rotations are extracted together, and
  // the damping field's inertia solve runs in the lanes too.
  std::size_t r0 = g.begin;
  for (; r0 + L <= g.end; r0 += L) regionBatchOf(FullBatch(), g, r0);
  if (r0 < g.end) regionBatchOf(static_cast<int>(g.end - r0), g, r0);
}

}  // namespace

void FLSM_KERNEL_NAME(rotationBatch, FLSM_KERNEL_LEVEL)(int count, const double* a, double* q, double* r,
                                                         double angleTolerance) {
  if (count == L)
    rotationBatch(FullBatch(), a, q, r, angleTolerance);
  else
    rotationBatch(count, a, q, r, angleTolerance);
}

void FLSM_KERNEL_NAME(regionBatch, FLSM_KERNEL_LEVEL)(const RegionBatchArgs& args) { regionBatch(args); }

double FLSM_KERNEL_NAME(fusedMultiplyAddProbe, FLSM_KERNEL_LEVEL)(double a, double c) { return a * a - c; }

}  // namespace detail
}  // namespace deformable_flsm
