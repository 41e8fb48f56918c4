/// @file test_collider_follower.cpp
/// Tests of ros/collider_follower.h (tf frames sampled without waiting, velocity from the last
/// two transforms, a frame not seen yet waited for, frames lost or stale after they were seen
/// held still and counted, short pauses harmless, a jump placed at rest, the admission test at the
/// first transform) and of the collider side of
/// runtime/simulation_loop.h (followed colliders join at their first pose, move along the sampled
/// velocity for a bounded time; collider commands applied or refused with a reason).
#include "deformable_flsm/ros/collider_follower.h"
#include "deformable_flsm/ros/collider_params.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include "../core/fixtures.h"
#include "../runtime/loop_harness.h"

#include <gtest/gtest.h>
#include <tf2_eigen/tf2_eigen.h>

#include <chrono>
#include <functional>
#include <thread>

namespace deformable_flsm {
namespace {

using Clock = std::chrono::steady_clock;

struct Posted {
  std::vector<std::pair<std::string, ColliderMotion>> motions;
  ColliderFollower::Post post() {
    return [this](const std::string& id, const ColliderMotion& m) { motions.emplace_back(id, m); };
  }
};

void setFrame(tf2::BufferCore& buffer, const Eigen::Isometry3d& T, double stamp,
              bool isStatic = false, const std::string& frame = "finger") {
  geometry_msgs::TransformStamped t = tf2::eigenToTransform(T);
  t.header.frame_id = "world";
  t.child_frame_id = frame;
  t.header.stamp = ros::Time(stamp);
  buffer.setTransform(t, "test", isStatic);
}

TEST(ColliderFollower, VelocityFromTheLastTwoTransformsOfTheOffsetPose) {
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  const Eigen::Isometry3d offset(Eigen::Translation3d(0.0, 0.1, 0.0));
  follower.follow("s", "finger", offset);
  Posted posted;
  ColliderFollower::Report report;
  std::vector<std::string>& problems = report.problems;

  // Not seen yet: nothing posted, the collider waits for its frame, named once; no miss.
  follower.sample(ros::Time(100.0), posted.post(), report);
  follower.sample(ros::Time(100.005), posted.post(), report);
  EXPECT_TRUE(posted.motions.empty());
  EXPECT_TRUE(problems.empty());
  ASSERT_EQ(report.waiting.size(), 1u) << "one line per waiting collider, not one per sample";
  EXPECT_EQ(report.waiting[0].first, "s");
  EXPECT_EQ(report.waiting[0].second, "finger");
  EXPECT_EQ(follower.misses(), 0u);
  EXPECT_EQ(follower.waiting(), 1u);

  // First transform: its pose (frame * offset), at rest.
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(1.0, 0.0, 0.0)), 100.0);
  report.clear();
  follower.sample(ros::Time(100.01), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 1u);
  EXPECT_TRUE(problems.empty());
  EXPECT_EQ(follower.waiting(), 0u);
  EXPECT_TRUE(posted.motions[0].second.pose.translation().isApprox(Eigen::Vector3d(1.0, 0.1, 0.0)));
  EXPECT_TRUE(posted.motions[0].second.linearVelocity.isZero(0.0));

  // 0.1 s later the frame moved 1 cm along x and turned 0.1 rad about z: the collider origin,
  // 0.1 m from the frame's, moved by (0.01, 0, 0) + (Rz(0.1) - I) (0, 0.1, 0).
  const Eigen::Isometry3d T1 =
      Eigen::Translation3d(1.01, 0.0, 0.0) * Eigen::AngleAxisd(0.1, Eigen::Vector3d::UnitZ());
  setFrame(buffer, T1, 100.1);
  follower.sample(ros::Time(100.11), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 2u);
  const ColliderMotion& m = posted.motions[1].second;
  const Eigen::Vector3d p1 = (T1 * offset).translation();
  EXPECT_TRUE(m.pose.translation().isApprox(p1, 1e-12));
  EXPECT_TRUE(m.linearVelocity.isApprox((p1 - Eigen::Vector3d(1.0, 0.1, 0.0)) / 0.1, 1e-6));
  EXPECT_TRUE(m.angularVelocity.isApprox(Eigen::Vector3d(0.0, 0.0, 1.0), 1e-6));

  // No new transform: nothing posted (the simulation moves on along the velocity).
  follower.sample(ros::Time(100.15), posted.post(), report);
  EXPECT_EQ(posted.motions.size(), 2u);

  // Stale: held still at the last pose, once; every sample counted.
  const std::uint64_t misses = follower.misses();
  follower.sample(ros::Time(100.1 + ColliderFollower::kStaleAfter + 0.1), posted.post(), report);
  follower.sample(ros::Time(100.1 + ColliderFollower::kStaleAfter + 0.2), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 3u);
  EXPECT_TRUE(posted.motions[2].second.pose.isApprox(m.pose));
  EXPECT_TRUE(posted.motions[2].second.linearVelocity.isZero(0.0));
  EXPECT_TRUE(posted.motions[2].second.angularVelocity.isZero(0.0));
  EXPECT_EQ(follower.misses(), misses + 2);

  // Back: the first new transform restarts from rest (no velocity across the gap).
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(2.0, 0.0, 0.0)), 101.0);
  follower.sample(ros::Time(101.0), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 4u);
  EXPECT_TRUE(posted.motions[3].second.linearVelocity.isZero(0.0));

  follower.forget("s");
  EXPECT_TRUE(follower.empty());
}

TEST(ColliderFollower, AFrameThatJumpsIsPlacedAtRestNotSweptThroughTheScene) {
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  follower.follow("s", "finger", Eigen::Isometry3d::Identity());
  Posted posted;
  ColliderFollower::Report report;
  const auto at = [](double x) { return Eigen::Isometry3d(Eigen::Translation3d(x, 0.0, 0.0)); };
  setFrame(buffer, at(0.0), 10.0);
  follower.sample(ros::Time(10.0), posted.post(), report);
  // 5 mm in 10 ms: a hand moving at 0.5 m/s
  setFrame(buffer, at(0.005), 10.01);
  follower.sample(ros::Time(10.01), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 2u);
  EXPECT_NEAR(posted.motions[1].second.linearVelocity.x(), 0.5, 1e-9);
  EXPECT_TRUE(report.jumped.empty());
  // 0.5 m in 10 ms (50 m/s): a relocalisation, not a motion; at the new pose, at rest
  setFrame(buffer, at(0.505), 10.02);
  follower.sample(ros::Time(10.02), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 3u);
  EXPECT_TRUE(posted.motions[2].second.pose.translation().isApprox(Eigen::Vector3d(0.505, 0, 0)));
  EXPECT_TRUE(posted.motions[2].second.linearVelocity.isZero(0.0));
  EXPECT_TRUE(posted.motions[2].second.angularVelocity.isZero(0.0));
  ASSERT_EQ(report.jumped.size(), 1u);
  EXPECT_EQ(report.jumped[0], "s");
  // and it moves on from there at its own speed again
  report.clear();
  setFrame(buffer, at(0.515), 10.03);
  follower.sample(ros::Time(10.03), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 4u);
  EXPECT_NEAR(posted.motions[3].second.linearVelocity.x(), 1.0, 1e-9);
  EXPECT_TRUE(report.jumped.empty());
}

TEST(ColliderFollower, AFrameThatStandsStillThenLeapsIsPlacedAtTheNewPoseNotCarriedPastIt) {
  // A robot's hand stands still (its tf comes at 30 Hz), then its first joint state after a pause
  // puts it 0.22 m lower in one sample (6.6 m/s: below kJumpSpeed). Moving on along that velocity
  // until the next sample would carry the collider 0.22 m past the pose tf says; it is placed
  // there at rest instead. A hand that speeds up as arms do is followed with its velocity.
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  follower.follow("hand", "finger", Eigen::Isometry3d::Identity());
  Posted posted;
  ColliderFollower::Report report;
  const auto at = [](double z) { return Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, z)); };
  const double period = 1.0 / 30.0;
  double t = 20.0;
  for (int k = 0; k < 3; ++k, t += period) {
    setFrame(buffer, at(0.083), t);
    follower.sample(ros::Time(t), posted.post(), report);
  }
  setFrame(buffer, at(0.083 - 0.22), t);
  follower.sample(ros::Time(t), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 4u);
  EXPECT_TRUE(posted.motions.back().second.pose.translation().isApprox(Eigen::Vector3d(0, 0, 0.083 - 0.22)));
  EXPECT_TRUE(posted.motions.back().second.linearVelocity.isZero(0.0));
  ASSERT_EQ(report.jumped.size(), 1u);
  // From rest again: an arm's hand speeding up at 5 m/s^2 is no jump.
  report.clear();
  double z = 0.083 - 0.22, v = 0.0;
  for (int k = 0; k < 10; ++k) {
    t += period;
    v += 5.0 * period;
    z += v * period;
    setFrame(buffer, at(z), t);
    follower.sample(ros::Time(t), posted.post(), report);
  }
  EXPECT_TRUE(report.jumped.empty());
  // (stamps are whole nanoseconds: the velocity is the motion over a rounded period)
  EXPECT_NEAR(posted.motions.back().second.linearVelocity.z(), v, 1e-6);
}

TEST(ColliderFollower, StaticTransformNeverGoesStale) {
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  follower.follow("s", "finger", Eigen::Isometry3d::Identity());
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 1.0)), 0.0, true);
  Posted posted;
  ColliderFollower::Report report;
  const std::vector<std::string>& problems = report.problems;
  follower.sample(ros::Time(1000.0), posted.post(), report);
  follower.sample(ros::Time(2000.0), posted.post(), report);
  EXPECT_TRUE(problems.empty());
  // Posted every time (a collider re-added on the frame gets its pose), always at rest.
  ASSERT_EQ(posted.motions.size(), 2u);
  for (const auto& m : posted.motions) {
    EXPECT_DOUBLE_EQ(m.second.pose.translation().z(), 1.0);
    EXPECT_TRUE(m.second.linearVelocity.isZero(0.0));
  }
}

TEST(ColliderFollower, AFrameThatOnlyAppearsLateIsWaitedForWithoutMisses) {
  // The frame's publisher starts 2 s after the follower (robot_state_publisher still loading):
  // every sample until then finds the frame unknown, none of them a miss.
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  follower.follow("s", "finger", Eigen::Isometry3d::Identity());
  Posted posted;
  ColliderFollower::Report report;
  for (int k = 0; k < 120; ++k) follower.sample(ros::Time(10.0 + k / 60.0), posted.post(), report);
  // A transform published long ago and never again is stale before it was ever used: waiting.
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.3)), 5.0);
  follower.sample(ros::Time(12.0), posted.post(), report);
  EXPECT_TRUE(posted.motions.empty());
  EXPECT_TRUE(report.problems.empty());
  EXPECT_EQ(report.waiting.size(), 1u);
  EXPECT_EQ(follower.misses(), 0u);
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.3)), 12.01);
  follower.sample(ros::Time(12.02), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), 1u);
  EXPECT_DOUBLE_EQ(posted.motions[0].second.pose.translation().z(), 0.3);
  EXPECT_EQ(follower.misses(), 0u);
  // From now on a lost frame is a miss.
  follower.sample(ros::Time(12.01 + ColliderFollower::kStaleAfter + 0.01), posted.post(), report);
  EXPECT_EQ(follower.misses(), 1u);
  EXPECT_EQ(report.problems.size(), 1u);
}

TEST(ColliderFollower, APauseShorterThanTheStaleTimeChangesNothing) {
  // A publisher at 100 Hz moving the frame up at 0.1 m/s pauses for 0.4 s: no miss, no hold
  // (the collider is not stopped), and the first transform after the pause carries the mean
  // velocity over it, so the collider goes on as before.
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  follower.follow("s", "finger", Eigen::Isometry3d::Identity());
  Posted posted;
  ColliderFollower::Report report;
  const double v = 0.1;
  double t = 50.0;
  for (int k = 0; k < 10; ++k, t += 0.01) {
    setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, v * (t - 50.0))), t);
    follower.sample(ros::Time(t + 0.001), posted.post(), report);
  }
  const std::size_t before = posted.motions.size();
  const double last = t - 0.01;
  // the pause: sampled every step, nothing new
  for (double now = last + 0.0167; now < last + 0.4; now += 0.0167)
    follower.sample(ros::Time(now), posted.post(), report);
  EXPECT_EQ(posted.motions.size(), before) << "nothing posted during the pause (no hold)";
  EXPECT_TRUE(report.problems.empty());
  EXPECT_EQ(follower.misses(), 0u);
  const double resumed = last + 0.4;
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, v * (resumed - 50.0))), resumed);
  follower.sample(ros::Time(resumed + 0.001), posted.post(), report);
  ASSERT_EQ(posted.motions.size(), before + 1);
  EXPECT_NEAR(posted.motions.back().second.linearVelocity.z(), v, 1e-9);
  EXPECT_EQ(follower.misses(), 0u);
}

TEST(ColliderFollower, AdmitDecidesAtTheFirstTransform) {
  // Two colliders on two frames; the admission test refuses poses below z = 0 (standing in for
  // "starts inside the object"): the one that appears there is dropped and named, never posted.
  tf2::BufferCore buffer;
  ColliderFollower follower(buffer, "world");
  const auto above = [](const Eigen::Isometry3d& pose) { return pose.translation().z() >= 0.0; };
  follower.follow("low", "a", Eigen::Isometry3d::Identity(), above);
  follower.follow("high", "b", Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.2)), above);
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, -0.1)), 1.0, false, "a");
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, -0.1)), 1.0, false, "b");
  Posted posted;
  ColliderFollower::Report report;
  follower.sample(ros::Time(1.01), posted.post(), report);
  ASSERT_EQ(report.excluded.size(), 1u);
  EXPECT_EQ(report.excluded[0], "low");
  ASSERT_EQ(posted.motions.size(), 1u);
  EXPECT_EQ(posted.motions[0].first, "high") << "the offset lifts it to z = 0.1: admitted";
  // The refused one is forgotten: later transforms below or above do not bring it back.
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, 0.5)), 1.1, false, "a");
  report.clear();
  follower.sample(ros::Time(1.11), posted.post(), report);
  for (const auto& m : posted.motions) EXPECT_NE(m.first, "low");
  EXPECT_TRUE(report.excluded.empty());
  // Admission is asked once: a later pose below z = 0 keeps the admitted one.
  setFrame(buffer, Eigen::Isometry3d(Eigen::Translation3d(0.0, 0.0, -0.5)), 1.2, false, "b");
  follower.sample(ros::Time(1.21), posted.post(), report);
  EXPECT_TRUE(report.excluded.empty());
  EXPECT_DOUBLE_EQ(posted.motions.back().second.pose.translation().z(), -0.3);
}

// --- the simulation loop's colliders ----------------------------------------------------------

Collider sphere(double radius) {
  Collider c;
  c.shape.type = ColliderType::Sphere;
  c.shape.radius = radius;
  return c;
}

SolverParams weightless() {
  SolverParams p;
  p.gravity.setZero();
  p.regionHalfWidth = 1;
  return p;
}

struct Rig {
  explicit Rig(const SolverParams& p = weightless()) {
    lattice = std::make_shared<const Lattice>(test::makeBox(4, 4, 4, 0.01), 1000.0, 1);
    stats = std::make_shared<CommandStats>();
    LoopSettings settings;
    settings.idleHold = 0.2;
    auto world = std::make_unique<World>(p.timeStep, p.substeps);
    world->addObject("box", lattice, p);
    loop = std::make_unique<SimulationLoop>(std::move(world), settings, stats);
  }
  CommandOutcome run(CommandBody body) { return test::runCommand(*loop, std::move(body)); }
  bool waitFor(const std::function<bool(const Snapshot&)>& done, double timeout = 5.0) {
    return test::waitForSnapshot(*loop, done, timeout);
  }
  std::uint64_t rejected(const std::string& reason) const { return test::rejectedCount(*stats, reason); }
  std::shared_ptr<const Lattice> lattice;
  std::shared_ptr<CommandStats> stats;
  std::unique_ptr<SimulationLoop> loop;
};

TEST(SimulationLoopColliders, FollowedColliderJoinsAtItsFirstPoseAndMovesAlongItsVelocity) {
  Rig rig;
  rig.loop->addFollowedCollider("finger", sphere(0.01));
  rig.loop->start();
  // Not in the solver before its frame is known.
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.steps > 2; }));
  EXPECT_EQ(rig.loop->acquire().colliders.count("finger"), 0u);

  ColliderMotion m;
  m.pose.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);  // far from the 4 cm box
  m.linearVelocity = Eigen::Vector3d(0.1, 0.0, 0.0);
  rig.loop->setColliderMotion("finger", m);
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.colliders.count("finger") > 0; }));
  // It moves along the velocity for at most kMaxExtrapolation without news, then holds still.
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.idle; }, 10.0));
  const double x = rig.loop->acquire().colliders.at("finger").pose.translation().x();
  EXPECT_GT(x, 1.0);
  EXPECT_LE(x, 1.0 + 0.1 * (SimulationLoop::kMaxExtrapolation + 0.02) + 1e-12);

  // A followed collider refuses MOVE; ADD without a frame makes it a fixed one that moves.
  MoveColliderCommand move;
  move.id = "finger";
  EXPECT_FALSE(rig.run(move).accepted);
  EXPECT_EQ(rig.rejected("collider_follows_frame"), 1u);
  SetColliderCommand fixed{"finger", sphere(0.01), ""};
  fixed.collider.pose.translation() = Eigen::Vector3d(2.0, 0.0, 0.0);
  EXPECT_TRUE(rig.run(fixed).accepted);
  move.pose.translation() = Eigen::Vector3d(3.0, 0.0, 0.0);
  EXPECT_TRUE(rig.run(move).accepted);
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) {
    return s.colliders.count("finger") > 0 &&
           s.colliders.at("finger").pose.translation().x() == 3.0;
  }));
  // A motion posted for it now is not applied: it follows no frame any more.
  m.pose.translation() = Eigen::Vector3d(-5.0, 0.0, 0.0);
  rig.loop->setColliderMotion("finger", m);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(rig.loop->acquire().colliders.at("finger").pose.translation().x(), 3.0);

  EXPECT_TRUE(rig.run(RemoveColliderCommand{"finger"}).accepted);
  EXPECT_FALSE(rig.run(RemoveColliderCommand{"finger"}).accepted);
  EXPECT_EQ(rig.rejected("unknown_collider"), 1u);
  EXPECT_TRUE(rig.waitFor([](const Snapshot& s) { return s.colliders.empty(); }));
}

TEST(SimulationLoopColliders, CollidersAreLimitedAndInvalidOnesRefused) {
  Rig rig;
  rig.loop->start();
  for (std::size_t i = 0; i < ColliderLimits::kMaxColliders; ++i) {
    SetColliderCommand add{"c" + std::to_string(i), sphere(0.01), ""};
    add.collider.pose.translation() = Eigen::Vector3d(1.0 + i, 0.0, 0.0);
    ASSERT_TRUE(rig.run(add).accepted);
  }
  SetColliderCommand extra{"extra", sphere(0.01), ""};
  EXPECT_FALSE(rig.run(extra).accepted);
  EXPECT_EQ(rig.rejected("too_many_colliders"), 1u);
  // Replacing one is not adding one.
  SetColliderCommand replace{"c0", sphere(0.02), ""};
  replace.collider.pose.translation() = Eigen::Vector3d(1.0, 0.0, 0.0);
  EXPECT_TRUE(rig.run(replace).accepted);
  EXPECT_TRUE(rig.run(RemoveColliderCommand{"c1"}).accepted);
  SetColliderCommand bad{"bad", sphere(-1.0), ""};
  EXPECT_FALSE(rig.run(bad).accepted);
  EXPECT_EQ(rig.rejected("bad_collider"), 1u);
}

TEST(SimulationLoopColliders, SnapshotCarriesTheContactWrench) {
  // The box resting on a plane under gravity: once at rest the plane carries its weight.
  SolverParams p = weightless();
  p.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  // Air drag takes a fraction ambientDamping h of each sub-step's gravity kick before contact
  // sees it (0.4 % here), within the tolerance.
  p.ambientDamping = 1.0;
  Rig rig(p);
  Collider plane;  // touching the particles' contact spheres (radius half the spacing)
  plane.pose.translation() = rig.lattice->restMin() - Eigen::Vector3d(0.0, 0.0, 0.005);
  rig.loop->start();
  ASSERT_TRUE(rig.run(SetColliderCommand{"plane", plane, ""}).accepted);
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.idle; }, 20.0));
  const Snapshot& s = rig.loop->acquire();
  const ContactWrench& w = s.wrenches.at("plane");
  const double weight = 9.81 * rig.lattice->totalMass();
  EXPECT_EQ(w.contacts, 16u);  // the bottom layer of 4 x 4 particles
  EXPECT_NEAR(-w.force.z() / weight, 1.0, 0.02);
  EXPECT_NEAR(w.force.head<2>().norm(), 0.0, 1e-3 * weight);
}

}  // namespace
}  // namespace deformable_flsm
