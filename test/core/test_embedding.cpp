#include "deformable_flsm/core/embedding.h"

#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/voxelizer.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <random>

using deformable_flsm::Embedding;
using deformable_flsm::Lattice;
using deformable_flsm::test::makeVoxels;

namespace {

/// An L-shaped lattice (so that the surface has concave and convex edges) and vertices spread
/// over and just beyond its occupied cells: every kind of missing corner occurs.
struct Scene {
  Lattice lattice;
  std::vector<Eigen::Vector3d> vertices;
};

Scene lShape() {
  const double h = 0.01;
  Scene s{Lattice(makeVoxels(Eigen::Vector3i(6, 5, 4), h, [](int i, int j, int) { return i < 2 || j < 2; }),
                  1000.0, 2),
          {}};
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (const auto& c : s.lattice.cells())
    for (int k = 0; k < 6; ++k)
      s.vertices.push_back(s.lattice.origin() + h * (c.cast<double>() + Eigen::Vector3d(u(rng), u(rng), u(rng))));
  // exactly on the outer faces and corners of the box
  s.vertices.emplace_back(0.0, 0.0, 0.0);
  s.vertices.emplace_back(0.06, 0.02, 0.04);
  s.vertices.emplace_back(0.02, 0.05, 0.0);
  return s;
}

std::vector<Eigen::Quaterniond> rotationsOf(std::size_t n, const Eigen::Matrix3d& R) {
  return std::vector<Eigen::Quaterniond>(n, Eigen::Quaterniond(R));
}

/// Largest distance between two vertex lists.
double maxDistance(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) d = std::max(d, (a[i] - b[i]).norm());
  return d;
}

}  // namespace

TEST(Embedding, ReproducesTheRestMeshExactly) {
  const Scene s = lShape();
  const Embedding e(s.lattice, s.vertices);
  EXPECT_GT(e.ghostCount(), 0u) << "the fixture should exercise ghost nodes";
  std::vector<Eigen::Vector3d> out;
  e.deform(s.lattice.restPositions(), rotationsOf(s.lattice.size(), Eigen::Matrix3d::Identity()), out);
  ASSERT_EQ(out.size(), s.vertices.size());
  // Trilinear weights sum to one: exact up to a few ulps of the coordinates (~1e-17 m).
  EXPECT_LT(maxDistance(out, s.vertices), 1e-15);
}

TEST(Embedding, FollowsRigidMotionExactly) {
  const Scene s = lShape();
  const Embedding e(s.lattice, s.vertices);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(1.9, Eigen::Vector3d(0.3, -1.0, 0.7).normalized()).toRotationMatrix();
  T.translation() = Eigen::Vector3d(-2.0, 0.5, 1.0);
  std::vector<Eigen::Vector3d> x;
  for (const auto& x0 : s.lattice.restPositions()) x.push_back(T * x0);
  std::vector<Eigen::Vector3d> out, expected;
  e.deform(x, rotationsOf(x.size(), T.linear()), out);
  for (const auto& v : s.vertices) expected.push_back(T * v);
  EXPECT_LT(maxDistance(out, expected), 1e-13);
}

TEST(Embedding, InteriorVerticesFollowAnyAffineDeformation) {
  // Trilinear interpolation is exact for affine maps where all 8 corners are particles.
  const Scene s = lShape();
  Eigen::Matrix3d F;
  F << 1.2, 0.1, 0.0, -0.05, 0.9, 0.2, 0.0, 0.3, 1.1;
  const Eigen::Vector3d t(0.01, 0.02, -0.03);
  std::vector<Eigen::Vector3d> inner;
  const double h = s.lattice.spacing();
  for (const auto& v : s.vertices) {
    const Eigen::Vector3d u = (v - s.lattice.origin()) / h - Eigen::Vector3d::Constant(0.5);
    const Eigen::Vector3i base = u.array().floor().cast<int>();
    bool all = true;
    for (int k = 0; k < 8; ++k)
      all = all && s.lattice.particleAt(base + Eigen::Vector3i(k & 1, (k >> 1) & 1, (k >> 2) & 1)) != Lattice::kNone;
    if (all) inner.push_back(v);
  }
  ASSERT_GT(inner.size(), 20u);
  const Embedding e(s.lattice, inner);
  std::vector<Eigen::Vector3d> x, out;
  for (const auto& x0 : s.lattice.restPositions()) x.push_back(F * x0 + t);
  e.deform(x, rotationsOf(x.size(), Eigen::Matrix3d::Identity()), out);
  for (std::size_t i = 0; i < inner.size(); ++i) EXPECT_LT((out[i] - (F * inner[i] + t)).norm(), 1e-15);
}

TEST(Embedding, BunnyRestAndRigidMotionAreExact) {
  const std::string path = deformable_flsm::kBunnyMeshPath;
  ASSERT_TRUE(std::filesystem::exists(path)) << path << " missing: install glmark2-data (a test dependency)";
  const auto mesh = deformable_flsm::loadMesh(path, 0.1);
  deformable_flsm::VoxelizeOptions opts;
  opts.resolution = 20;
  const Lattice lattice(deformable_flsm::voxelize(mesh, opts), 1000.0, 2);
  const Embedding e(lattice, mesh.vertices);
  std::vector<Eigen::Vector3d> out;
  e.deform(lattice.restPositions(), rotationsOf(lattice.size(), Eigen::Matrix3d::Identity()), out);
  // coordinates ~0.1 m: 1e-15 m is a few ulps
  EXPECT_LT(maxDistance(out, mesh.vertices), 1e-15);
  const Eigen::Matrix3d R = Eigen::AngleAxisd(-2.2, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
  std::vector<Eigen::Vector3d> x, expected;
  for (const auto& x0 : lattice.restPositions()) x.push_back(R * x0 + Eigen::Vector3d(0.3, 0.0, 0.0));
  for (const auto& v : mesh.vertices) expected.push_back(R * v + Eigen::Vector3d(0.3, 0.0, 0.0));
  e.deform(x, rotationsOf(x.size(), R), out);
  EXPECT_LT(maxDistance(out, expected), 1e-14);
}

TEST(Embedding, RejectsMismatchedState) {
  const Scene s = lShape();
  const Embedding e(s.lattice, s.vertices);
  std::vector<Eigen::Vector3d> out;
  EXPECT_THROW(e.deform({}, {}, out), std::invalid_argument);
}
