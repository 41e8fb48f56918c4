/// @file test_problem_reporter.cpp
/// Tests of runtime/problem_reporter.h: what the node's log says about the scene and the loop,
/// each problem once when it appears (a reset, saturation), lasting ones throttled.
#include "deformable_flsm/runtime/problem_reporter.h"

#include "../core/fixtures.h"

#include <gtest/gtest.h>

#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {
namespace {

struct Logged {
  std::vector<std::pair<ProblemSeverity, std::string>> lines;
  ProblemLog sink() {
    return [this](ProblemSeverity s, const std::string& line) { lines.emplace_back(s, line); };
  }
  bool anyContains(const std::string& text) const {
    for (const auto& l : lines)
      if (l.second.find(text) != std::string::npos) return true;
    return false;
  }
};

class ProblemReporterTest : public ::testing::Test {
 protected:
  ProblemReporterTest() : lattice_(test::makeBox(3, 3, 3, 0.01), 1000.0, 1) {}
  NodeParams params_;
  SceneInfo info_;
  Lattice lattice_;
  Logged log_;
};

TEST_F(ProblemReporterTest, AnEmptyPinBoxIsNamedWithTheLatticeBounds) {
  info_.pinnedPerBox = {3, 0};
  info_.pinned = 3;
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  reporter.warnAboutScene();
  ASSERT_EQ(log_.lines.size(), 1u);
  EXPECT_EQ(log_.lines[0].first, ProblemSeverity::Warning);
  EXPECT_NE(log_.lines[0].second.find("~pinned box 1 holds no particle"), std::string::npos);
  EXPECT_NE(log_.lines[0].second.find("frame 'world'"), std::string::npos);
}

TEST_F(ProblemReporterTest, GravityWithNothingToHoldTheObjectIsWarnedAbout) {
  params_.ground = false;
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  reporter.warnAboutScene();
  EXPECT_TRUE(log_.anyContains("falls forever"));
  Logged quiet;
  params_.ground = true;
  ProblemReporter grounded(params_, info_, lattice_, quiet.sink());
  grounded.warnAboutScene();
  EXPECT_TRUE(quiet.lines.empty());
}

TEST_F(ProblemReporterTest, EachResetIsAnErrorWithItsCauseOnce) {
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  int asked = 0;
  reporter.setResetCause([&asked] {
    ++asked;
    return std::string("particle 7 deep in collider 'c'");
  });
  LoopDiagnostics d;
  d.steps = 100;
  d.requestedRealTimeFactor = d.achievedRealTimeFactor = 1.0;
  reporter.report(d);
  EXPECT_TRUE(log_.lines.empty());
  d.solverResets = 1;
  reporter.report(d);
  reporter.report(d);  // the same reset: not again
  ASSERT_EQ(log_.lines.size(), 1u);
  EXPECT_EQ(log_.lines[0].first, ProblemSeverity::Error);
  EXPECT_TRUE(log_.anyContains("reset to rest (1 times so far)"));
  EXPECT_TRUE(log_.anyContains("particle 7 deep in collider 'c'"));
  EXPECT_EQ(asked, 1);
  d.solverResets = 2;
  reporter.report(d);
  EXPECT_EQ(log_.lines.size(), 2u);
}

TEST_F(ProblemReporterTest, ALastingSlowLoopIsThrottled) {
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  LoopDiagnostics d;
  d.steps = 100;
  d.requestedRealTimeFactor = 1.0;
  d.achievedRealTimeFactor = 0.5;
  d.stepSeconds = 2.0 * params_.solver.timeStep;  // a step takes twice its wall time
  for (int i = 0; i < 50; ++i) reporter.report(d);  // 50 publish ticks, well within the period
  ASSERT_EQ(log_.lines.size(), 1u);
  EXPECT_TRUE(log_.anyContains("the steps take too long"));
  // a different kind is throttled on its own
  reporter.publishingTook(1.0);
  reporter.publishingTook(1.0);
  EXPECT_EQ(log_.lines.size(), 2u);
  EXPECT_TRUE(log_.anyContains("publishing took 1000.0 ms"));
}

TEST_F(ProblemReporterTest, SaturationIsReportedWhenItStartsNotWhileItLasts) {
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  LoopDiagnostics d;
  d.steps = 100;
  d.requestedRealTimeFactor = d.achievedRealTimeFactor = 1.0;
  d.stiffnessSaturated = true;
  d.alpha = 1.0;
  reporter.report(d);
  reporter.report(d);
  ASSERT_EQ(log_.lines.size(), 1u);
  EXPECT_TRUE(log_.anyContains("asks for more stiffness than the time step allows"));
  d.stiffnessSaturated = false;
  reporter.report(d);
  d.stiffnessSaturated = true;
  reporter.report(d);
  EXPECT_EQ(log_.lines.size(), 2u);
}

// A collider that keeps pressing on a patch under 3 cells across is warned about once, with the
// spacing that would resolve it; a touch that passes, or a patch of enough particles, is not.
TEST_F(ProblemReporterTest, ASmallContactPatchThatLastsIsWarnedAboutOnce) {
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  ContactWrench small, resolved;
  small.contacts = 3;
  small.force = Eigen::Vector3d(0, 0, 0.5);
  resolved.contacts = ProblemReporter::kResolvedContacts;
  resolved.force = Eigen::Vector3d(0, 0, 2.0);
  const double dt = 1.0 / 30.0;
  // a touch on its way in: small for half a second, then resolved, then gone
  for (int i = 0; i < 15; ++i) reporter.watchContacts({{"finger", small}, {"pad", resolved}}, i * dt);
  reporter.watchContacts({{"finger", resolved}, {"pad", resolved}}, 15 * dt);
  for (int i = 16; i < 60; ++i) reporter.watchContacts({{"finger", ContactWrench{}}, {"pad", resolved}}, i * dt);
  EXPECT_TRUE(log_.lines.empty());
  // then pressing on 3 particles for more than a second: one warning, naming the collider
  for (int i = 60; i < 200; ++i) reporter.watchContacts({{"finger", small}, {"pad", resolved}}, i * dt);
  ASSERT_EQ(log_.lines.size(), 1u);
  EXPECT_EQ(log_.lines[0].first, ProblemSeverity::Warning);
  EXPECT_TRUE(log_.anyContains("collider 'finger' has pressed on only 3 particles")) << log_.lines[0].second;
  EXPECT_TRUE(log_.anyContains("under 3 cells of 0.01 m")) << log_.lines[0].second;
  // 3 particles: about 2 sqrt(3 / pi) = 1.95 cells across; 3 cells across needs a spacing of 0.0065 m, 3.7 times the particles
  EXPECT_TRUE(log_.anyContains("~spacing 0.00651 m (about 4 times the particles)")) << log_.lines[0].second;
}

// A collider placed deep into the object is warned about once, with what to do instead.
TEST_F(ProblemReporterTest, AColliderPlacedDeepIntoTheObjectIsWarnedAboutOnce) {
  ProblemReporter reporter(params_, info_, lattice_, log_.sink());
  ContactWrench placed;
  placed.contacts = 12;
  placed.buried = 5;
  placed.force = Eigen::Vector3d(0, 0, 1.0);
  reporter.watchContacts({{"pad", placed}}, 0.0);
  reporter.watchContacts({{"pad", placed}}, 1.0 / 30.0);
  ASSERT_EQ(log_.lines.size(), 1u);
  EXPECT_TRUE(log_.anyContains("collider 'pad' found 5 particles deeper than their radius (0.005 m)"))
      << log_.lines[0].second;
  EXPECT_TRUE(log_.anyContains("Move a collider into the object over several steps")) << log_.lines[0].second;
}

}  // namespace
}  // namespace deformable_flsm
