/// @file test_render_mesh.cpp
/// Tests of runtime/render_mesh.h: roll/pitch/yaw as in ROS, and meshoptimizer simplification to a
/// triangle budget with compact, valid output.
#include "deformable_flsm/runtime/render_mesh.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <filesystem>

namespace deformable_flsm {
namespace {

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;

TEST(RotationFromRpy, MatchesRosConvention) {
  // Roll about x turns y into z: the Y-up bunny stands up in Z-up ROS.
  const Eigen::Matrix3d roll = rotationFromRpy({M_PI / 2, 0.0, 0.0});
  EXPECT_TRUE((roll * Eigen::Vector3d::UnitY()).isApprox(Eigen::Vector3d::UnitZ(), 1e-12));
  // Fixed axes: roll first, then pitch, then yaw (R = Rz Ry Rx).
  const Eigen::Vector3d rpy(0.3, -0.2, 1.1);
  const Eigen::Matrix3d expected =
      (Eigen::AngleAxisd(1.1, Eigen::Vector3d::UnitZ()) *
       Eigen::AngleAxisd(-0.2, Eigen::Vector3d::UnitY()) *
       Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitX())).toRotationMatrix();
  EXPECT_TRUE(rotationFromRpy(rpy).isApprox(expected, 1e-12));
}

TEST(RotateMesh, RotatesVerticesKeepsTriangles) {
  TriMesh m;
  m.vertices = {{0, 1, 0}, {1, 0, 0}, {0, 0, 1}};
  m.triangles = {{0, 1, 2}};
  rotateMesh({M_PI / 2, 0.0, 0.0}, m);
  EXPECT_TRUE(m.vertices[0].isApprox(Eigen::Vector3d(0, 0, 1), 1e-12));
  EXPECT_TRUE(m.vertices[1].isApprox(Eigen::Vector3d(1, 0, 0), 1e-12));
  EXPECT_TRUE(m.vertices[2].isApprox(Eigen::Vector3d(0, -1, 0), 1e-12));
  EXPECT_EQ(m.triangles.size(), 1u);
}

TEST(SimplifyMesh, WithinBudgetIsUnchanged) {
  TriMesh m;
  m.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.triangles = {{0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};
  const SimplifyResult r = simplifyMesh(m, 4);
  EXPECT_EQ(r.mesh.triangles, m.triangles);
  EXPECT_EQ(r.mesh.vertices, m.vertices);
  EXPECT_EQ(r.relativeError, 0.0);
  EXPECT_THROW(simplifyMesh(m, 0), std::invalid_argument);
}

TEST(SimplifyMesh, BunnyMeetsTheBudgetWithCompactValidOutput) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const TriMesh bunny = loadMesh(kBunnyPath, 0.1);
  for (const std::size_t budget : {20000u, 2000u}) {
    SCOPED_TRACE(budget);
    const SimplifyResult r = simplifyMesh(bunny, budget);
    EXPECT_LE(r.mesh.triangles.size(), budget);
    EXPECT_GT(r.mesh.triangles.size(), budget / 2);  // not collapsed to nothing
    // Every vertex used, every index valid: the embedding gets only what is drawn.
    std::vector<char> used(r.mesh.vertices.size(), 0);
    for (const auto& t : r.mesh.triangles)
      for (const std::uint32_t v : t) {
        ASSERT_LT(v, r.mesh.vertices.size());
        used[v] = 1;
      }
    for (const char u : used) EXPECT_TRUE(u);
    EXPECT_NO_THROW(validateMesh(r.mesh, "simplified bunny"));
    // The shape survives: same bounding box to within 2 % of the extent.
    const double extent = (bunny.boundsMax() - bunny.boundsMin()).norm();
    EXPECT_LT((r.mesh.boundsMax() - bunny.boundsMax()).norm(), 0.02 * extent);
    EXPECT_LT((r.mesh.boundsMin() - bunny.boundsMin()).norm(), 0.02 * extent);
    EXPECT_LT(r.relativeError, 0.02);
  }
}

}  // namespace
}  // namespace deformable_flsm
