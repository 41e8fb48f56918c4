/// @file test_simulation_loop_time.cpp
/// Tests of runtime/simulation_loop.h's time (LoopTime) and pausing: a served time ticks once per
/// step and goes on at rest, runs slower rather than jump when the machine falls behind, and at a
/// real-time factor of 0 steps as fast as it can; a followed time is never led and never goes
/// back; a paused loop steps only when asked, and stepping on request is bit-identical from run
/// to run.
#include "deformable_flsm/runtime/simulation_loop.h"

#include "../core/fixtures.h"
#include "loop_harness.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <mutex>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace deformable_flsm {
namespace {

using test::makeBox;

/// What a TickObserver saw: each tick's time and whether it came with a new state.
struct Ticks {
  std::mutex mutex;
  std::vector<std::pair<double, bool>> seen;
  SimulationLoop::TickObserver observer() {
    return [this](double time, const Snapshot* state) {
      // the state handed over is the one the tick is of
      if (state != nullptr) {
        EXPECT_EQ(state->time, time);
      }
      std::lock_guard<std::mutex> lock(mutex);
      seen.emplace_back(time, state != nullptr);
    };
  }
  std::vector<std::pair<double, bool>> copy() {
    std::lock_guard<std::mutex> lock(mutex);
    return seen;
  }
};

struct TimeRig {
  TimeRig(const LoopSettings& settings, double timeStep, std::shared_ptr<LoopClock> clock = nullptr,
          bool gravity = false) {
    SolverParams p;
    if (!gravity) p.gravity.setZero();
    p.regionHalfWidth = 1;
    p.ambientDamping = 5.0;
    p.timeStep = timeStep;
    auto lattice = std::make_shared<const Lattice>(makeBox(4, 4, 4, 0.01), 1000.0, p.regionHalfWidth);
    auto world = std::make_unique<World>(p.timeStep, p.substeps);
    Solver& solver = world->addObject("box", lattice, p);
    // held by one corner, so that a falling box swings and comes to rest
    solver.setPinned(static_cast<std::uint32_t>(lattice->size() - 1), true);
    stats = std::make_shared<CommandStats>();
    loop = std::make_unique<SimulationLoop>(std::move(world), settings, stats, std::move(clock));
    loop->setTickObserver(ticks.observer());
    loop->setNotice([this](const std::string& what) {
      std::lock_guard<std::mutex> lock(ticks.mutex);
      notices.push_back(what);
    });
  }
  CommandOutcome run(CommandBody body) { return test::runCommand(*loop, std::move(body)); }
  bool waitFor(const std::function<bool(const Snapshot&)>& done, double timeout = 5.0) {
    return test::waitForSnapshot(*loop, done, timeout);
  }

  Ticks ticks;
  std::vector<std::string> notices;  // under ticks.mutex
  std::shared_ptr<CommandStats> stats;
  std::unique_ptr<SimulationLoop> loop;
};

LoopClock::Duration ticksOf(double seconds) {
  return std::chrono::duration_cast<LoopClock::Duration>(std::chrono::duration<double>(seconds));
}

void advance(ManualLoopClock& clock, double seconds) {
  ASSERT_TRUE(clock.advanceAndSettle(ticksOf(seconds))) << "the loop did not wait on its clock again";
}

TEST(SimulationLoopTime, AServedTimeTicksOncePerStepAndGoesOnAtRest) {
  // Steps of 1/50 s at half of real time: one tick per 40 ms of the clock, each a whole step
  // later than the one before; the weightless box rests after 0.1 s of stillness, and from then
  // on the time goes on in ticks without a state while nothing steps.
  auto clock = std::make_shared<ManualLoopClock>();
  LoopSettings settings;
  settings.time = LoopTime::Served;
  settings.realTimeFactor = 0.5;
  settings.idleHold = 0.1;
  TimeRig rig(settings, 0.02, clock);
  rig.loop->start();
  for (int i = 0; i < 30; ++i) advance(*clock, 0.04);
  const std::vector<std::pair<double, bool>> seen = rig.ticks.copy();
  ASSERT_EQ(seen.size(), 30u);
  for (std::size_t k = 0; k < seen.size(); ++k)
    EXPECT_DOUBLE_EQ(seen[k].first, 0.02 * static_cast<double>(k + 1)) << "tick " << k;
  const Snapshot& s = rig.loop->acquire();
  ASSERT_TRUE(s.diag.idle) << "the still box should rest";
  EXPECT_LT(s.diag.steps, 30u) << "at rest the time goes on without steps";
  EXPECT_TRUE(seen.front().second);
  EXPECT_FALSE(seen.back().second) << "a tick at rest carries no new state";
  // the state's time is the time of its step; the loop's time is the newest tick's
  EXPECT_DOUBLE_EQ(s.time, 0.02 * static_cast<double>(s.diag.steps));
  EXPECT_DOUBLE_EQ(rig.loop->clockTime(), 0.6);
}

TEST(SimulationLoopTime, AServedTimeBehindItsPaceRunsSlowerInsteadOfJumping) {
  // Ten steps' worth of the clock at once: the loop takes its batch of four, forgives the rest
  // (counted as dropped), and its time is the four steps it took: a served time is always the
  // time of what was stepped.
  auto clock = std::make_shared<ManualLoopClock>();
  LoopSettings settings;
  settings.time = LoopTime::Served;
  settings.idleHold = 0.0;
  TimeRig rig(settings, 0.02, clock);
  rig.loop->start();
  advance(*clock, 0.2);
  const Snapshot& s = rig.loop->acquire();
  EXPECT_EQ(s.diag.steps, 4u);
  EXPECT_EQ(s.diag.droppedSteps, 6u);
  EXPECT_DOUBLE_EQ(s.time, 0.08);
  EXPECT_DOUBLE_EQ(rig.loop->clockTime(), 0.08);
}

TEST(SimulationLoopTime, AtARealTimeFactorOfZeroItStepsAsFastAsItCanAndNeverRests) {
  LoopSettings settings;
  settings.time = LoopTime::Served;
  settings.realTimeFactor = 0.0;
  settings.idleHold = 0.05;  // it would rest after 3 still steps if it rested at all
  TimeRig rig(settings, 0.02);
  rig.loop->start();
  // 500 steps (10 s of simulated time) come in far less than 10 s of the wall clock
  const auto start = std::chrono::steady_clock::now();
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.steps >= 500; }, 9.0));
  EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count(), 10.0);
  const Snapshot& s = rig.loop->acquire();
  EXPECT_FALSE(s.diag.idle);
  EXPECT_DOUBLE_EQ(s.time, 0.02 * static_cast<double>(s.diag.steps));
  EXPECT_THROW(SimulationLoop(std::make_unique<World>(0.02, 1), [] {
                 LoopSettings paced;
                 paced.realTimeFactor = 0.0;
                 return paced;
               }(), std::make_shared<CommandStats>()),
               std::invalid_argument)
      << "a real-time factor of 0 is for a served time only";
}

TEST(SimulationLoopTime, APaceSetAfterAsFastAsItCanStepsFromThen) {
  // As fast as it can for a while, then real time: the steps taken fast are no debt, and the
  // loop goes on at one step per step of the clock.
  auto clock = std::make_shared<ManualLoopClock>();
  LoopSettings settings;
  settings.time = LoopTime::Served;
  settings.realTimeFactor = 0.0;
  settings.idleHold = 0.0;
  TimeRig rig(settings, 0.02, clock);
  rig.loop->start();
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.steps >= 50; }));
  const std::uint64_t waits = clock->waits();
  rig.loop->setRealTimeFactor(1.0);
  ASSERT_TRUE(clock->awaitWaitBeyond(waits)) << "it never waits on its clock again";
  const std::uint64_t before = rig.loop->acquire().diag.steps;
  for (int i = 1; i <= 5; ++i) {
    advance(*clock, 0.02);
    EXPECT_EQ(rig.loop->acquire().diag.steps, before + i);
  }
}

TEST(SimulationLoopTime, AFollowedTimeIsNeverLedAndAJumpBackResetsTheScene) {
  LoopSettings settings;
  settings.time = LoopTime::Followed;
  settings.idleHold = 0.0;
  TimeRig rig(settings, 0.02, nullptr, /*gravity=*/true);
  rig.loop->start();
  const auto timeIs = [&](double t) {
    return rig.waitFor([t](const Snapshot& s) { return std::abs(s.time - t) < 1e-9; });
  };
  // Before the first time to follow the state has no time on that clock: nothing may be stamped
  // with it (the node publishes nothing from it).
  EXPECT_FALSE(rig.loop->acquire().timeStarted);
  Snapshot summary;
  rig.loop->copySummary(summary);
  EXPECT_FALSE(summary.timeStarted);
  // Nothing steps before the first time to follow; the loop's time starts there.
  rig.loop->followTime(100.0);
  ASSERT_TRUE(timeIs(100.0));
  EXPECT_TRUE(rig.loop->acquire().timeStarted);
  rig.loop->copySummary(summary);
  EXPECT_TRUE(summary.timeStarted);
  EXPECT_EQ(rig.loop->acquire().diag.steps, 0u);
  // Whole steps up to the followed time, never past it.
  rig.loop->followTime(100.05);
  ASSERT_TRUE(timeIs(100.04));
  rig.loop->followTime(100.059);
  rig.loop->followTime(100.061);
  ASSERT_TRUE(timeIs(100.06));
  EXPECT_EQ(rig.loop->acquire().diag.steps, 3u);
  // Far behind: a batch of four steps, and the time jumps to the followed one (the rest dropped).
  rig.loop->followTime(100.5);
  ASSERT_TRUE(timeIs(100.5));
  EXPECT_EQ(rig.loop->acquire().diag.steps, 7u);
  EXPECT_EQ(rig.loop->acquire().diag.droppedSteps, 18u);
  // Paused, it takes no steps on request: the followed clock paces them.
  ASSERT_TRUE(rig.run(PauseCommand{true}).accepted);
  EXPECT_FALSE(rig.run(StepCommand{3}).accepted);
  ASSERT_TRUE(rig.run(PauseCommand{false}).accepted);
  // Back in time (a bag played again): the scene is reset to rest and goes on from there.
  rig.loop->followTime(50.0);
  ASSERT_TRUE(timeIs(50.0));
  const Snapshot& s = rig.loop->acquire();
  EXPECT_NEAR(s.diag.simTime, 0.0, 1e-12) << "reset: the scene's time starts again";
  for (std::size_t i = 0; i < s.objects[0].positions.size(); ++i)
    ASSERT_EQ(s.objects[0].positions[i], rig.loop->lattice().restPositions()[i]) << "particle " << i;
  {
    std::lock_guard<std::mutex> lock(rig.ticks.mutex);
    ASSERT_EQ(rig.notices.size(), 1u);
    EXPECT_NE(rig.notices[0].find("went back"), std::string::npos) << rig.notices[0];
  }
  // Every tick was at or behind the time followed then, and none went back but the reset.
  const std::vector<std::pair<double, bool>> seen = rig.ticks.copy();
  int backwards = 0;
  for (std::size_t k = 1; k < seen.size(); ++k) backwards += seen[k].first < seen[k - 1].first;
  EXPECT_EQ(backwards, 1);
}

TEST(SimulationLoopTime, APausedLoopStepsOnlyWhenAskedAndGoesOnFromThereWhenUnpaused) {
  auto clock = std::make_shared<ManualLoopClock>();
  LoopSettings settings;
  settings.time = LoopTime::Served;
  settings.idleHold = 0.0;
  settings.startPaused = true;
  TimeRig rig(settings, 0.02, clock, /*gravity=*/true);
  rig.loop->start();
  // A second of the clock passes: nothing steps.
  clock->advance(ticksOf(1.0));
  std::this_thread::sleep_for(std::chrono::milliseconds(50));
  EXPECT_EQ(rig.loop->acquire().diag.steps, 0u);
  EXPECT_TRUE(rig.loop->acquire().diag.paused);
  // Asked for: stepped, answered once done.
  const CommandOutcome stepped = rig.run(StepCommand{5});
  ASSERT_TRUE(stepped.accepted) << stepped.message;
  EXPECT_EQ(rig.loop->acquire().diag.steps, 5u);
  EXPECT_DOUBLE_EQ(rig.loop->clockTime(), 0.1);
  EXPECT_EQ(rig.ticks.copy().size(), 5u) << "each step asked for is a tick";
  EXPECT_FALSE(rig.run(StepCommand{0}).accepted);
  EXPECT_FALSE(rig.run(StepCommand{CommandLimits::kMaxSteps + 1}).accepted);
  // Unpaused: it goes on at its pace from where it was; the paused second is not owed.
  ASSERT_TRUE(rig.run(PauseCommand{false}).accepted);
  EXPECT_FALSE(rig.run(StepCommand{1}).accepted) << "a step while running is refused";
  EXPECT_EQ(test::rejectedCount(*rig.stats, "not_paused"), 1u);
  advance(*clock, 0.02);
  advance(*clock, 0.02);
  EXPECT_EQ(rig.loop->acquire().diag.steps, 7u);
  EXPECT_EQ(rig.loop->acquire().diag.droppedSteps, 0u);
  EXPECT_DOUBLE_EQ(rig.loop->clockTime(), 0.14);
}

TEST(SimulationLoopTime, UnpausingAnswersTheStepsAskedFor) {
  // Many steps asked for, and an unpause right behind them: the steps' answer comes, whether
  // they were all taken or the unpause cut them short.
  LoopSettings settings;
  settings.time = LoopTime::Served;
  settings.startPaused = true;
  settings.idleHold = 0.0;
  TimeRig rig(settings, 0.02);
  rig.loop->start();
  Command step{StepCommand{CommandLimits::kMaxSteps}, std::make_shared<std::promise<CommandOutcome>>(), ""};
  auto answer = step.outcome->get_future();
  rig.loop->submit(std::move(step));
  std::this_thread::sleep_for(std::chrono::milliseconds(20));  // some steps taken
  ASSERT_TRUE(rig.run(PauseCommand{false}).accepted);
  ASSERT_EQ(answer.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  const CommandOutcome o = answer.get();
  EXPECT_TRUE(o.accepted);
  EXPECT_NE(o.message.find("not taken"), std::string::npos) << o.message;
}

TEST(SimulationLoopTime, SteppingOnRequestIsBitIdenticalFromRunToRun) {
  // Lockstep: a client that steps a paused scene gets the same state every time, to the bit.
  const auto run = [] {
    LoopSettings settings;
    settings.time = LoopTime::Served;
    settings.startPaused = true;
    TimeRig rig(settings, 1.0 / 30.0, nullptr, /*gravity=*/true);
    rig.loop->start();
    GrabCommand g;
    g.id = "pull";
    g.particle = 0;
    g.target = rig.loop->lattice().restPositions()[0] + Eigen::Vector3d(0.005, 0.0, 0.0);
    const CommandOutcome grabbed = rig.run(g);
    EXPECT_TRUE(grabbed.accepted) << grabbed.message;
    for (int i = 0; i < 10; ++i) EXPECT_TRUE(rig.run(StepCommand{7}).accepted);
    // displacements from rest: the same to the bit when the positions are
    std::vector<Eigen::Vector3d> u = rig.loop->acquire().objects[0].positions;
    for (std::size_t i = 0; i < u.size(); ++i) u[i] -= rig.loop->lattice().restPositions()[i];
    return u;
  };
  const std::vector<Eigen::Vector3d> a = run(), b = run();
  ASSERT_EQ(a.size(), b.size());
  double moved = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) {
    ASSERT_EQ(a[i], b[i]) << "particle " << i;
    moved = std::max(moved, a[i].norm());
  }
  EXPECT_GT(moved, 1e-3) << "the scene stepped (m)";
}


TEST(SimulationLoopTime, AStageThatHoldsTheThreadForSecondsIsSaid) {
  // a step that takes 1.2 s of wall time (here its tick's observer sleeps) holds every state up:
  // the loop says so, naming the stage, so that a node's log tells what held its states
  std::atomic<int> ticks{0};  // outlives the loop's thread
  LoopSettings settings;
  settings.realTimeFactor = 1.0;
  TimeRig rig(settings, 0.02);
  rig.loop->setTickObserver([&ticks](double, const Snapshot*) {
    if (++ticks == 3) std::this_thread::sleep_for(std::chrono::milliseconds(1200));
  });
  rig.loop->start();
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  std::string said;
  while (said.empty() && std::chrono::steady_clock::now() < until) {
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
    std::lock_guard<std::mutex> lock(rig.ticks.mutex);
    for (const std::string& n : rig.notices)
      if (n.find("stepping the scene") != std::string::npos) said = n;
  }
  ASSERT_FALSE(said.empty()) << "a 1.2 s step was not said";
  EXPECT_NE(said.find("the simulation thread spent 1."), std::string::npos) << said;
  std::lock_guard<std::mutex> lock(rig.ticks.mutex);
  EXPECT_EQ(rig.notices.size(), 1u) << "only the slow stage is said";
}

}  // namespace
}  // namespace deformable_flsm
