// A scene's colliders posed over a step in one place (ColliderScene), the one contact query every
// contact solver asks of a posed collider (PosedCollider), and a wrench's contacts counted once per
// particle and collider whichever solver met it (ContactTally).
#include "deformable_flsm/core/collider_scene.h"
#include "deformable_flsm/core/contact_tally.h"
#include "deformable_flsm/core/world.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <stdexcept>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::world_scenes;

namespace {

// The closed form of a rigid motion at constant velocities: x(t) = x + v t, R(t) = exp(t [w]) R.
Eigen::Isometry3d movedBy(const Eigen::Isometry3d& pose, const Eigen::Vector3d& v, const Eigen::Vector3d& w, double t) {
  Eigen::Isometry3d out = pose;
  out.translation() += v * t;
  out.linear() = Eigen::AngleAxisd(w.norm() * t, w.normalized()).toRotationMatrix() * pose.linear();
  return out;
}

}  // namespace

TEST(ColliderScene, SubstepPosesFollowTheVelocitiesFromTheStepsStart) {
  ColliderScene scene;
  Collider c = box(Eigen::Vector3d(0.1, -0.2, 0.3), Eigen::Vector3d(0.02, 0.03, 0.04));
  c.pose.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(1, 2, 3).normalized()).toRotationMatrix();
  c.linearVelocity = Eigen::Vector3d(0.5, -0.25, 1.0);
  c.angularVelocity = Eigen::Vector3d(0.3, -2.0, 1.2);
  scene.map()["b"] = c;
  scene.map()["a"] = ground(0.0);
  scene.changed();
  ASSERT_EQ(scene.posed().size(), 2u);
  EXPECT_EQ(*scene.posed()[0].id, "a") << "in id order, as the map";
  const PosedCollider& b = scene.posed()[1];
  const double T = 0.05, H = T / 5;
  scene.beginStep();
  for (int s = 0; s < 5; ++s) {
    scene.poseSubstep(s, H);
    EXPECT_TRUE(b.before.isApprox(movedBy(c.pose, c.linearVelocity, c.angularVelocity, s * H), 1e-12)) << s;
    EXPECT_TRUE(b.now.isApprox(movedBy(c.pose, c.linearVelocity, c.angularVelocity, (s + 1) * H), 1e-12)) << s;
    Eigen::Vector3d lo, hi;
    ASSERT_TRUE(colliderBounds(c.shape, b.now, lo, hi));
    EXPECT_TRUE(b.bounded && lo == b.lo && hi == b.hi) << "the bounds at the sub-step's end";
    EXPECT_FALSE(scene.posed()[0].bounded) << "a half-space has no bounds";
  }
  scene.endStep(T);
  EXPECT_TRUE(scene.map().at("b").pose.isApprox(movedBy(c.pose, c.linearVelocity, c.angularVelocity, T), 1e-12))
      << "left where the step took it, in the map";
  scene.beginStep();
  EXPECT_TRUE(b.start.isApprox(scene.map().at("b").pose, 0.0)) << "the next step starts from there";
}

TEST(ColliderScene, NearSaysFalseOnlyForPointsFartherThanTheMargin) {
  Collider shapes[3];
  shapes[0] = box(Eigen::Vector3d::Zero(), Eigen::Vector3d(0.02, 0.05, 0.01));
  shapes[1].shape.type = ColliderType::Sphere;
  shapes[1].shape.radius = 0.03;
  shapes[2].shape.type = ColliderType::Capsule;
  shapes[2].shape.radius = 0.01;
  shapes[2].shape.halfLength = 0.04;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-0.12, 0.12);
  for (Collider& c : shapes) {
    ColliderScene scene;
    c.pose.linear() = Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, -1, 2).normalized()).toRotationMatrix();
    c.pose.translation() = Eigen::Vector3d(0.01, 0.02, -0.01);
    scene.map()["c"] = c;
    scene.changed();
    const PosedCollider& p = scene.posed()[0];
    int culled = 0;
    for (int i = 0; i < 20000; ++i) {
      const Eigen::Vector3d x(u(rng), u(rng), u(rng));
      const double margin = 0.01;
      if (p.near(x, margin)) continue;
      ++culled;
      Eigen::Vector3d n;
      ASSERT_GT(p.gap(x, 0.0, n), margin) << "culled a point within the margin";
    }
    EXPECT_GT(culled, 1000) << "the bounds cull most far points";
  }
}

TEST(ContactTally, EachParticleCountsOncePerColliderInTheLastSubstep) {
  ContactTally tally;
  tally.resize(10, 130);  // more colliders than one word of bits
  std::vector<std::size_t> counts(130, 0);
  const auto count = [&] {
    std::fill(counts.begin(), counts.end(), 0);
    tally.count([&](std::size_t c) { ++counts[c]; });
  };
  tally.beginSubstep();
  tally.touch(3, 0);
  tally.touch(3, 0);  // the same contact met by a second solver
  tally.touch(4, 0);
  tally.touch(3, 129);
  tally.touch(9, 64);
  count();
  EXPECT_EQ(counts[0], 2u);
  EXPECT_EQ(counts[64], 1u);
  EXPECT_EQ(counts[129], 1u);
  tally.beginSubstep();  // a new sub-step forgets the last one's
  tally.touch(4, 129);
  count();
  EXPECT_EQ(counts[0], 0u);
  EXPECT_EQ(counts[129], 1u);
  EXPECT_EQ(counts[64], 0u);
}

TEST(ContactTally, AStackedBlocksBottomLayerIsCountedOnceOnTheGround) {
  // the bottom block is pressed onto the ground by the top one: its bottom particles meet the
  // ground in its own contact pass and in the object contact's rows, and are counted once
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  auto bottom = boxAt(5, 5, 3, 0.01, Eigen::Vector3d(0, 0, 0.001));
  world.addObject("bottom", bottom, paramsFor(*bottom, 0.5, 2.0));
  auto top = boxAt(5, 5, 3, 0.01, Eigen::Vector3d(0, 0, 0.033));
  world.addObject("top", top, paramsFor(*top, 0.5, 2.0));
  for (int i = 0; i < stepsFor(2.0); ++i) world.step();
  double mean = 0.0;  // over a second: what the ground carried, whatever is left of the settling
  for (int i = 0; i < stepsFor(1.0); ++i) {
    world.step();
    mean += world.contactWrench("ground").force.z() / stepsFor(1.0);
  }
  EXPECT_EQ(world.contactWrench("ground").contacts, 25u) << "the 5 x 5 bottom layer";
  EXPECT_EQ(world.objectWrench("bottom", "top").contacts, 25u);
  const double weight = (bottom->totalMass() + top->totalMass()) * kG;
  EXPECT_NEAR(mean, -weight, 0.02 * weight) << "the ground carries both";
}

TEST(ContactTally, AnotherSolversContactOutsideTheObjectIsRefused) {
  auto lattice = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0.001));
  Solver s(lattice, paramsFor(*lattice));
  s.setCollider("ground", ground(0.0));
  EXPECT_NO_THROW(s.touchCollider(0, 0));
  EXPECT_THROW(s.touchCollider(static_cast<std::uint32_t>(s.positions().size()), 0), std::out_of_range);
  EXPECT_THROW(s.touchCollider(0, 1), std::out_of_range);
  EXPECT_THROW(s.addColliderImpulse(1, Eigen::Vector3d::UnitZ(), Eigen::Vector3d::Zero()), std::out_of_range);
  ColliderScene scene;
  scene.map()["a"] = ground(0.0);  // added without changed(): the scene cannot pose it
  EXPECT_THROW(scene.endStep(0.01), std::logic_error);
}
