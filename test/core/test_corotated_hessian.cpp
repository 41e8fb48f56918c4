// The co-rotated region stiffness as a product (core/corotated_hessian.h): symmetric, zero on the
// rigid motions of every region it is co-rotated with, positive on deformations, and the same
// from FastLSM's window sums as from the direct sums over each region.
#include "deformable_flsm/core/corotated_hessian.h"
#include "deformable_flsm/core/fast_summation.h"
#include "deformable_flsm/core/lattice.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <memory>
#include <random>

using deformable_flsm::CorotatedHessian;
using deformable_flsm::Lattice;
using deformable_flsm::NaiveSummer;
using deformable_flsm::RegionSummer;
using deformable_flsm::SliceStreamSummer;

namespace {

using deformable_flsm::test::Rest;

double dot(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) s += a[i].dot(b[i]);
  return s;
}

/// An L-shaped lattice (regions clipped by the surface and by the notch), w = 2.
std::shared_ptr<const Lattice> lShape() {
  const auto vox = deformable_flsm::test::makeVoxels(Eigen::Vector3i(7, 6, 5), 0.01,
                                                     [](int i, int j, int) { return i < 3 || j < 2; });
  return std::make_shared<const Lattice>(vox, 1000.0, 2);
}

}  // namespace

TEST(CorotatedHessian, SymmetricPositiveAndZeroOnRigidMotions) {
  const auto L = lShape();
  const std::size_t n = L->size();
  SliceStreamSummer summer(*L, 1);
  Rest rest(*L, summer);
  CorotatedHessian K(summer, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
  // every region turned by the same rotation R: the rigid motions t + theta x (R x0) are K's null space
  const Eigen::Quaterniond R(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  K.setRotations(std::vector<Eigen::Quaterniond>(n, R));
  std::vector<double> beta(n), weightSum(n), invCount(n);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (std::size_t i = 0; i < n; ++i) beta[i] = 1.0 + 0.5 * u(rng);
  std::vector<double> sums;
  summer.scatter(beta, 1, sums);
  for (std::size_t i = 0; i < n; ++i) {
    weightSum[i] = sums[i];
    invCount[i] = 1.0 / L->regionCounts()[i];
  }
  K.setCoefficients(2.0, 0.5, beta, weightSum, invCount);
  const std::vector<Eigen::Vector3d> zero(n, Eigen::Vector3d::Zero());
  std::vector<Eigen::Vector3d> a(n), b(n), Ka(n), Kb(n), rigid(n), Kr(n);
  const Eigen::Vector3d t(0.3, -0.2, 0.5), theta(1.0, -2.0, 0.5);
  double scale = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    a[i] = Eigen::Vector3d(u(rng), u(rng), u(rng));
    b[i] = Eigen::Vector3d(u(rng), u(rng), u(rng));
    rigid[i] = t + theta.cross(R * L->restPositions()[i]);
    scale += rigid[i].norm();
  }
  K.apply(summer, zero, a, Ka);
  K.apply(summer, zero, b, Kb);
  K.apply(summer, zero, rigid, Kr);
  const double kaa = dot(a, Ka), kbb = dot(b, Kb);
  EXPECT_GT(kaa, 0.0);
  EXPECT_GT(kbb, 0.0);
  // symmetric to round-off: a.Kb = b.Ka
  EXPECT_NEAR(dot(a, Kb), dot(b, Ka), 1e-12 * std::sqrt(kaa * kbb));
  double kr = 0.0;
  for (const Eigen::Vector3d& y : Kr) kr += y.norm();
  const double massScale = L->totalMass() / n * 2.0 * 27;  // m~ sum c_r over the up to (2w+1)^3 regions
  EXPECT_LT(kr, 1e-12 * massScale * scale) << "a rigid motion has no elastic force";
  // a deformation does: a uniform stretch along x
  std::vector<Eigen::Vector3d> stretch(n), Ks(n);
  for (std::size_t i = 0; i < n; ++i) stretch[i] = Eigen::Vector3d(R * L->restPositions()[i]).cwiseProduct(Eigen::Vector3d(1, 0, 0));
  K.apply(summer, zero, stretch, Ks);
  EXPECT_GT(dot(stretch, Ks), 0.0);
}

TEST(CorotatedHessian, WindowSumsEqualTheDirectSums) {
  const auto L = lShape();
  const std::size_t n = L->size();
  SliceStreamSummer fast(*L, 2);
  NaiveSummer naive(*L);
  Rest rest(*L, naive);
  CorotatedHessian Kf(fast, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
  CorotatedHessian Kn(naive, L->regionMassFractions(), rest.q, rest.regionMass, rest.c0);
  std::mt19937 rng(5);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Quaterniond> rotations(n);
  for (auto& q : rotations) q = Eigen::Quaterniond(1.0, 0.2 * u(rng), 0.2 * u(rng), 0.2 * u(rng)).normalized();
  std::vector<double> beta(n, 1.3), weightSum(n), invCount(n);
  for (std::size_t i = 0; i < n; ++i) {
    invCount[i] = 1.0 / L->regionCounts()[i];
    weightSum[i] = 1.3 / invCount[i];
  }
  for (CorotatedHessian* K : {&Kf, &Kn}) {
    K->setRotations(rotations);
    K->setCoefficients(1.5, 0.2, beta, weightSum, invCount);
  }
  std::vector<Eigen::Vector3d> D(n), p(n), yf(n), yn(n);
  for (std::size_t i = 0; i < n; ++i) {
    D[i] = Eigen::Vector3d::Constant(L->masses()[i]);
    p[i] = Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  Kf.apply(fast, D, p, yf);
  Kn.apply(naive, D, p, yn);
  double err = 0.0, norm = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    err = std::max(err, (yf[i] - yn[i]).norm());
    norm = std::max(norm, yn[i].norm());
  }
  // sliding windows add and subtract: round-off of a few ulps of the largest window sum
  EXPECT_LT(err, 1e-12 * norm);
}
