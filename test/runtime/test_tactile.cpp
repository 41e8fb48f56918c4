/// @file test_tactile.cpp
/// Tests of runtime/tactile.h on contacts laid out by hand: each lands on the taxel under it,
/// pressure times area and shear add up to the forces on the face, contacts on other faces stay
/// out, a turned box is read in its own frame.
#include "deformable_flsm/runtime/tactile.h"

#include <gtest/gtest.h>

#include <cmath>
#include <numeric>
#include <vector>

namespace deformable_flsm {
namespace {

Collider pad() {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = Eigen::Vector3d(0.04, 0.01, 0.04);  // 8 x 2 x 8 cm, thin along y
  return c;
}

TEST(Tactile, FacesParse) {
  int axis = 0, sign = 0;
  ASSERT_TRUE(parseFace("-y", axis, sign));
  EXPECT_EQ(axis, 1);
  EXPECT_EQ(sign, -1);
  EXPECT_EQ(faceName(axis, sign), "-y");
  EXPECT_FALSE(parseFace("y", axis, sign));
  EXPECT_FALSE(parseFace("+w", axis, sign));
}

TEST(Tactile, EachContactLandsOnItsTaxelAndTheForcesAddUp) {
  // the pad's +y face (u = z, v = x), 4 x 8 taxels of 1 cm x 2 cm
  Collider box = pad();
  box.pose = Eigen::Translation3d(0.3, 0.2, 0.1) * Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ());
  TactileSpec spec;
  spec.name = "left";
  spec.collider = "pad";
  spec.axis = 1;
  spec.sign = 1;
  spec.rows = 4;
  spec.cols = 8;
  const Eigen::Matrix3d R = box.pose.linear();
  const auto world = [&](const Eigen::Vector3d& local) { return box.pose * local; };
  std::vector<ParticleContact> contacts;
  // on the face at local (x, 0.01, z), pushing in (-y) with some shear along z
  contacts.push_back({1, world({0.005, 0.01, -0.035}), R * Eigen::Vector3d(0.0, -2.0, 0.5)});
  contacts.push_back({2, world({-0.025, 0.0105, 0.015}), R * Eigen::Vector3d(0.1, -1.0, 0.0)});
  // just beyond the face's edge: the edge's taxel
  contacts.push_back({3, world({0.0, 0.01, 0.041}), R * Eigen::Vector3d(0.0, -0.5, 0.0)});
  // on the opposite face and on the bottom: elsewhere
  contacts.push_back({4, world({0.0, -0.01, 0.0}), R * Eigen::Vector3d(0.0, 3.0, 0.0)});
  contacts.push_back({5, world({0.0, 0.0, -0.04}), R * Eigen::Vector3d(0.0, 0.0, 1.0)});
  TactileImage image;
  tactileImage(spec, box, contacts, image);
  ASSERT_EQ(image.pressure.size(), 32u);
  EXPECT_NEAR(image.taxelArea, 0.01 * 0.02, 1e-15);
  const auto taxel = [&](int row, int col) { return image.pressure[static_cast<std::size_t>(row) * 8 + col]; };
  // contact 1: u = z = -0.035 -> column 0; v = x = 0.005 -> row 2
  EXPECT_NEAR(taxel(2, 0), 2.0 / image.taxelArea, 1e-3);
  // contact 2: z = 0.015 -> column 5; x = -0.025 -> row 0
  EXPECT_NEAR(taxel(0, 5), 1.0 / image.taxelArea, 1e-3);
  // contact 3: z = 0.041 -> the last column; x = 0 -> row 2
  EXPECT_NEAR(taxel(2, 7), 0.5 / image.taxelArea, 1e-3);
  double pa = 0.0;
  for (float p : image.pressure) pa += p * image.taxelArea;
  EXPECT_NEAR(pa, 3.5, 1e-5);
  EXPECT_NEAR(image.normalForce, 3.5, 1e-12);
  EXPECT_NEAR(image.shearForce.x(), 0.5, 1e-12);  // along u = z
  EXPECT_NEAR(image.shearForce.y(), 0.1, 1e-12);  // along v = x
  EXPECT_NEAR(image.shear[2 * (2 * 8 + 0)] * image.taxelArea, 0.5, 1e-6);
  EXPECT_TRUE(image.elsewhere.isApprox(R * Eigen::Vector3d(0.0, 3.0, 1.0), 1e-12));
  Collider ball;
  ball.shape.type = ColliderType::Sphere;
  ball.shape.radius = 0.1;
  EXPECT_THROW(tactileImage(spec, ball, contacts, image), std::invalid_argument);
}

}  // namespace
}  // namespace deformable_flsm
