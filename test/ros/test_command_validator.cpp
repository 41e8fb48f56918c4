/// @file test_command_validator.cpp
/// Tests of ros/command_validator.h: every bad field is refused with its reason, good commands
/// come out in the simulation frame. Frames come from a table instead of tf (no master).
#include "deformable_flsm/ros/command_validator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>

namespace deformable_flsm {
namespace {

constexpr std::size_t kParticles = 100;
constexpr double kSize = 0.3;  // L (m)
const double kNaN = std::numeric_limits<double>::quiet_NaN();
const double kInf = std::numeric_limits<double>::infinity();

/// "offset" is the simulation frame shifted by +1 m in x; "turned" is rotated 90 deg about z.
class Validator : public ::testing::Test {
 protected:
  Validator()
      : validator_(kParticles, kSize, "world",
                   [this](const std::string& frame, const ros::Time&, Eigen::Isometry3d& T,
                          std::string& why) {
                     const auto it = frames_.find(frame);
                     if (it == frames_.end()) {
                       why = "frame '" + frame + "' does not exist";
                       return false;
                     }
                     T = it->second;
                     return true;
                   },
                   [] { return Eigen::Vector3d(0.0, 0.0, 0.0); }) {
    frames_["offset"] = Eigen::Isometry3d(Eigen::Translation3d(1.0, 0.0, 0.0));
    frames_["turned"] =
        Eigen::Isometry3d(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  }

  static DragCommand grab() {
    DragCommand m;
    m.action = DragCommand::GRAB;
    m.id = "hand";
    m.particle = 5;
    m.target.z = 0.1;
    return m;
  }
  static ForceCommand push() {
    ForceCommand m;
    m.kind = ForceCommand::FORCE;
    m.particle = -1;
    m.point.x = 0.05;
    m.radius = 0.02;
    m.force.x = 1.0;
    m.duration = 0.5;
    return m;
  }
  /// The reason a drag is refused, or "" when it is accepted.
  std::string dragReason(const DragCommand& m) {
    CommandBody out;
    Rejection why;
    if (validator_.drag(m, out, why)) return "";
    EXPECT_FALSE(why.detail.empty()) << why.reason;
    return why.reason;
  }
  std::string forceReason(const ForceCommand& m) {
    CommandBody out;
    Rejection why;
    if (validator_.force(m, out, why)) return "";
    EXPECT_FALSE(why.detail.empty()) << why.reason;
    return why.reason;
  }

  std::map<std::string, Eigen::Isometry3d> frames_;
  CommandValidator validator_;
};

TEST_F(Validator, GoodGrabByIndex) {
  CommandBody out;
  Rejection why;
  ASSERT_TRUE(validator_.drag(grab(), out, why)) << why.detail;
  const GrabCommand& g = std::get<GrabCommand>(out);
  EXPECT_EQ(g.id, "hand");
  EXPECT_EQ(g.particle, 5);
  EXPECT_EQ(g.target, Eigen::Vector3d(0.0, 0.0, 0.1));
  EXPECT_EQ(g.stiffness, 0.0);
}

TEST_F(Validator, GrabByPointDefaultsToOneParticleAndTransformsFrames) {
  DragCommand m = grab();
  m.header.frame_id = "offset";
  m.particle = -1;
  m.point.x = -1.0;  // = (0, 0, 0) in the simulation frame
  m.target.x = -0.9;
  m.target.z = 0.0;
  m.stiffness = 50.0;
  CommandBody out;
  Rejection why;
  ASSERT_TRUE(validator_.drag(m, out, why)) << why.detail;
  const GrabCommand& g = std::get<GrabCommand>(out);
  EXPECT_EQ(g.particle, -1);
  EXPECT_EQ(g.count, 1u);  // 0 means 1
  EXPECT_LT(g.point.norm(), 1e-12);
  EXPECT_TRUE(g.target.isApprox(Eigen::Vector3d(0.1, 0.0, 0.0), 1e-12));
  EXPECT_EQ(g.stiffness, 50.0);
}

// Letting go is always safe: a release is accepted whatever its other fields hold, so that a
// sender with a broken field can still free what it grabbed.
TEST_F(Validator, MoveAndRelease) {
  DragCommand m = grab();
  m.action = DragCommand::MOVE;
  CommandBody out;
  Rejection why;
  ASSERT_TRUE(validator_.drag(m, out, why));
  EXPECT_EQ(std::get<MoveCommand>(out).target, Eigen::Vector3d(0.0, 0.0, 0.1));
  m.action = DragCommand::RELEASE;
  m.target.x = kNaN;
  m.particle = -7;
  ASSERT_TRUE(validator_.drag(m, out, why));
  EXPECT_EQ(std::get<ReleaseCommand>(out).id, "hand");
}

// ATTACH grabs like GRAB, with the point in the frame attached to, and carries that frame's pose
// now (simulation frame <- frame) and its name; it needs no target, so a target out of reach
// does not matter.
TEST_F(Validator, AttachCarriesTheFrameAndItsPose) {
  DragCommand m = grab();
  m.action = DragCommand::ATTACH;
  m.header.frame_id = "turned";
  m.particle = -1;
  m.point.x = 0.1;  // (0, 0.1, 0) in the simulation frame
  m.count = 4;
  m.target.x = 1e3;
  CommandBody out;
  Rejection why;
  ASSERT_TRUE(validator_.drag(m, out, why)) << why.detail;
  const AttachCommand& a = std::get<AttachCommand>(out);
  EXPECT_EQ(a.frame, "turned");
  EXPECT_EQ(a.grab.id, "hand");
  EXPECT_EQ(a.grab.count, 4u);
  EXPECT_TRUE(a.grab.point.isApprox(Eigen::Vector3d(0.0, 0.1, 0.0), 1e-12));
  EXPECT_TRUE(a.pose.linear().isApprox(frames_["turned"].linear(), 1e-12));
  EXPECT_LT(a.pose.translation().norm(), 1e-12);
  // The simulation frame (empty or by name) does not move: nothing to follow.
  for (const char* sim : {"", "world"}) {
    m.header.frame_id = sim;
    ASSERT_TRUE(validator_.drag(m, out, why)) << why.detail;
    EXPECT_TRUE(std::get<AttachCommand>(out).frame.empty());
  }
  // A frame tf does not know is refused like any other command's.
  m.header.frame_id = "nowhere";
  EXPECT_EQ(dragReason(m), "unknown_frame");
  m = grab();
  m.action = DragCommand::ATTACH;
  m.stiffness = -1.0;
  EXPECT_EQ(dragReason(m), "bad_stiffness");
  m.stiffness = 0.0;
  m.particle = -1;
  m.point.x = 10.0;
  EXPECT_EQ(dragReason(m), "out_of_reach");
  m.point.x = kNaN;
  EXPECT_EQ(dragReason(m), "non_finite");
}

TEST_F(Validator, EveryBadDragFieldIsRefusedWithItsReason) {
  DragCommand m;
  m = grab(); m.action = 7;                   EXPECT_EQ(dragReason(m), "bad_action");
  m = grab(); m.action = 4;                   EXPECT_EQ(dragReason(m), "bad_action");
  m = grab(); m.id = "";                      EXPECT_EQ(dragReason(m), "bad_id");
  m = grab(); m.id = std::string(65, 'a');    EXPECT_EQ(dragReason(m), "bad_id");
  m = grab(); m.id = "tab\there";             EXPECT_EQ(dragReason(m), "bad_id");
  m = grab(); m.particle = kParticles;        EXPECT_EQ(dragReason(m), "bad_index");
  m = grab(); m.particle = -2;                EXPECT_EQ(dragReason(m), "bad_index");
  m = grab(); m.target.x = kNaN;              EXPECT_EQ(dragReason(m), "non_finite");
  m = grab(); m.target.y = kInf;              EXPECT_EQ(dragReason(m), "non_finite");
  m = grab(); m.point.z = -kInf;              EXPECT_EQ(dragReason(m), "non_finite");
  m = grab(); m.stiffness = kNaN;             EXPECT_EQ(dragReason(m), "non_finite");
  m = grab(); m.stiffness = -1.0;             EXPECT_EQ(dragReason(m), "bad_stiffness");
  m = grab(); m.target.x = 1e30;              EXPECT_EQ(dragReason(m), "out_of_reach");
  m = grab(); m.target.x = 2.1 * kSize;       EXPECT_EQ(dragReason(m), "out_of_reach");
  m = grab(); m.target.x = 1.9 * kSize;       EXPECT_EQ(dragReason(m), "");
  m = grab(); m.particle = -1; m.point.y = 1e30;  EXPECT_EQ(dragReason(m), "out_of_reach");
  m = grab(); m.particle = -1; m.count = kParticles + 1;  EXPECT_EQ(dragReason(m), "bad_count");
  m = grab(); m.header.frame_id = "nowhere";  EXPECT_EQ(dragReason(m), "unknown_frame");
  m = grab(); m.action = DragCommand::MOVE; m.target.z = kNaN;  EXPECT_EQ(dragReason(m), "non_finite");
}

TEST_F(Validator, GoodForceIsRotatedNotTranslated) {
  ForceCommand m = push();
  m.header.frame_id = "turned";
  CommandBody out;
  Rejection why;
  ASSERT_TRUE(validator_.force(m, out, why)) << why.detail;
  const ApplyForceCommand& p = std::get<ApplyForceCommand>(out);
  EXPECT_FALSE(p.impulse);
  EXPECT_NEAR(p.force.x(), 0.0, 1e-12);  // x turned 90 deg about z is y
  EXPECT_NEAR(p.force.y(), 1.0, 1e-12);
  EXPECT_NEAR(p.point.y(), 0.05, 1e-12);
  EXPECT_EQ(p.duration, 0.5);
  EXPECT_EQ(p.radius, 0.02);
}

TEST_F(Validator, ImpulseIgnoresDuration) {
  ForceCommand m = push();
  m.kind = ForceCommand::IMPULSE;
  m.duration = 0.0;
  CommandBody out;
  Rejection why;
  ASSERT_TRUE(validator_.force(m, out, why)) << why.detail;
  EXPECT_TRUE(std::get<ApplyForceCommand>(out).impulse);
}

TEST_F(Validator, EveryBadForceFieldIsRefusedWithItsReason) {
  ForceCommand m;
  m = push(); m.kind = 2;                     EXPECT_EQ(forceReason(m), "bad_action");
  m = push(); m.particle = kParticles;        EXPECT_EQ(forceReason(m), "bad_index");
  m = push(); m.force.z = kNaN;               EXPECT_EQ(forceReason(m), "non_finite");
  m = push(); m.radius = kInf;                EXPECT_EQ(forceReason(m), "non_finite");
  m = push(); m.duration = kNaN;              EXPECT_EQ(forceReason(m), "non_finite");
  m = push(); m.point.x = kNaN;               EXPECT_EQ(forceReason(m), "non_finite");
  m = push(); m.duration = 0.0;               EXPECT_EQ(forceReason(m), "bad_duration");
  m = push(); m.duration = -1.0;              EXPECT_EQ(forceReason(m), "bad_duration");
  m = push(); m.duration = 61.0;              EXPECT_EQ(forceReason(m), "bad_duration");
  m = push(); m.radius = -0.01;               EXPECT_EQ(forceReason(m), "bad_radius");
  m = push(); m.radius = 1.1 * kSize;         EXPECT_EQ(forceReason(m), "bad_radius");
  m = push(); m.point.x = 1e30;               EXPECT_EQ(forceReason(m), "out_of_reach");
  m = push(); m.header.frame_id = "nowhere";  EXPECT_EQ(forceReason(m), "unknown_frame");
  // The magnitude is limited per selected mass, which only the simulation knows: not here.
  m = push(); m.force.x = 1e30;               EXPECT_EQ(forceReason(m), "");
}

TEST_F(Validator, PinBox) {
  Rejection why;
  EXPECT_TRUE(validator_.box(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 1), why));
  EXPECT_FALSE(validator_.box(Eigen::Vector3d(1, -1, -1), Eigen::Vector3d(0, 1, 1), why));
  EXPECT_EQ(why.reason, "bad_box");
  EXPECT_FALSE(validator_.box(Eigen::Vector3d(kNaN, -1, -1), Eigen::Vector3d(0, 1, 1), why));
  EXPECT_EQ(why.reason, "non_finite");
}

TEST(CommandStats, CountsByReasonAndCallsTheHook) {
  CommandStats stats;
  int calls = 0;
  stats.setRejectHook([&](const std::string& reason, const std::string&) {
    ++calls;
    EXPECT_FALSE(reason.empty());
  });
  stats.accept();
  stats.reject("non_finite", "a");
  stats.reject("non_finite", "b");
  stats.reject("bad_index", "c");
  const CommandStats::Counts c = stats.counts();
  EXPECT_EQ(c.accepted, 1u);
  EXPECT_EQ(c.rejected, 3u);
  EXPECT_EQ(c.rejectedByReason.at("non_finite"), 2u);
  EXPECT_EQ(c.rejectedByReason.at("bad_index"), 1u);
  EXPECT_EQ(c.lastRejection, "c");
  EXPECT_EQ(calls, 3);
}

}  // namespace
}  // namespace deformable_flsm
