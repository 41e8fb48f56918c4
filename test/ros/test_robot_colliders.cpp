/// @file test_robot_colliders.cpp
/// Tests of ros/robot_colliders.h: a URDF's collision elements as colliders (shapes, origins,
/// ids, link frames, mesh scale per axis, friction), links chosen by patterns with a warning for
/// a pattern that matches nothing, errors that name what to fix, and the start-up overlap test.
#include "deformable_flsm/ros/robot_colliders.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/ros/param_loader.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace deformable_flsm {
namespace {

/// A closed unit cube (urdf/meshes/unit_box.stl), by file:// URL.
std::string unitBoxUrl() { return std::string("file://") + FLSM_TEST_DIR + "/../urdf/meshes/unit_box.stl"; }

std::string urdf() {
  return R"(<?xml version="1.0"?>
<robot name="test_arm">
  <link name="world"/>
  <link name="base">
    <collision>
      <origin xyz="0 0 0.5" rpy="0 0 1.5707963267948966"/>
      <geometry><box size="0.1 0.2 0.3"/></geometry>
    </collision>
  </link>
  <link name="arm">
    <collision><geometry><cylinder radius="0.02" length="0.3"/></geometry></collision>
    <collision>
      <origin xyz="0 0 0.15"/>
      <geometry><sphere radius="0.05"/></geometry>
    </collision>
  </link>
  <link name="hand">
    <collision>
      <geometry><mesh filename=")" + unitBoxUrl() + R"(" scale="0.1 0.2 0.3"/></geometry>
    </collision>
    <visual><geometry><sphere radius="1"/></geometry></visual>
  </link>
  <link name="camera"><visual><geometry><sphere radius="0.01"/></geometry></visual></link>
  <joint name="j0" type="fixed"><parent link="world"/><child link="base"/></joint>
  <joint name="j1" type="fixed"><parent link="base"/><child link="arm"/></joint>
  <joint name="j2" type="fixed"><parent link="arm"/><child link="hand"/></joint>
  <joint name="j3" type="fixed"><parent link="hand"/><child link="camera"/></joint>
</robot>
)";
}

RobotColliderOptions options() {
  RobotColliderOptions o;
  o.descriptionParam = "/robot_description";
  o.staticFriction = 0.9;
  o.kineticFriction = 0.7;
  return o;
}

const RobotCollider& find(const RobotColliders& r, const std::string& id) {
  for (const RobotCollider& c : r.colliders)
    if (c.spec.id == id) return c;
  throw std::runtime_error("no collider " + id);
}

std::string errorOf(const std::string& xml, const RobotColliderOptions& o) {
  try {
    parseRobotColliders(xml, o);
  } catch (const ParamError& e) {
    return e.what();
  }
  return "";
}

TEST(RobotColliders, EveryCollisionElementFollowsItsLinkAtItsOrigin) {
  const RobotColliders r = parseRobotColliders(urdf(), options());
  EXPECT_EQ(r.robotName, "test_arm");
  ASSERT_EQ(r.colliders.size(), 4u) << "camera has no collision geometry, world none at all";
  EXPECT_TRUE(r.warnings.empty());

  const RobotCollider& base = find(r, "robot/base/0");
  EXPECT_EQ(base.link, "base");
  EXPECT_EQ(base.spec.followFrame, "base");
  EXPECT_EQ(base.spec.collider.shape.type, ColliderType::Box);
  EXPECT_TRUE(base.spec.collider.shape.halfExtents.isApprox(Eigen::Vector3d(0.05, 0.1, 0.15)));
  EXPECT_TRUE(base.spec.collider.pose.translation().isApprox(Eigen::Vector3d(0, 0, 0.5)));
  EXPECT_TRUE((base.spec.collider.pose.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-9))
      << "rpy yaw 90 degrees turns x into y";
  EXPECT_EQ(base.spec.collider.staticFriction, 0.9);
  EXPECT_EQ(base.spec.collider.kineticFriction, 0.7);

  const RobotCollider& rod = find(r, "robot/arm/0");
  EXPECT_EQ(rod.spec.collider.shape.type, ColliderType::Cylinder) << "an exact cylinder, not a capsule";
  EXPECT_DOUBLE_EQ(rod.spec.collider.shape.radius, 0.02);
  EXPECT_DOUBLE_EQ(rod.spec.collider.shape.halfLength, 0.15);
  const RobotCollider& ball = find(r, "robot/arm/1");
  EXPECT_EQ(ball.link, "arm");
  EXPECT_EQ(ball.spec.collider.shape.type, ColliderType::Sphere);
  EXPECT_TRUE(ball.spec.collider.pose.translation().isApprox(Eigen::Vector3d(0, 0, 0.15)));

  // The unit cube scaled per axis: its distance field is that of the 0.1 x 0.2 x 0.3 box.
  const RobotCollider& hand = find(r, "robot/hand/0");
  ASSERT_EQ(hand.spec.collider.shape.type, ColliderType::Mesh);
  ASSERT_TRUE(hand.spec.collider.shape.distanceField);
  Eigen::Vector3d lo, hi, n;
  ASSERT_TRUE(colliderBounds(hand.spec.collider.shape, Eigen::Isometry3d::Identity(), lo, hi));
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3d(0.05, 0.1, 0.15), 1e-9)) << hi.transpose();
  EXPECT_NEAR(shapeDistance(hand.spec.collider.shape, Eigen::Vector3d(0, 0, 0.25), n), 0.1, 1e-3);
  EXPECT_EQ(hand.spec.meshUrl, unitBoxUrl());
}

TEST(RobotColliders, PatternsChooseLinksAndOneMatchingNothingIsNamed) {
  RobotColliderOptions o = options();
  o.includeLinks = {"arm|hand", "gripper_.*"};
  o.excludeLinks = {"hand", "wrist"};
  const RobotColliders r = parseRobotColliders(urdf(), o);
  ASSERT_EQ(r.colliders.size(), 2u);
  for (const RobotCollider& c : r.colliders) EXPECT_EQ(c.link, "arm");
  std::string all;
  for (const std::string& w : r.warnings) all += w + "\n";
  EXPECT_NE(all.find("~robot_links pattern 'gripper_.*' matches no link"), std::string::npos) << all;
  EXPECT_NE(all.find("~robot_exclude_links pattern 'wrist' matches no link"), std::string::npos) << all;
  EXPECT_NE(all.find("arm, base, camera, hand, world"), std::string::npos) << "lists the links: " << all;
  EXPECT_EQ(all.find("'arm|hand'"), std::string::npos) << all;
  // Patterns match whole names: "ar" is not "arm".
  o.includeLinks = {"ar"};
  o.excludeLinks = {};
  EXPECT_TRUE(parseRobotColliders(urdf(), o).colliders.empty());
}

TEST(RobotColliders, ErrorsNameWhatToFix) {
  const std::string broken = errorOf("<robot name='x'><link name='a'/><joint name='j' type='fixed'>"
                                     "<parent link='a'/><child link='b'/></joint></robot>",
                                     options());
  EXPECT_NE(broken.find("~robot_description ('/robot_description')"), std::string::npos) << broken;
  EXPECT_NE(broken.find("does not parse"), std::string::npos) << broken;
  EXPECT_NE(errorOf("", options()).find("does not parse"), std::string::npos);

  RobotColliderOptions o = options();
  o.includeLinks = {"arm["};
  const std::string regex = errorOf(urdf(), o);
  EXPECT_NE(regex.find("~robot_links pattern 'arm['"), std::string::npos) << regex;

  std::string missing = urdf();
  missing.replace(missing.find("unit_box.stl"), 12, "no_such.stl");
  const std::string mesh = errorOf(missing, options());
  EXPECT_NE(mesh.find("robot link 'hand' <collision> 0"), std::string::npos) << mesh;
  EXPECT_NE(mesh.find("no_such.stl"), std::string::npos) << mesh;
  EXPECT_NE(mesh.find("~robot_exclude_links"), std::string::npos) << mesh;

  const std::string flat = "<robot name='f'><link name='plate'><collision><geometry>"
                           "<cylinder radius='0.1' length='0'/></geometry></collision></link></robot>";
  const std::string zero = errorOf(flat, options());
  EXPECT_NE(zero.find("robot link 'plate'"), std::string::npos) << zero;
  EXPECT_NE(zero.find("cylinder half length"), std::string::npos) << zero;
}

TEST(RobotColliders, OverlapIsAContactSphereReachingIntoTheShape) {
  ColliderShape ball;
  ball.type = ColliderType::Sphere;
  ball.radius = 0.1;
  const Eigen::Isometry3d pose(Eigen::Translation3d(1, 0, 0));
  const std::vector<Eigen::Vector3d> particles{{1.12, 0, 0}, {3, 3, 3}};
  EXPECT_TRUE(overlapsParticles(ball, pose, particles, 0.03)) << "0.02 from the surface, r = 0.03";
  EXPECT_FALSE(overlapsParticles(ball, pose, particles, 0.01)) << "0.02 from the surface, r = 0.01";
  EXPECT_FALSE(overlapsParticles(ball, Eigen::Isometry3d::Identity(), particles, 0.03));
}

}  // namespace
}  // namespace deformable_flsm
