/// @file test_thread_governor.cpp
/// Tests of core/thread_governor.h with made-up step times: it settles on the faster mode,
/// probes the slower one less and less often, and follows a change of the machine.
#include "deformable_flsm/core/thread_governor.h"

#include <gtest/gtest.h>

#include <vector>

namespace deformable_flsm {
namespace {

/// Runs `steps` steps whose time depends on the mode; returns the steps run threaded.
std::size_t run(ThreadGovernor& g, int steps, double threadedSeconds, double singleSeconds) {
  std::size_t threaded = 0;
  for (int s = 0; s < steps; ++s) {
    const bool t = g.threaded();
    threaded += t ? 1 : 0;
    g.record(t ? threadedSeconds : singleSeconds);
  }
  return threaded;
}

TEST(ThreadGovernor, KeepsThreadsWhenTheyAreFaster) {
  ThreadGovernor g;
  const std::size_t threaded = run(g, 2000, 1.0, 1.7);  // a quiet machine: 1.7x
  // It opens with three steps of each mode, then probes one thread 8, 16, ... 256 steps apart.
  const double cost = (threaded * 1.0 + (2000 - threaded) * 1.7) / 2000.0;
  EXPECT_LT(cost, 1.02) << threaded << " threaded steps";
  EXPECT_TRUE(g.threaded());
}

TEST(ThreadGovernor, ChoosesAfterThreeStepsOfEachMode) {
  // Quiet machine: the threads from the seventh step on.
  ThreadGovernor quiet;
  std::vector<bool> modes;
  for (int s = 0; s < 6; ++s) {
    modes.push_back(quiet.threaded());
    quiet.record(modes.back() ? 1.0 : 1.7);
  }
  EXPECT_EQ(modes, (std::vector<bool>{false, true, false, true, false, true}));
  EXPECT_TRUE(quiet.threaded());
  // Busy machine: back to one thread after the same opening.
  ThreadGovernor busy;
  run(busy, 6, 4.0, 1.0);
  EXPECT_FALSE(busy.threaded());
  EXPECT_EQ(busy.threadedSteps(), 3u);
  // Threads not clearly faster (less than kToThreadsMargin): one thread.
  ThreadGovernor even;
  run(even, 6, 0.9, 1.0);
  EXPECT_FALSE(even.threaded());
}

TEST(ThreadGovernor, FallsBackToOneThreadWhenThreadsAreSlower) {
  ThreadGovernor g;
  // Another process on one of two cores: two threads take 4 times as long as one.
  const std::size_t threaded = run(g, 2000, 4.0, 1.0);
  EXPECT_FALSE(g.threaded());
  // The opening's three threaded steps and the probes of the threads cost, ever rarer.
  const double cost = (threaded * 4.0 + (2000 - threaded) * 1.0) / 2000.0;
  EXPECT_LT(cost, 1.1) << threaded << " threaded steps";
}

TEST(ThreadGovernor, ALuckyThreadedStepDoesNotBringTheThreadsBack) {
  // Busy machine: the threads mostly take 4x, but one step in five gets both cores and takes
  // half. The medians decide, not single steps.
  ThreadGovernor g;
  std::size_t threaded = 0;
  double total = 0.0;
  for (int s = 0; s < 4000; ++s) {
    const bool t = g.threaded();
    const double seconds = t ? (s % 5 == 0 ? 0.5 : 4.0) : 1.0;
    threaded += t ? 1 : 0;
    total += seconds;
    g.record(seconds);
  }
  EXPECT_LT(total / 4000.0, 1.1) << threaded << " threaded steps";
}

TEST(ThreadGovernor, FollowsAChangeOfTheMachine) {
  ThreadGovernor g;
  run(g, 3000, 1.0, 1.7);  // quiet: threads, probes now 256 steps apart
  ASSERT_TRUE(g.threaded());
  // A job starts on the other core: the threaded steps slow down 4x. The governor must not
  // wait for its next scheduled probe.
  int steps = 0;
  while (g.threaded() && steps < 100) {
    g.record(g.threaded() ? 4.0 : 1.7);
    ++steps;
  }
  EXPECT_FALSE(g.threaded());
  EXPECT_LT(steps, 20);
  // The job ends: the threads win again at a later probe.
  run(g, 1000, 1.0, 1.7);
  EXPECT_TRUE(g.threaded());
}

TEST(ThreadGovernor, CountsTheSteps) {
  ThreadGovernor g;
  run(g, 100, 1.0, 2.0);
  EXPECT_EQ(g.threadedSteps() + g.singleSteps(), 100u);
  EXPECT_GT(g.singleSteps(), 0u);  // it probed
}

}  // namespace
}  // namespace deformable_flsm
