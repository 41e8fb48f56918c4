#include "deformable_flsm/core/corotated_hessian.h"

#include <Eigen/Eigenvalues>

namespace deformable_flsm {

namespace {

/// Rest-inertia eigenvalues below this fraction of the largest are treated as zero: a collinear
/// region has no rotation about its own line to project out, so its inverse is the
/// pseudo-inverse (as solveInertia() in the explicit step's damping).
constexpr double kInertiaRankTolerance = 1e-10;

}  // namespace

CorotatedHessian::CorotatedHessian(RegionSummer& summer, const std::vector<double>& massFractions,
                                   const std::vector<Eigen::Vector3d>& restCentered,
                                   const std::vector<double>& regionMass,
                                   const std::vector<Eigen::Vector3d>& regionRestCenter)
    : massFractions_(massFractions),
      restCentered_(restCentered),
      regionMass_(regionMass),
      regionRestCenter_(regionRestCenter) {
  const std::size_t n = massFractions.size();
  // I0_r = tr(P) 1 - P, P = sum m~ q q^T - M_r c0 c0^T the second moment about c0_r.
  std::vector<double> second(6 * n), secondSum;
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& q = restCentered[i];
    double* d = &second[6 * i];
    const double m = massFractions[i];
    d[0] = m * q.x() * q.x();
    d[1] = m * q.y() * q.y();
    d[2] = m * q.z() * q.z();
    d[3] = m * q.x() * q.y();
    d[4] = m * q.x() * q.z();
    d[5] = m * q.y() * q.z();
  }
  summer.gather(second, 6, secondSum);
  restInertiaInverse_.resize(n);
  Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig;
  for (std::size_t r = 0; r < n; ++r) {
    const double* S = &secondSum[6 * r];
    const Eigen::Vector3d& c0 = regionRestCenter[r];
    Eigen::Matrix3d P;
    P << S[0], S[3], S[4], S[3], S[1], S[5], S[4], S[5], S[2];
    P -= regionMass[r] * c0 * c0.transpose();
    const Eigen::Matrix3d I = P.trace() * Eigen::Matrix3d::Identity() - P;
    eig.computeDirect(I);
    const Eigen::Vector3d& lambda = eig.eigenvalues();
    const double cutoff = kInertiaRankTolerance * lambda.cwiseAbs().maxCoeff();
    Eigen::Vector3d inv;
    for (int k = 0; k < 3; ++k) inv[k] = lambda[k] > cutoff ? 1.0 / lambda[k] : 0.0;
    const Eigen::Matrix3d& V = eig.eigenvectors();
    restInertiaInverse_[r] = V * inv.asDiagonal() * V.transpose();
  }
  rotation_.assign(n, Eigen::Matrix3d::Identity());
  coefficient_.assign(n, 0.0);
  coefficientSum_.assign(n, 0.0);
}

void CorotatedHessian::setRotations(const std::vector<Eigen::Quaterniond>& rotations) {
  for (std::size_t r = 0; r < rotation_.size(); ++r) rotation_[r] = rotations[r].toRotationMatrix();
}

void CorotatedHessian::setCoefficients(double a, double b, const std::vector<double>& beta,
                                       const std::vector<double>& weightSum,
                                       const std::vector<double>& invCount) {
  for (std::size_t r = 0; r < coefficient_.size(); ++r) {
    coefficient_[r] = a * beta[r] + b;
    coefficientSum_[r] = a * weightSum[r] + b / invCount[r];
  }
}

void CorotatedHessian::apply(RegionSummer& summer, const std::vector<Eigen::Vector3d>& diagonal,
                             const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
  diagonal_ = &diagonal;
  input_ = &p;
  output_ = &y;
  summer.apply(*this);
  diagonal_ = nullptr;
  input_ = nullptr;
  output_ = nullptr;
}

void CorotatedHessian::particleData(std::size_t begin, std::size_t end, double* out) {
  const std::vector<Eigen::Vector3d>& p = *input_;
  for (std::size_t i = begin; i < end; ++i) {
    double* d = out + (i - begin) * 12;
    const Eigen::Vector3d mp = massFractions_[i] * p[i];
    const Eigen::Vector3d& q = restCentered_[i];
    d[0] = mp.x();
    d[1] = mp.y();
    d[2] = mp.z();
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) d[3 + 3 * a + b] = mp[a] * q[b];
  }
}

void CorotatedHessian::regionData(std::size_t begin, std::size_t end, const double* sums, double* out) {
  for (std::size_t r = begin; r < end; ++r) {
    const double* s = sums + (r - begin) * 12;
    double* o = out + (r - begin) * 12;
    const Eigen::Matrix3d& R = rotation_[r];
    const Eigen::Vector3d mp(s[0], s[1], s[2]);
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> S(s + 3);
    const Eigen::Matrix3d A = S * R.transpose();  // sum m~ p (R q)^T
    const Eigen::Vector3d Rc0 = R * regionRestCenter_[r];
    // sum m~ q~ x p, q~ = R (q - c0)
    const Eigen::Vector3d L = Eigen::Vector3d(A(2, 1) - A(1, 2), A(0, 2) - A(2, 0), A(1, 0) - A(0, 1)) - Rc0.cross(mp);
    const Eigen::Vector3d theta = R * (restInertiaInverse_[r] * (R.transpose() * L));
    const Eigen::Vector3d t = mp / regionMass_[r];
    const double c = coefficient_[r];
    // c [theta]x R: the fit's rotation part applied to q, theta x (R q) = ([theta]x R) q
    Eigen::Matrix3d thetaCross;
    thetaCross << 0.0, -theta.z(), theta.y(), theta.z(), 0.0, -theta.x(), -theta.y(), theta.x(), 0.0;
    const Eigen::Matrix3d B = c * (thetaCross * R);
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) o[3 * a + b] = B(a, b);
    const Eigen::Vector3d shift = c * (t - theta.cross(Rc0));
    o[9] = shift.x();
    o[10] = shift.y();
    o[11] = shift.z();
  }
}

void CorotatedHessian::particleResult(std::size_t begin, std::size_t end, const double* sums) {
  const std::vector<Eigen::Vector3d>& p = *input_;
  const std::vector<Eigen::Vector3d>& D = *diagonal_;
  std::vector<Eigen::Vector3d>& y = *output_;
  for (std::size_t i = begin; i < end; ++i) {
    const double* s = sums + (i - begin) * 12;
    const Eigen::Map<const Eigen::Matrix<double, 3, 3, Eigen::RowMajor>> B(s);
    const Eigen::Vector3d fit = B * restCentered_[i] + Eigen::Vector3d(s[9], s[10], s[11]);
    y[i] = D[i].cwiseProduct(p[i]) + massFractions_[i] * (coefficientSum_[i] * p[i] - fit);
  }
}

}  // namespace deformable_flsm
