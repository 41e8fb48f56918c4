#include "deformable_flsm/core/corotated_hessian.h"

#include "inertia.h"

#include <Eigen/Eigenvalues>

#include <array>

namespace deformable_flsm {

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
  for (std::size_t r = 0; r < n; ++r) {
    const double* S = &secondSum[6 * r];
    const Eigen::Vector3d& c0 = regionRestCenter[r];
    Eigen::Matrix3d P;
    P << S[0], S[3], S[4], S[3], S[1], S[5], S[4], S[5], S[2];
    P -= regionMass[r] * c0 * c0.transpose();
    // a collinear region has no rotation about its own line to project out: the pseudo-inverse
    restInertiaInverse_[r] = InertiaInverse(P.trace() * Eigen::Matrix3d::Identity() - P).matrix();
  }
  rotation_.assign(n, Eigen::Matrix3d::Identity());
  rotatedCenter_ = regionRestCenter;
  rotatedInertiaInverse_.resize(n);
  for (std::size_t r = 0; r < n; ++r) {
    const Eigen::Matrix3d& J = restInertiaInverse_[r];
    rotatedInertiaInverse_[r] = {J(0, 0), J(1, 1), J(2, 2), J(0, 1), J(0, 2), J(1, 2)};
  }
  coefficient_.assign(n, 0.0);
  coefficientPerMass_.assign(n, 0.0);
  coefficientSum_.assign(n, 0.0);
}

// Per region, what every product of the sub-step shares: R_r, the rotated rest centre R_r c0_r and
// the rotated inverse inertia R_r I0_r^+ R_r^T (symmetric: its upper triangle).
void CorotatedHessian::setRotations(const std::vector<Eigen::Quaterniond>& rotations) {
  for (std::size_t r = 0; r < rotation_.size(); ++r) {
    const Eigen::Matrix3d R = rotations[r].toRotationMatrix();
    rotation_[r] = R;
    rotatedCenter_[r] = R * regionRestCenter_[r];
    const Eigen::Matrix3d J = R * restInertiaInverse_[r] * R.transpose();
    rotatedInertiaInverse_[r] = {J(0, 0), J(1, 1), J(2, 2), J(0, 1), J(0, 2), J(1, 2)};
  }
}

void CorotatedHessian::setCoefficients(double a, double b, const std::vector<double>& beta,
                                       const std::vector<double>& weightSum,
                                       const std::vector<double>& invCount) {
  for (std::size_t r = 0; r < coefficient_.size(); ++r) {
    coefficient_[r] = a * beta[r] + b;
    coefficientPerMass_[r] = coefficient_[r] / regionMass_[r];
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

// In scalars rather than Eigen's small vectors: built from components, those went through the
// stack, and their two 8-byte stores read back as one 16-byte load stalled the loop (store
// forwarding fails); this is the hottest loop of the implicit step.
void CorotatedHessian::regionData(std::size_t begin, std::size_t end, const double* sums, double* out) {
  for (std::size_t r = begin; r < end; ++r) {
    const double* s = sums + (r - begin) * 12;
    double* o = out + (r - begin) * 12;
    const Eigen::Matrix3d& R = rotation_[r];
    const double mx = s[0], my = s[1], mz = s[2];
    // A = S R^T (S = sum m~ p q^T, row-major at s + 3): only its antisymmetric part is needed,
    // A_ab = S_a . R_b (rows)
    const auto A = [&](int a, int b) { return s[3 + 3 * a] * R(b, 0) + s[4 + 3 * a] * R(b, 1) + s[5 + 3 * a] * R(b, 2); };
    const Eigen::Vector3d& Rc0 = rotatedCenter_[r];
    const double cx = Rc0.x(), cy = Rc0.y(), cz = Rc0.z();
    // L = sum m~ q~ x p, q~ = R (q - c0): vec(A) - (R c0) x sum m~ p
    const double Lx = A(2, 1) - A(1, 2) - (cy * mz - cz * my);
    const double Ly = A(0, 2) - A(2, 0) - (cz * mx - cx * mz);
    const double Lz = A(1, 0) - A(0, 1) - (cx * my - cy * mx);
    const std::array<double, 6>& J = rotatedInertiaInverse_[r];
    const double c = coefficient_[r];
    // c theta, theta = J L
    const double tx = c * (J[0] * Lx + J[3] * Ly + J[4] * Lz);
    const double ty = c * (J[3] * Lx + J[1] * Ly + J[5] * Lz);
    const double tz = c * (J[4] * Lx + J[5] * Ly + J[2] * Lz);
    // c [theta]x R: column b is c theta x (R e_b); theta x (R q) = ([theta]x R) q
    for (int b = 0; b < 3; ++b) {
      const double ux = R(0, b), uy = R(1, b), uz = R(2, b);
      o[b] = ty * uz - tz * uy;
      o[3 + b] = tz * ux - tx * uz;
      o[6 + b] = tx * uy - ty * ux;
    }
    // c / M_r sum m~ p - c theta x R c0
    const double cm = coefficientPerMass_[r];
    o[9] = cm * mx - (ty * cz - tz * cy);
    o[10] = cm * my - (tz * cx - tx * cz);
    o[11] = cm * mz - (tx * cy - ty * cx);
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
