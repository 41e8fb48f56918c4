// A scene's colliders kept once: a World's objects read the World's (Solver::shareColliders()),
// so that a collider added, moved or removed through the World is the one every object
// touches, moved once per step; changing them through an object is refused.
#include "deformable_flsm/core/world.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <stdexcept>

using namespace deformable_flsm;
using namespace deformable_flsm::world_scenes;

TEST(SharedColliders, EveryObjectReadsTheWorldsOneMap) {
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  world.addObject("a", boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0.001)), paramsFor(*boxAt(3, 3, 3, 0.01, {0, 0, 0})));
  world.addObject("b", boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0.1, 0, 0.001)),
                  paramsFor(*boxAt(3, 3, 3, 0.01, {0, 0, 0})));
  const Solver& a = *world.object("a");
  const Solver& b = *world.object("b");
  EXPECT_EQ(&a.colliders(), &b.colliders()) << "one map, not a copy per object";
  world.setCollider("wall", box(Eigen::Vector3d(0.5, 0, 0.05), Eigen::Vector3d(0.01, 0.1, 0.05)));
  EXPECT_EQ(a.colliders().size(), 2u);
  EXPECT_EQ(b.colliders().count("wall"), 1u);
  // moved at 1 m/s along x: after one step every object reads it one step further
  const Eigen::Isometry3d start = a.colliders().at("wall").pose;
  ASSERT_TRUE(world.moveCollider("wall", start, Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Zero()));
  world.step();
  EXPECT_NEAR(b.colliders().at("wall").pose.translation().x(), start.translation().x() + kStep, 1e-15);
  ASSERT_TRUE(world.removeCollider("wall"));
  EXPECT_EQ(a.colliders().count("wall"), 0u);
  // an object's colliders are the World's: changing them through it throws and changes nothing
  Solver& c = *world.object("a");
  EXPECT_THROW(c.setCollider("box", box(Eigen::Vector3d(0, 0, 1), Eigen::Vector3d::Constant(0.1))), std::logic_error);
  EXPECT_THROW(c.moveCollider("ground", Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()),
               std::logic_error);
  EXPECT_THROW(c.removeCollider("ground"), std::logic_error);
  EXPECT_THROW(c.removeAllColliders(), std::logic_error);
  EXPECT_EQ(b.colliders().size(), 1u);
}
