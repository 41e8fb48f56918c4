// The implicit step's two-level preconditioner (core/two_level_preconditioner.h): its coarse
// matrix, assembled from the region moments, is the Galerkin product P^T A P that the matrix-free
// product gives column by column, with fixed particles outside the coarse space; the
// preconditioner is symmetric and positive definite (what PCG needs).
#include "deformable_flsm/core/corotated_hessian.h"
#include "deformable_flsm/core/fast_summation.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/two_level_preconditioner.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>

using deformable_flsm::CorotatedHessian;
using deformable_flsm::Lattice;
using deformable_flsm::RegionSummer;
using deformable_flsm::SliceStreamSummer;
using deformable_flsm::TwoLevelPreconditioner;

namespace {

using deformable_flsm::test::Rest;

/// An L-shaped lattice (regions clipped by the surface and by the notch, aggregates cut by both).
std::shared_ptr<const Lattice> lShape(int w) {
  const auto vox = deformable_flsm::test::makeVoxels(Eigen::Vector3i(9, 7, 6), 0.01,
                                                     [](int i, int j, int) { return i < 4 || j < 3; });
  return std::make_shared<const Lattice>(vox, 1000.0, w);
}

/// Random region rotations, coefficients and diagonal: a linearisation point of a deformed object.
struct Point {
  std::vector<Eigen::Quaterniond> rotations;
  std::vector<double> beta, weightSum, invCount;
  std::vector<Eigen::Vector3d> diagonal;
  Point(const Lattice& L, RegionSummer& summer, unsigned seed) {
    const std::size_t n = L.size();
    std::mt19937 rng(seed);
    std::uniform_real_distribution<double> u(0.5, 1.5);
    for (std::size_t r = 0; r < n; ++r)
      rotations.push_back(Eigen::Quaterniond(Eigen::AngleAxisd(u(rng), Eigen::Vector3d(u(rng), u(rng) - 1.0, 0.3).normalized())));
    beta.resize(n);
    for (double& b : beta) b = u(rng);
    std::vector<double> one(n, 1.0), count;
    summer.scatter(beta, 1, weightSum);  // sum over the regions that contain i
    summer.scatter(one, 1, count);
    for (double c : count) invCount.push_back(1.0 / c);
    for (std::size_t i = 0; i < n; ++i) diagonal.push_back(Eigen::Vector3d(u(rng), u(rng), u(rng)) * L.masses()[i]);
  }
};

}  // namespace

// P^T (D + sum_r c_r K_r) P from the regions' moments equals the product with each coarse
// column; pinned particles are outside P; a rank-one term and an edge add what their quadratic
// forms say.
TEST(TwoLevelPreconditioner, CoarseMatrixIsTheGalerkinProduct) {
  for (int w : {1, 2}) {
    const auto L = lShape(w);
    const std::size_t n = L->size();
    SliceStreamSummer summer(*L, 1);
    const Rest rest(*L, summer);
    CorotatedHessian K(summer, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
    const Point point(*L, summer, 7u + static_cast<unsigned>(w));
    K.setRotations(point.rotations);
    K.setCoefficients(3.0, 0.5, point.beta, point.weightSum, point.invCount);
    TwoLevelPreconditioner pre(*L, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0, 1000);
    EXPECT_GE(pre.aggregateSize(), 2 * w);
    std::vector<char> pinned(n, 0), dragged(n, 0);
    for (std::size_t i = 0; i < n; ++i) pinned[i] = L->cells()[i].x() == 0 ? 1 : 0;
    pre.setFixed(summer, pinned, dragged);
    pre.beginAssembly(point.diagonal, K);
    pre.addRegions(K);
    const Eigen::MatrixXd& Ac = pre.coarseMatrix();
    constexpr int kModes = TwoLevelPreconditioner::kModes;
    const Eigen::Index N = kModes * static_cast<Eigen::Index>(pre.aggregates());
    ASSERT_EQ(Ac.rows(), N);
    // the oracle: A applied to each column of P
    std::vector<std::vector<Eigen::Vector3d>> AP(static_cast<std::size_t>(N), std::vector<Eigen::Vector3d>(n));
    for (Eigen::Index c = 0; c < N; ++c) {
      std::vector<Eigen::Vector3d> column(n, Eigen::Vector3d::Zero());
      for (std::size_t i = 0; i < n; ++i)
        if (pre.aggregateOf(i) == c / kModes) column[i] = pre.prolongation(i).col(c % kModes);
      K.apply(summer, point.diagonal, column, AP[static_cast<std::size_t>(c)]);
    }
    double scale = 0.0;
    for (Eigen::Index c = 0; c < N; ++c) scale = std::max(scale, std::abs(Ac(c, c)));
    for (Eigen::Index a = 0; a < N; ++a)
      for (Eigen::Index b = 0; b < N; ++b) {
        double expected = 0.0;
        for (std::size_t i = 0; i < n; ++i)
          if (pre.aggregateOf(i) == a / kModes)
            expected += pre.prolongation(i).col(a % kModes).dot(AP[static_cast<std::size_t>(b)][i]);
        // round-off of the window sums and of the sums over up to a few hundred particles
        ASSERT_NEAR(Ac(a, b), expected, 1e-10 * scale) << "w " << w << " entry " << a << ", " << b;
      }
    // rank-one and edge terms: u^T A_c u grows by weight (v . P u)^2 and k |(P u)_i - (P u)_j|^2
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> uni(-1.0, 1.0);
    Eigen::VectorXd u(N);
    for (Eigen::Index c = 0; c < N; ++c) u[c] = uni(rng);
    const auto field = [&](std::size_t i) -> Eigen::Vector3d {
      const int a = pre.aggregateOf(i);
      return a < 0 ? Eigen::Vector3d::Zero() : Eigen::Vector3d(pre.prolongation(i) * u.segment<kModes>(kModes * a));
    };
    const double before = u.dot(Ac * u);
    const std::uint32_t ends[3] = {0, static_cast<std::uint32_t>(n / 2), static_cast<std::uint32_t>(n - 1)};
    const Eigen::Vector3d g[3] = {Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(-2, 0.5, 1), Eigen::Vector3d(0.3, -1, 2)};
    pre.addOuter(ends, g, 3, 2.0);
    pre.addEdge(ends[1], ends[2], 5.0);
    double vp = 0.0;
    for (int k = 0; k < 3; ++k) vp += g[k].dot(field(ends[k]));
    const double expected = before + 2.0 * vp * vp + 5.0 * (field(ends[1]) - field(ends[2])).squaredNorm();
    EXPECT_NEAR(u.dot(pre.coarseMatrix() * u), expected, 1e-12 * std::abs(expected));
  }
}

// z = D^-1 r + P A_c^-1 P^T r is symmetric and positive: a . M^-1 b = b . M^-1 a, a . M^-1 a > 0.
TEST(TwoLevelPreconditioner, IsSymmetricPositiveDefinite) {
  const auto L = lShape(1);
  const std::size_t n = L->size();
  SliceStreamSummer summer(*L, 1);
  const Rest rest(*L, summer);
  CorotatedHessian K(summer, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
  const Point point(*L, summer, 11u);
  K.setRotations(point.rotations);
  K.setCoefficients(1e3, 1.0, point.beta, point.weightSum, point.invCount);
  TwoLevelPreconditioner pre(*L, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0, 16);
  EXPECT_LE(pre.aggregates(), 16u);
  std::vector<char> pinned(n, 0), dragged(n, 0);
  pre.setFixed(summer, pinned, dragged);
  pre.beginAssembly(point.diagonal, K);
  pre.addRegions(K);
  ASSERT_TRUE(pre.factorize());
  std::vector<Eigen::Vector3d> invD(n), a(n), b(n), za(n), zb(n);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> uni(-1.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) {
    invD[i] = point.diagonal[i].cwiseInverse();
    a[i] = Eigen::Vector3d(uni(rng), uni(rng), uni(rng));
    b[i] = Eigen::Vector3d(uni(rng), uni(rng), uni(rng));
  }
  pre.apply(invD, a, za);
  pre.apply(invD, b, zb);
  double ab = 0.0, ba = 0.0, aa = 0.0, jacobi = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    ab += a[i].dot(zb[i]);
    ba += b[i].dot(za[i]);
    aa += a[i].dot(za[i]);
    jacobi += a[i].dot(invD[i].cwiseProduct(a[i]));
  }
  EXPECT_NEAR(ab, ba, 1e-10 * aa);
  EXPECT_GT(aa, jacobi) << "the coarse part adds a positive term";
}

// The coarse space holds the rigid motions of the object as it lies: rotated as a whole by R (every
// region's rotation R), the velocity field w x (R q_i) + v of any spin w and drift v is P u for some
// u (each aggregate translates and turns about its centre), so the coarse solve carries rotation
// and bending, not only translation. (An L whose faces fall on aggregate boundaries: an aggregate
// cut down to a line of particles moves by translation only.)
TEST(TwoLevelPreconditioner, CoarseSpaceHoldsTheRotatedObjectsRigidMotions) {
  const auto L = std::make_shared<const Lattice>(
      deformable_flsm::test::makeVoxels(Eigen::Vector3i(8, 6, 6), 0.01, [](int i, int j, int) { return i < 4 || j < 2; }),
      1000.0, 1);
  const std::size_t n = L->size();
  SliceStreamSummer summer(*L, 1);
  const Rest rest(*L, summer);
  CorotatedHessian K(summer, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
  const Point point(*L, summer, 13u);
  const Eigen::Quaterniond R(Eigen::AngleAxisd(1.1, Eigen::Vector3d(0.3, -0.5, 0.8).normalized()));
  K.setRotations(std::vector<Eigen::Quaterniond>(n, R));
  K.setCoefficients(1.0, 0.0, point.beta, point.weightSum, point.invCount);
  TwoLevelPreconditioner pre(*L, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0, 1000);
  ASSERT_EQ(pre.aggregateSize(), 2);
  std::vector<char> pinned(n, 0), dragged(n, 0);
  pre.setFixed(summer, pinned, dragged);
  pre.beginAssembly(point.diagonal, K);
  constexpr int kModes = TwoLevelPreconditioner::kModes;
  const Eigen::Index N = kModes * static_cast<Eigen::Index>(pre.aggregates());
  Eigen::MatrixXd P = Eigen::MatrixXd::Zero(3 * static_cast<Eigen::Index>(n), N);
  for (std::size_t i = 0; i < n; ++i)
    P.block<3, kModes>(3 * static_cast<Eigen::Index>(i), kModes * pre.aggregateOf(i)) = pre.prolongation(i);
  const Eigen::Vector3d w(0.4, -1.2, 0.7), v(0.1, 0.2, -0.3);
  Eigen::VectorXd p(3 * static_cast<Eigen::Index>(n));
  for (std::size_t i = 0; i < n; ++i) p.segment<3>(3 * static_cast<Eigen::Index>(i)) = w.cross(R * rest.q[i]) + v;
  const Eigen::VectorXd u = P.colPivHouseholderQr().solve(p);
  // round-off of a least-squares fit over ~1e3 rows
  EXPECT_LT((P * u - p).norm(), 1e-10 * p.norm());
}

// The coarse factorisation is kept while A changes little and renewed when it does: an aggregate
// turned beyond the bound, a changed diagonal (a spring drag added) or an age beyond the bound.
TEST(TwoLevelPreconditioner, AssemblesAgainWhenTheAggregatesTurnOrTheDiagonalChanges) {
  const auto L = lShape(1);
  const std::size_t n = L->size();
  SliceStreamSummer summer(*L, 1);
  const Rest rest(*L, summer);
  CorotatedHessian K(summer, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
  const Point point(*L, summer, 17u);
  K.setRotations(point.rotations);
  K.setCoefficients(10.0, 1.0, point.beta, point.weightSum, point.invCount);
  TwoLevelPreconditioner pre(*L, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0, 16);
  std::vector<char> pinned(n, 0), dragged(n, 0);
  pre.setFixed(summer, pinned, dragged);
  constexpr double kTurn = 0.05;
  constexpr int kAge = 5;
  ASSERT_TRUE(pre.needsAssembly(point.diagonal, K, kTurn, kAge)) << "never assembled";
  pre.beginAssembly(point.diagonal, K);
  pre.addRegions(K);
  ASSERT_TRUE(pre.factorize());
  EXPECT_FALSE(pre.needsAssembly(point.diagonal, K, kTurn, kAge));
  // every region turned by half the bound: kept; by twice the bound: assembled again
  const auto turned = [&](double angle) {
    std::vector<Eigen::Quaterniond> r = point.rotations;
    for (auto& q : r) q = Eigen::Quaterniond(Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ())) * q;
    return r;
  };
  K.setRotations(turned(0.5 * kTurn));
  EXPECT_FALSE(pre.needsAssembly(point.diagonal, K, kTurn, kAge));
  K.setRotations(turned(2.0 * kTurn));
  EXPECT_TRUE(pre.needsAssembly(point.diagonal, K, kTurn, kAge));
  K.setRotations(point.rotations);
  std::vector<Eigen::Vector3d> stiffer = point.diagonal;
  stiffer[n / 2] *= 2.0;
  EXPECT_TRUE(pre.needsAssembly(stiffer, K, kTurn, kAge));
  // unchanged inputs: kept for kAge calls after the assembly (four made above), then renewed
  int calls = 4;
  do {
    ++calls;
  } while (!pre.needsAssembly(point.diagonal, K, kTurn, kAge));
  EXPECT_EQ(calls, kAge + 1);
}
