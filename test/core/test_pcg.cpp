// Preconditioned conjugate gradients with prescribed entries (core/pcg.h), against a dense
// solve of the same system: the constrained parts of x keep their values, the free part solves
// the filtered equations, and residual() is b - A x, which a caller can correct for a change of b
// and solve again from, without a product with A.
#include "deformable_flsm/core/pcg.h"

#include <gtest/gtest.h>

#include <Eigen/Dense>

#include <random>
#include <vector>

using deformable_flsm::Pcg;
using deformable_flsm::PcgConstraint;

namespace {

constexpr int kParticles = 12;

/// A random symmetric positive definite 3n x 3n system, with every kind of constraint.
struct System {
  Eigen::MatrixXd A;
  std::vector<Eigen::Vector3d> b, normal, invDiagonal;
  std::vector<PcgConstraint> constraint;
  explicit System(unsigned seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    const int n = 3 * kParticles;
    Eigen::MatrixXd G(n, n);
    for (int i = 0; i < n; ++i)
      for (int j = 0; j < n; ++j) G(i, j) = u(rng);
    A = G * G.transpose() + n * Eigen::MatrixXd::Identity(n, n);
    for (int i = 0; i < kParticles; ++i) {
      b.emplace_back(u(rng), u(rng), u(rng));
      normal.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)).normalized());
      invDiagonal.push_back(A.diagonal().segment<3>(3 * i).cwiseInverse());
      constraint.push_back(i % 4 == 1 ? PcgConstraint::Fixed
                                      : (i % 4 == 3 ? PcgConstraint::Normal : PcgConstraint::Free));
    }
  }
  void apply(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) const {
    Eigen::VectorXd v(3 * kParticles);
    for (int i = 0; i < kParticles; ++i) v.segment<3>(3 * i) = p[i];
    const Eigen::VectorXd w = A * v;
    for (int i = 0; i < kParticles; ++i) y[i] = w.segment<3>(3 * i);
  }
  /// The filtered system solved densely: x = x0 + S z with S^T A S z = S^T (b - A x0).
  std::vector<Eigen::Vector3d> exact(const std::vector<Eigen::Vector3d>& x0) const {
    const int n = 3 * kParticles;
    Eigen::MatrixXd S = Eigen::MatrixXd::Zero(n, n);
    Eigen::VectorXd v(n), rhs(n);
    for (int i = 0; i < kParticles; ++i) {
      Eigen::Matrix3d Si = Eigen::Matrix3d::Identity();
      if (constraint[i] == PcgConstraint::Fixed) Si.setZero();
      if (constraint[i] == PcgConstraint::Normal) Si -= normal[i] * normal[i].transpose();
      S.block<3, 3>(3 * i, 3 * i) = Si;
      v.segment<3>(3 * i) = x0[i];
      rhs.segment<3>(3 * i) = b[i];
    }
    // S A S + (1 - S) is SPD, and its solution has no part outside S's range
    const Eigen::MatrixXd M = S * A * S + (Eigen::MatrixXd::Identity(n, n) - S);
    const Eigen::VectorXd z = M.llt().solve(S * (rhs - A * v));
    std::vector<Eigen::Vector3d> x(kParticles);
    for (int i = 0; i < kParticles; ++i) x[i] = x0[i] + z.segment<3>(3 * i);
    return x;
  }
};

double maxDifference(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, (a[i] - b[i]).cwiseAbs().maxCoeff());
  return d;
}

}  // namespace

// Solved to 1e-12: the dense solution, the prescribed parts untouched, and residual() = b - A x.
TEST(Pcg, SolvesTheFilteredSystemAndKeepsItsResidual) {
  for (unsigned seed : {1u, 2u, 3u}) {
    const System sys(seed);
    std::vector<Eigen::Vector3d> x0(kParticles);
    std::mt19937 rng(seed + 10);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    for (auto& xi : x0) xi = Eigen::Vector3d(u(rng), u(rng), u(rng));
    std::vector<Eigen::Vector3d> x = x0;
    Pcg pcg;
    pcg.resize(kParticles);
    const auto product = [&sys](const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
      sys.apply(p, y);
    };
    const auto result = pcg.solve(product, sys.invDiagonal, sys.constraint, sys.normal, sys.b, x, 0.0, 1e-12, 200);
    EXPECT_TRUE(result.converged) << "seed " << seed;
    EXPECT_GT(result.initialResidual, 0.0);
    EXPECT_LT(maxDifference(x, sys.exact(x0)), 1e-10) << "seed " << seed;
    for (int i = 0; i < kParticles; ++i) {
      if (sys.constraint[i] == PcgConstraint::Fixed) {
        EXPECT_EQ(x[i], x0[i]);
      } else if (sys.constraint[i] == PcgConstraint::Normal) {
        EXPECT_NEAR(x[i].dot(sys.normal[i]), x0[i].dot(sys.normal[i]), 1e-12);
      }
    }
    std::vector<Eigen::Vector3d> Ax(kParticles), r(kParticles);
    sys.apply(x, Ax);
    for (int i = 0; i < kParticles; ++i) r[i] = sys.b[i] - Ax[i];
    EXPECT_LT(maxDifference(pcg.residual(), r), 1e-10) << "seed " << seed;
  }
}

// b changed at two entries (one free, one prescribed), the residual corrected by addToResidual():
// the next solve, started from the kept residual without a product, reaches the solution of the
// changed system, and takes the same iterations as one that computes its residual.
TEST(Pcg, SolvesAgainFromAResidualCorrectedForAChangedRightHandSide) {
  System sys(7);
  std::vector<Eigen::Vector3d> x0(kParticles, Eigen::Vector3d(0.1, -0.2, 0.3));
  std::vector<Eigen::Vector3d> x = x0;
  Pcg pcg;
  pcg.resize(kParticles);
  int products = 0;
  const auto product = [&](const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
    ++products;
    sys.apply(p, y);
  };
  pcg.solve(product, sys.invDiagonal, sys.constraint, sys.normal, sys.b, x, 0.0, 1e-12, 200);
  const Eigen::Vector3d d0(0.3, -0.1, 0.2), d1(-0.2, 0.4, 0.1);
  sys.b[0] += d0;
  pcg.addToResidual(0, d0);
  sys.b[3] += d1;  // a Normal entry
  pcg.addToResidual(3, d1);
  std::vector<Eigen::Vector3d> again = x, fresh = x;
  products = 0;
  const auto kept = pcg.solve(product, sys.invDiagonal, sys.constraint, sys.normal, sys.b, again, 0.0, 1e-12, 200, true);
  EXPECT_EQ(products, kept.iterations) << "no product for the initial residual";
  Pcg other;
  other.resize(kParticles);
  const auto computed = other.solve(product, sys.invDiagonal, sys.constraint, sys.normal, sys.b, fresh, 0.0, 1e-12, 200);
  EXPECT_TRUE(kept.converged);
  EXPECT_NEAR(kept.iterations, computed.iterations, 1);
  EXPECT_LT(maxDifference(again, sys.exact(x)), 1e-10);
  EXPECT_LT(maxDifference(again, fresh), 1e-10);
}
