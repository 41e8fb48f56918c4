/// @file test_simulation_loop_pace.cpp
/// Tests of runtime/simulation_loop.h's pace and rest on small box lattices: the loop rests when
/// nothing moves (only at equilibrium) and wakes on a command, paces itself to its clock, steps a
/// command at once, and drops debt it cannot pay instead of spiralling.
#include "deformable_flsm/runtime/simulation_loop.h"

#include "../core/fixtures.h"
#include "loop_harness.h"
#include "loop_rig.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <memory>
#include <string>
#include <thread>

namespace deformable_flsm {
namespace {

using std::chrono::duration;
using Clock = std::chrono::steady_clock;

using test::makeBox;
using loop_rig::quickIdle;
using loop_rig::Rig;
using loop_rig::weightless;

TEST(SimulationLoop, RestsWhenStillAndWakesOnACommand) {
  Rig rig(quickIdle());
  rig.holdByFarCorner();
  rig.loop->start();
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.idle; }, 5.0));
  const std::uint64_t steps = rig.loop->acquire().diag.steps;
  const std::uint64_t seq = rig.loop->acquire().sequence;
  std::this_thread::sleep_for(std::chrono::milliseconds(200));
  EXPECT_EQ(rig.loop->acquire().diag.steps, steps) << "stepping while idle";
  EXPECT_EQ(rig.loop->acquire().sequence, seq) << "new snapshots while idle";

  // A rejected command does not wake it...
  EXPECT_FALSE(rig.run(ReleaseCommand{"nobody"}).accepted);
  std::this_thread::sleep_for(std::chrono::milliseconds(100));
  EXPECT_EQ(rig.loop->acquire().diag.steps, steps);
  // ... an accepted one does, at once.
  ApplyForceCommand kick;
  kick.particle = 0;
  kick.force = Eigen::Vector3d(0.0, 0.0, 1e-4);
  kick.impulse = true;
  const Clock::time_point t0 = Clock::now();
  ASSERT_TRUE(rig.run(kick).accepted);
  ASSERT_TRUE(rig.waitFor([&](const Snapshot& s) { return s.diag.steps > steps && !s.diag.idle; }));
  EXPECT_LT(duration<double>(Clock::now() - t0).count(), 0.5);
  // And it rests again once the kick has died down.
  EXPECT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.idle; }, 20.0));
}

/// A soft 1 m cantilever, 20 x 2 x 2 cells of 5 cm, clamped over its first cell: E = 50 kPa
/// under a body load of 0.02 m/s^2 with air drag 1.5/s, regions w = 2. Its first bending mode
/// swings with a period of several seconds and turns slowly at each end of the swing: a
/// speed threshold sees it still there long before it has settled.
SolverParams softBar() {
  SolverParams p;
  p.youngsModulus = 5e4;
  p.gravity = Eigen::Vector3d(0.0, 0.0, -0.02);
  p.ambientDamping = 1.5;
  p.regionHalfWidth = 2;
  return p;
}

std::unique_ptr<World> clampedBar(const SolverParams& p) {
  auto lattice = std::make_shared<const Lattice>(makeBox(20, 2, 2, 0.05), 1000.0, p.regionHalfWidth);
  auto world = std::make_unique<World>(p.timeStep, p.substeps);
  Solver& solver = world->addObject("bar", lattice, p);
  solver.pinBox(Eigen::Vector3d(-1.0, -1.0, -1.0), Eigen::Vector3d(0.05, 1.0, 1.0), true);
  return world;
}

/// Mean z displacement of the particles at the free end (m; negative = down).
double tipDeflection(const std::vector<Eigen::Vector3d>& x, const Lattice& L) {
  double sum = 0.0;
  int n = 0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    if (L.restPositions()[i].x() < 0.95) continue;
    sum += x[i].z() - L.restPositions()[i].z();
    ++n;
  }
  return sum / n;
}

TEST(SimulationLoop, RestsOnlyAtEquilibrium) {
  // Reference: the bar kept awake for 60 s of simulated time (its slowest mode decays at
  // ~0.75/s: e^-45 of the start-up swing is left).
  std::unique_ptr<World> awake = clampedBar(softBar());
  for (int s = 0; s < 3600; ++s) awake->step();
  const Solver& bar = *awake->object("bar");
  const double settled = tipDeflection(bar.positions(), bar.lattice());
  ASSERT_LT(settled, -5e-3);  // a visible sag, of the order of rho g L^4 / (E t^2)

  // The node's settings (the defaults), simulated 20x faster than real time.
  LoopSettings settings;
  settings.realTimeFactor = 20.0;
  auto stats = std::make_shared<CommandStats>();
  SimulationLoop loop(clampedBar(softBar()), settings, stats);
  loop.start();
  const Clock::time_point end = Clock::now() + std::chrono::seconds(30);
  while (!loop.acquire().diag.idle && Clock::now() < end)
    std::this_thread::sleep_for(std::chrono::milliseconds(10));
  const Snapshot& s = loop.acquire();
  ASSERT_TRUE(s.diag.idle) << "not at rest after 30 s (" << s.diag.simTime << " s simulated)";
  const double atRest = tipDeflection(s.objects[0].positions, loop.lattice());
  RecordProperty("tip_deflection_kept_awake_um", static_cast<int>(std::lround(-1e6 * settled)));
  RecordProperty("tip_deflection_at_rest_um", static_cast<int>(std::lround(-1e6 * atRest)));
  RecordProperty("rest_after_simulated_ms", static_cast<int>(std::lround(1e3 * s.diag.simTime)));
  // Within 1 % of the settled deflection.
  EXPECT_NEAR(atRest, settled, 0.01 * std::abs(settled))
      << "declared at rest at " << s.diag.simTime << " s of simulated time";
}

/// `seconds` in the loop clock's ticks.
LoopClock::Duration ticks(double seconds) {
  return std::chrono::duration_cast<LoopClock::Duration>(duration<double>(seconds));
}

/// The loop's clock moved by `seconds` once the loop waits on it; returns when the loop has
/// stepped what that time asks and waits again.
void advance(ManualLoopClock& clock, double seconds) {
  ASSERT_TRUE(clock.advanceAndSettle(ticks(seconds))) << "the loop did not wait on its clock again";
}

/// A rig that never rests, stepping `timeStep` at `realTimeFactor` of `clock` (moved by hand).
Rig pacedRig(const std::shared_ptr<ManualLoopClock>& clock, double timeStep, double realTimeFactor = 1.0) {
  LoopSettings settings;
  settings.idleHold = 0.0;  // never rest: these tests are about pacing
  settings.realTimeFactor = realTimeFactor;
  SolverParams p = weightless();
  p.timeStep = timeStep;
  return Rig(settings, p, 6, clock);
}

TEST(SimulationLoop, PacedToItsClock) {
  // At half of real time, 1/50 s steps are due every 40 ms of the clock: one step per 40 ms,
  // simulated time half the clock's, whatever the machine's load.
  auto clock = std::make_shared<ManualLoopClock>();
  Rig rig = pacedRig(clock, 0.02, 0.5);
  rig.loop->start();
  for (int i = 1; i <= 40; ++i) {
    advance(*clock, 0.04);
    const LoopDiagnostics d = rig.loop->acquire().diag;
    ASSERT_EQ(d.steps, static_cast<std::uint64_t>(i)) << "after " << 0.04 * i << " s of the clock";
    EXPECT_NEAR(d.simTime, 0.02 * i, 1e-12);
  }
  const LoopDiagnostics d = rig.loop->acquire().diag;
  EXPECT_NEAR(d.achievedRealTimeFactor, 0.5, 1e-9);
  EXPECT_EQ(d.droppedSteps, 0u);
}

TEST(SimulationLoop, ACommandIsSteppedAtOnceAndThePaceKept) {
  // Steps of 0.1 s at a fifth of real time, 0.5 s of the clock apart: a command that had to wait
  // for the next step would show up to 0.5 s late. It is stepped at once, borrowing the next
  // step's time, and the pace is kept: simulated time never leads the clock's by more than a step.
  auto clock = std::make_shared<ManualLoopClock>();
  Rig rig = pacedRig(clock, 0.1, 0.2);
  rig.loop->start();
  advance(*clock, 0.5);
  ASSERT_EQ(rig.loop->acquire().diag.steps, 1u);
  advance(*clock, 0.25);  // halfway to the next step
  const Eigen::Vector3d target = rig.loop->lattice().restPositions()[0] + Eigen::Vector3d(-0.01, 0, 0);
  GrabCommand g;
  g.id = "a";
  g.particle = 0;
  g.target = target;
  std::uint64_t waits = clock->waits();
  ASSERT_TRUE(rig.run(g).accepted);
  ASSERT_TRUE(clock->awaitWaitBeyond(waits));
  // Stepped with the clock where it was: no time passed.
  const Snapshot& s = rig.loop->acquire();
  EXPECT_EQ(s.diag.steps, 2u);
  EXPECT_LT((s.objects[0].positions[0] - target).norm(), 1e-9);
  double wall = 0.75;
  EXPECT_LE(s.diag.simTime, 0.2 * wall + 0.1 + 1e-9);
  // The borrowed step is paid back: the step due at 1.0 s of the clock was taken early, so the
  // next comes at 1.5 s; moves in between are stepped at once only while that does not put
  // simulated time more than a step ahead.
  for (int i = 0; i < 6; ++i) {
    MoveCommand m;
    m.id = "a";
    m.target = target + Eigen::Vector3d(0, 0.001 * i, 0);
    waits = clock->waits();
    ASSERT_TRUE(rig.run(m).accepted);
    ASSERT_TRUE(clock->awaitWaitBeyond(waits));
    advance(*clock, 0.15);
    wall += 0.15;
    const double simTime = rig.loop->acquire().diag.simTime;
    EXPECT_LE(simTime, 0.2 * wall + 0.1 + 1e-9) << "at " << wall << " s of the clock";
    EXPECT_GE(simTime, 0.2 * wall - 0.1 - 1e-9) << "at " << wall << " s of the clock";
  }
}

TEST(SimulationLoop, ASlowMachineDropsDebtInsteadOfSpiralling) {
  // Asking for 1000 x real time: a second of the clock owes 60,000 steps. The loop takes at
  // most maxCatchUpSteps at a time, drops the rest and reports them, and goes back to its
  // commands.
  LoopSettings settings;
  settings.idleHold = 0.0;
  settings.realTimeFactor = 1000.0;
  auto clock = std::make_shared<ManualLoopClock>();
  Rig rig(settings, weightless(), 6, clock);
  rig.loop->start();
  advance(*clock, 1.0);
  LoopDiagnostics d = rig.loop->acquire().diag;
  EXPECT_EQ(d.steps, static_cast<std::uint64_t>(settings.maxCatchUpSteps));
  const double owed = 1000.0 / rig.solver->params().timeStep;  // steps owed by the second
  EXPECT_NEAR(static_cast<double>(d.droppedSteps), owed - settings.maxCatchUpSteps, 1.0);
  EXPECT_GT(d.achievedRealTimeFactor, 0.0);
  EXPECT_LT(d.achievedRealTimeFactor, 1000.0);
  const std::uint64_t waits = clock->waits();
  EXPECT_TRUE(rig.run(ResetCommand{}).accepted);
  ASSERT_TRUE(clock->awaitWaitBeyond(waits));
}

TEST(SimulationLoop, ANewPaceOwesTheTimeBeforeItAtTheOldOne) {
  // Half a step of the clock at real time, then 10 x real time: the half step is half a step
  // owed, not five steps (which would step a batch at once and drop one); the rest of the step
  // comes after 0.001 s of the clock at the new pace.
  auto clock = std::make_shared<ManualLoopClock>();
  Rig rig = pacedRig(clock, 0.02);
  rig.loop->start();
  advance(*clock, 0.01);
  ASSERT_EQ(rig.loop->acquire().diag.steps, 0u);
  const std::uint64_t waits = clock->waits();
  rig.loop->setRealTimeFactor(10.0);
  ASSERT_TRUE(clock->awaitWaitBeyond(waits));
  LoopDiagnostics d = rig.loop->acquire().diag;
  EXPECT_EQ(d.steps, 0u);
  EXPECT_EQ(d.droppedSteps, 0u);
  advance(*clock, 0.001);
  d = rig.loop->acquire().diag;
  EXPECT_EQ(d.steps, 1u);
  EXPECT_EQ(d.droppedSteps, 0u);
}

TEST(SimulationLoop, AStepSlowerThanItsShareOfTheClockStepsOnWithoutSleeping) {
  // Each step costs 1.5 steps of the clock (the frame lookup before it moves the clock on): the
  // loop is always behind, so it must step back to back, at 2/3 of real time, and drop what it
  // cannot catch up. A loop that slept a step after every batch would wait here for a clock that
  // only its own steps move.
  const double dt = 0.02, cost = 0.03;
  const int batch = LoopSettings().maxCatchUpSteps;
  auto clock = std::make_shared<ManualLoopClock>();
  std::atomic<bool> slow{false};  // before the rig: the loop's thread reads it until the rig goes
  Rig rig = pacedRig(clock, dt);
  rig.loop->setFrameSource([&](const std::string&, Eigen::Isometry3d& T) {
    if (slow.load()) clock->advance(ticks(cost));
    T = Eigen::Isometry3d::Identity();
    return true;
  });
  rig.loop->start();
  AttachCommand a;
  a.grab.id = "hand";
  a.grab.point = rig.loop->lattice().restPositions()[0];
  a.grab.count = 1;
  a.frame = "hand";
  const std::uint64_t waits = clock->waits();
  ASSERT_TRUE(rig.run(a).accepted);
  ASSERT_TRUE(clock->awaitWaitBeyond(waits));  // stepped at once (borrowing a step), waiting
  const LoopDiagnostics before = rig.loop->acquire().diag;
  const LoopClock::TimePoint t0 = clock->now();
  slow = true;
  clock->advance(ticks(2 * dt));  // the borrowed step and the next are due
  ASSERT_TRUE(rig.waitFor([&](const Snapshot& s) { return s.diag.steps >= before.steps + 100; }))
      << "the loop stopped after " << rig.loop->acquire().diag.steps - before.steps << " steps";
  rig.loop->stop();
  const LoopDiagnostics d = rig.loop->acquire().diag;
  // the clock moved by the kick and by each step since
  const double clockTime = duration<double>(clock->now() - t0).count();
  EXPECT_NEAR(clockTime, 2 * dt + cost * double(d.steps - before.steps), 1e-6);
  EXPECT_NEAR(d.achievedRealTimeFactor, dt / cost, 1e-6);
  // every step the clock owed is stepped, dropped (whole steps, each counted), or still owed:
  // the borrowed one, what the last batch of maxCatchUpSteps took, and a fraction of a step
  EXPECT_GT(d.droppedSteps, before.droppedSteps);
  const double accounted =
      (d.simTime - before.simTime) + dt * double(d.droppedSteps - before.droppedSteps);
  EXPECT_LE(accounted, clockTime + 1e-9);
  EXPECT_GE(accounted, clockTime - batch * cost - 3 * dt);
}

TEST(SimulationLoop, RealTimeFactorChangesAtRunTime) {
  LoopSettings settings;
  settings.idleHold = 0.0;
  Rig rig(settings);
  rig.loop->start();
  rig.loop->setRealTimeFactor(2.0);
  EXPECT_TRUE(rig.waitFor(
      [](const Snapshot& s) { return s.diag.requestedRealTimeFactor == 2.0; }, 2.0));
  EXPECT_THROW(rig.loop->setRealTimeFactor(0.0), std::invalid_argument);
  EXPECT_THROW(rig.loop->setRealTimeFactor(std::numeric_limits<double>::quiet_NaN()),
               std::invalid_argument);
}

}  // namespace
}  // namespace deformable_flsm
