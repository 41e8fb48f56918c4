#include "deformable_flsm/core/polar.h"

#include <gtest/gtest.h>

#include <Eigen/SVD>

#include <limits>
#include <random>
#include <vector>

using deformable_flsm::extractRotation;
using deformable_flsm::PolarStats;

namespace {

/// Orthonormality and det = +1 to round-off of a few ulps of a unit matrix.
constexpr double kRotationTolerance = 1e-12;

void expectProperRotation(const Eigen::Matrix3d& R) {
  ASSERT_TRUE(R.allFinite());
  EXPECT_LT((R.transpose() * R - Eigen::Matrix3d::Identity()).norm(), kRotationTolerance);
  EXPECT_NEAR(R.determinant(), 1.0, kRotationTolerance);
}

Eigen::Matrix3d randomRotation(std::mt19937& rng) {
  std::normal_distribution<double> n(0.0, 1.0);
  Eigen::Quaterniond q(n(rng), n(rng), n(rng), n(rng));
  return q.normalized().toRotationMatrix();
}

/// The reference: closest proper rotation by SVD, tr(R^T A) maximal.
double bestTrace(const Eigen::Matrix3d& A) {
  Eigen::JacobiSVD<Eigen::Matrix3d> svd(A, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d U = svd.matrixU();
  if ((U * svd.matrixV().transpose()).determinant() < 0) U.col(2) *= -1;
  return (U * svd.matrixV().transpose()).transpose().cwiseProduct(A.transpose()).sum();
}

}  // namespace

TEST(Polar, PureRotationIsRecoveredExactlyFromAnyWarmStart) {
  std::mt19937 rng(1);
  for (int t = 0; t < 200; ++t) {
    const Eigen::Matrix3d Rtrue = randomRotation(rng);
    Eigen::Quaterniond q(randomRotation(rng));
    const Eigen::Matrix3d R = extractRotation(Rtrue, q);
    expectProperRotation(R);
    EXPECT_LT((R - Rtrue).norm(), 1e-12) << "trial " << t;
  }
}

TEST(Polar, MatchesSvdPolarFactorForStretchedMatrices) {
  std::mt19937 rng(2);
  std::uniform_real_distribution<double> s(0.2, 5.0);
  for (int t = 0; t < 200; ++t) {
    const Eigen::Matrix3d Q = randomRotation(rng);
    const Eigen::Matrix3d V = randomRotation(rng);
    const Eigen::Matrix3d S = V * Eigen::Vector3d(s(rng), s(rng), s(rng)).asDiagonal() * V.transpose();
    const Eigen::Matrix3d A = Q * S;
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    const Eigen::Matrix3d R = extractRotation(A, q);
    expectProperRotation(R);
    // Polar factor is unique for det A > 0; S has condition <= 25, so 1e-10 is generous.
    EXPECT_LT((R - Q).norm(), 1e-10) << "trial " << t;
  }
}

TEST(Polar, WarmStartConvergesInFewIterations) {
  // A step's rotation differs from the last by a small angle: Newton should need <= 3 iterations.
  const Eigen::Matrix3d A = Eigen::AngleAxisd(0.3, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix() *
                            Eigen::Vector3d(1.1, 0.9, 1.05).asDiagonal();
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.29, Eigen::Vector3d(1, 2, 3).normalized()));
  PolarStats stats;
  extractRotation(A, q, deformable_flsm::PolarOptions(), &stats);
  EXPECT_LE(stats.iterations, 3);
  EXPECT_FALSE(stats.usedSvd);
}

TEST(Polar, DegenerateMatricesGiveProperRotationsWithoutNaN) {
  std::mt19937 rng(3);
  const Eigen::Matrix3d Q = randomRotation(rng);
  const Eigen::Vector3d a(1.0, 2.0, -0.5), b(0.3, -1.0, 2.0);
  const std::vector<std::pair<const char*, Eigen::Matrix3d>> cases = {
      {"zero", Eigen::Matrix3d::Zero()},
      {"collinear (rank 1)", a * b.transpose()},
      {"planar (rank 2)", Q * Eigen::Vector3d(2.0, 1.0, 0.0).asDiagonal()},
      {"inverted (det < 0)", Q * Eigen::Vector3d(1.0, 1.0, -1.0).asDiagonal()},
      {"point reflection -I", -Eigen::Matrix3d::Identity()},
      {"180 degree turn", Eigen::Vector3d(-1.0, -1.0, 1.0).asDiagonal()},
      {"tiny", 1e-300 * Q},
      {"huge", 1e300 * Q},
  };
  for (const auto& c : cases) {
    for (int start = 0; start < 5; ++start) {
      Eigen::Quaterniond q = start == 0 ? Eigen::Quaterniond::Identity() : Eigen::Quaterniond(randomRotation(rng));
      const Eigen::Matrix3d R = extractRotation(c.second, q);
      SCOPED_TRACE(c.first);
      expectProperRotation(R);
      // Optimal: tr(R^T A) equals the SVD optimum (relative 1e-9 of |A|).
      const double scale = std::max(1e-300, c.second.norm());
      EXPECT_GE((R.transpose() * c.second).trace() / scale, bestTrace(c.second) / scale - 1e-9);
    }
  }
}

TEST(Polar, ZeroMatrixKeepsTheWarmStart) {
  Eigen::Quaterniond q(Eigen::AngleAxisd(0.7, Eigen::Vector3d::UnitY()));
  const Eigen::Quaterniond before = q;
  extractRotation(Eigen::Matrix3d::Zero(), q);
  EXPECT_LT((q.toRotationMatrix() - before.toRotationMatrix()).norm(), 1e-15);
}

TEST(Polar, NonFiniteInputLeavesWarmStartAndNeverReturnsNaN) {
  Eigen::Matrix3d A = Eigen::Matrix3d::Identity();
  A(1, 2) = std::numeric_limits<double>::quiet_NaN();
  Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
  expectProperRotation(extractRotation(A, q));
}

// The batch (one SIMD lane per matrix) gives what the general routine gives, lane by lane, in
// batches that mix the usual case (a deformed rotation, warm start near it) with the cases the
// lanes hand over (zero, planar, inverted, non-finite A; a warm start far away), in every lane
// position and for every batch size; and a lane's result does not depend on its batch mates.
TEST(Polar, BatchEqualsTheGeneralRoutineLaneByLane) {
  using deformable_flsm::extractRotationBatch;
  using deformable_flsm::kRotationBatch;
  std::mt19937 rng(17);
  std::normal_distribution<double> n(0.0, 1.0);
  std::vector<Eigen::Matrix3d> cases;
  std::vector<Eigen::Quaterniond> starts;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Matrix3d R = randomRotation(rng);
    Eigen::Matrix3d S = Eigen::Matrix3d::Identity();
    for (int a = 0; a < 3; ++a)
      for (int b = 0; b < 3; ++b) S(a, b) += 0.1 * n(rng);
    cases.push_back(1e-6 * R * S);  // region-sized entries
    const Eigen::Quaterniond near = Eigen::Quaterniond(R) * Eigen::Quaterniond(1.0, 0.02 * n(rng), 0.02 * n(rng), 0.02 * n(rng)).normalized();
    starts.push_back(i % 5 == 4 ? Eigen::Quaterniond(randomRotation(rng)) : near);
  }
  cases[3].setZero();
  cases[7] = Eigen::Vector3d(1, 2, 3) * Eigen::Vector3d(0, 1, 1).transpose() + Eigen::Vector3d(2, -1, 0) * Eigen::Vector3d(1, 0, 0).transpose();
  cases[11] = -Eigen::Matrix3d::Identity();
  cases[13](1, 2) = std::numeric_limits<double>::quiet_NaN();
  cases[17](0, 0) = std::numeric_limits<double>::infinity();

  std::vector<Eigen::Matrix3d> expected(cases.size());
  std::vector<Eigen::Quaterniond> expectedQ(cases.size());
  for (std::size_t i = 0; i < cases.size(); ++i) {
    expectedQ[i] = starts[i];
    expected[i] = extractRotation(cases[i], expectedQ[i]);
  }
  for (int count = 1; count <= kRotationBatch; ++count) {
    for (std::size_t first = 0; first + count <= cases.size(); first += count) {
      std::vector<double> a(9 * count), r(9 * count);
      std::vector<Eigen::Quaterniond> q(starts.begin() + first, starts.begin() + first + count);
      for (int l = 0; l < count; ++l)
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) a[9 * l + 3 * i + j] = cases[first + l](i, j);
      extractRotationBatch(count, a.data(), q.data(), r.data());
      for (int l = 0; l < count; ++l) {
        const std::size_t c = first + l;
        Eigen::Matrix3d R;
        for (int i = 0; i < 3; ++i)
          for (int j = 0; j < 3; ++j) R(i, j) = r[9 * l + 3 * i + j];
        expectProperRotation(R);
        EXPECT_LT((R - expected[c]).cwiseAbs().maxCoeff(), 1e-12) << "case " << c << ", batch of " << count;
        EXPECT_LT((q[l].toRotationMatrix() - R).cwiseAbs().maxCoeff(), 1e-12) << "case " << c;
      }
    }
  }
}
