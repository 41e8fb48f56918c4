/// @file test_simulation_loop.cpp
/// Tests of runtime/simulation_loop.h's commands on small box lattices: commands reach the
/// solver (or are rejected with a reason), an attached drag follows its frame, a full queue
/// answers, and the loop never hands out a non-finite state.
#include "deformable_flsm/runtime/simulation_loop.h"

#include "../core/fixtures.h"
#include "loop_harness.h"
#include "loop_rig.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <future>
#include <limits>
#include <mutex>
#include <thread>

namespace deformable_flsm {
namespace {

using Clock = std::chrono::steady_clock;

using test::makeBox;
using loop_rig::quickIdle;
using loop_rig::Rig;
using loop_rig::weightless;

TEST(SimulationLoop, FirstSnapshotIsTheRestState) {
  Rig rig;
  rig.loop->start();
  const Snapshot& s = rig.loop->acquire();
  EXPECT_GE(s.sequence, 1u);
  ASSERT_EQ(s.objects[0].positions.size(), rig.loop->lattice().size());
  for (std::size_t i = 0; i < s.objects[0].positions.size(); ++i)
    EXPECT_EQ(s.objects[0].positions[i], rig.loop->lattice().restPositions()[i]);
}

// The state thread's summary (copySummary()) is the newest complete state, read beside the
// mesh thread's acquire() while the loop steps: never older than what acquire() handed out, its
// parts from one state (the drags and the diagnostics of the same snapshot).
TEST(SimulationLoop, SummaryIsTheNewestStateBesideTheReader) {
  Rig rig;
  rig.holdByFarCorner();
  rig.loop->start();
  GrabCommand g;
  g.id = "a";
  g.particle = 0;
  g.target = rig.loop->lattice().restPositions()[0] + Eigen::Vector3d(-0.01, 0, 0);
  ASSERT_TRUE(rig.run(g).accepted);
  Snapshot summary;
  std::uint64_t seen = 0;
  for (int k = 0; k < 200; ++k) {
    const std::uint64_t acquired = rig.loop->acquire().sequence;
    rig.loop->copySummary(summary);
    EXPECT_GE(summary.sequence, acquired);
    EXPECT_GE(summary.sequence, seen) << "the summary went back in time";
    seen = summary.sequence;
    ASSERT_EQ(summary.objects.size(), 1u);
    EXPECT_TRUE(summary.objects[0].positions.empty()) << "the summary carries no particles";
    EXPECT_EQ(summary.objects[0].diag.drags, summary.objects[0].drags.size());
    EXPECT_EQ(summary.diag.drags, summary.objects[0].drags.size());
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
  }
  EXPECT_GT(seen, 1u) << "the loop never stepped";
  EXPECT_EQ(summary.objects[0].drags.size(), 1u) << "the grab never reached the summary";
}

TEST(SimulationLoop, HardGrabHoldsTheParticleAtTheTargetAndReleaseReturnsToRest) {
  Rig rig(quickIdle());
  rig.holdByFarCorner();
  rig.loop->start();
  const Eigen::Vector3d target = rig.loop->lattice().restPositions()[0] + Eigen::Vector3d(-0.01, 0, 0);
  GrabCommand g;
  g.id = "a";
  g.particle = 0;
  g.target = target;
  const CommandOutcome o = rig.run(g);
  ASSERT_TRUE(o.accepted) << o.message;
  EXPECT_EQ(o.particles, 1u);
  // A hard drag sets the particle's velocity so that it lands on the target every sub-step.
  ASSERT_TRUE(rig.waitFor([&](const Snapshot& s) {
    return s.diag.steps > 2 && s.objects[0].drags.size() == 1 && (s.objects[0].positions[0] - target).norm() < 1e-9;
  }));
  EXPECT_TRUE(rig.run(ReleaseCommand{"a"}).accepted);
  // Back to the rest shape.
  EXPECT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.idle; }, 20.0));
  EXPECT_LT(rig.loop->acquire().diag.shapeError, 1e-3 * rig.loop->lattice().objectSize());
}

// An attached drag follows its frame through the FrameSource before every step; while the
// source does not know the frame, the drag holds where the frame was last seen.
TEST(SimulationLoop, AttachedDragFollowsItsFrameAndHoldsWhenTheFrameIsLost) {
  LoopSettings settings;
  settings.idleHold = 0.0;
  Rig rig(settings);
  std::mutex mutex;
  Eigen::Isometry3d hand = Eigen::Isometry3d::Identity();
  bool known = true;
  int lookups = 0;
  rig.loop->setFrameSource([&](const std::string& frame, Eigen::Isometry3d& T) {
    std::lock_guard<std::mutex> lock(mutex);
    EXPECT_EQ(frame, "hand");
    ++lookups;
    T = hand;
    return known;
  });
  const Eigen::Vector3d corner = rig.loop->lattice().restPositions()[0];
  const std::vector<std::uint32_t> grabbed = rig.solver->nearestParticles(corner, 4);
  rig.loop->start();

  AttachCommand a;
  a.grab.id = "hand";
  a.grab.point = corner;
  a.grab.count = 4;
  a.frame = "hand";
  a.pose = hand;  // the particles' offsets in the hand frame are their positions now
  const CommandOutcome o = rig.run(a);
  ASSERT_TRUE(o.accepted) << o.message;
  EXPECT_EQ(o.particles, 4u);
  // A MOVE would fight the frame: refused.
  EXPECT_FALSE(rig.run(MoveCommand{"hand", Eigen::Vector3d::Zero()}).accepted);
  EXPECT_EQ(rig.rejected("attached_drag"), 1u);

  const auto at = [&](const Snapshot& s, const Eigen::Isometry3d& T) {
    double e = 0.0;
    for (std::uint32_t p : grabbed)
      e = std::max(e, (s.objects[0].positions[p] - T * rig.loop->lattice().restPositions()[p]).norm());
    return e;
  };
  Eigen::Isometry3d moved = Eigen::Translation3d(0.0, 0.0, 0.02) *
                            Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX());
  {
    std::lock_guard<std::mutex> lock(mutex);
    hand = moved;
  }
  EXPECT_TRUE(rig.waitFor([&](const Snapshot& s) { return at(s, moved) < 1e-9; }));
  // Lost: the frame source says no; a pose it would have given is ignored, the drag holds.
  {
    std::lock_guard<std::mutex> lock(mutex);
    known = false;
    hand = Eigen::Translation3d(0.0, 0.05, 0.0) * moved;
  }
  const std::uint64_t steps = rig.loop->acquire().diag.steps;
  ASSERT_TRUE(rig.waitFor([&](const Snapshot& s) { return s.diag.steps > steps + 10; }));
  EXPECT_LT(at(rig.loop->acquire(), moved), 1e-9);
  // Found again: it follows.
  {
    std::lock_guard<std::mutex> lock(mutex);
    known = true;
    moved = hand;
  }
  EXPECT_TRUE(rig.waitFor([&](const Snapshot& s) { return at(s, moved) < 1e-9; }));
  // Released: the frame is no longer looked up.
  ASSERT_TRUE(rig.run(ReleaseCommand{"hand"}).accepted);
  int before;
  {
    std::lock_guard<std::mutex> lock(mutex);
    before = lookups;
  }
  const std::uint64_t released = rig.loop->acquire().diag.steps;
  ASSERT_TRUE(rig.waitFor([&](const Snapshot& s) { return s.diag.steps > released + 5; }));
  std::lock_guard<std::mutex> lock(mutex);
  EXPECT_EQ(lookups, before);
}

TEST(SimulationLoop, AttachToANonRigidFrameIsRefused) {
  Rig rig;
  rig.loop->start();
  AttachCommand a;
  a.grab.id = "hand";
  a.grab.particle = 0;
  a.frame = "hand";
  a.pose.linear() *= 1.5;
  EXPECT_FALSE(rig.run(a).accepted);
  EXPECT_EQ(rig.rejected("bad_frame"), 1u);
  EXPECT_TRUE(rig.loop->acquire().objects[0].drags.empty());
}

TEST(SimulationLoop, SpringDragsOnTheSameParticlesShareTheLimit) {
  // Each spring drag alone within the limit, several on one particle added up past explicit
  // integration's stability and blew up: the limit is on their sum.
  Rig rig;
  rig.loop->start();
  const double h = rig.solver->params().substepLength();
  const auto& L = rig.loop->lattice();
  const double k0 = L.masses()[0] / (h * h);  // kMaxSpringRate = 1 on particle 0 alone
  GrabCommand g;
  g.particle = 0;
  g.target = L.restPositions()[0];
  g.id = "a";
  g.stiffness = 0.6 * k0;
  EXPECT_TRUE(rig.run(g).accepted);
  g.id = "b";
  const CommandOutcome o = rig.run(g);
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("other spring drags"), std::string::npos) << o.message;
  EXPECT_EQ(rig.rejected("spring_too_stiff"), 1u);
  g.stiffness = 0.35 * k0;  // what is left beside "a"
  EXPECT_TRUE(rig.run(g).accepted);
  g.id = "a";  // replacing "a": its own spring does not count against it
  g.stiffness = 0.6 * k0;
  EXPECT_TRUE(rig.run(g).accepted);
  g.id = "c";  // another particle: the whole limit
  g.particle = 1;
  g.target = L.restPositions()[1];
  g.stiffness = 0.9 * L.masses()[1] / (h * h);
  EXPECT_TRUE(rig.run(g).accepted);
  EXPECT_EQ(rig.rejected("spring_too_stiff"), 1u);
}

TEST(SimulationLoop, ACommandMovesTheObjectItAddressesAndNoOther) {
  // Two weightless boxes 1 m apart: a drag of "b" moves b; a, untouched, stays at rest (to
  // round-off: shape matching at rest reproduces the rest positions to ~1e-16 m per step).
  const SolverParams params = weightless();
  auto lattice = std::make_shared<const Lattice>(makeBox(4, 4, 4, 0.01), 1000.0, params.regionHalfWidth);
  Voxelization far = makeBox(4, 4, 4, 0.01);
  far.origin.x() += 1.0;
  auto farLattice = std::make_shared<const Lattice>(far, 1000.0, params.regionHalfWidth);
  auto world = std::make_unique<World>(params.timeStep, params.substeps);
  world->addObject("a", lattice, params);
  world->addObject("b", farLattice, params);
  LoopSettings settings;
  settings.idleHold = 0.0;
  auto stats = std::make_shared<CommandStats>();
  SimulationLoop loop(std::move(world), settings, stats);
  ASSERT_EQ(loop.objectNames(), (std::vector<std::string>{"a", "b"}));
  loop.start();

  GrabCommand grab;
  grab.id = "hand";
  grab.particle = 0;
  const Eigen::Vector3d target = farLattice->restPositions()[0] + Eigen::Vector3d(0.0, 0.0, 0.005);
  grab.target = target;
  Command toB{grab, std::make_shared<std::promise<CommandOutcome>>(), "b"};
  auto answer = toB.outcome->get_future();
  loop.submit(std::move(toB));
  ASSERT_EQ(answer.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  EXPECT_TRUE(answer.get().accepted);
  const Clock::time_point end = Clock::now() + std::chrono::seconds(5);
  while (Clock::now() < end) {
    const Snapshot& s = loop.acquire();
    if (s.diag.steps > 2 && (s.objects[1].positions[0] - target).norm() < 1e-9) break;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  const Snapshot& s = loop.acquire();
  ASSERT_EQ(s.objects.size(), 2u);
  EXPECT_EQ(s.objects[1].name, "b");
  EXPECT_LT((s.objects[1].positions[0] - target).norm(), 1e-9) << "b was not dragged";
  EXPECT_EQ(s.objects[1].drags.size(), 1u);
  EXPECT_TRUE(s.objects[0].drags.empty());
  for (std::size_t i = 0; i < lattice->size(); ++i)
    ASSERT_LT((s.objects[0].positions[i] - lattice->restPositions()[i]).norm(), 1e-12)
        << "a moved at particle " << i;
  EXPECT_EQ(s.diag.drags, 1u);  // the scene's figures sum the objects'
  // a, which did not move, still shows its first state; b has newer ones (its messages are
  // rebuilt, a's are not)
  EXPECT_EQ(s.objects[0].version, 1u);
  EXPECT_GT(s.objects[1].version, 1u);

  // An object the scene does not have: refused, counted, nothing else changes.
  Command toNobody{ReleaseCommand{"hand"}, std::make_shared<std::promise<CommandOutcome>>(), "gone"};
  auto refused = toNobody.outcome->get_future();
  loop.submit(std::move(toNobody));
  ASSERT_EQ(refused.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  const CommandOutcome o = refused.get();
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("'gone'"), std::string::npos) << o.message;
  EXPECT_EQ(stats->counts().rejectedByReason.at("unknown_object"), 1u);
  EXPECT_EQ(loop.acquire().diag.drags, 1u);
}

TEST(SimulationLoop, RejectionsCarryTheirReason) {
  Rig rig;
  rig.loop->start();
  EXPECT_FALSE(rig.run(MoveCommand{"nobody", Eigen::Vector3d::Zero()}).accepted);
  EXPECT_FALSE(rig.run(ReleaseCommand{"nobody"}).accepted);
  EXPECT_EQ(rig.rejected("unknown_drag"), 2u);

  GrabCommand stiff;
  stiff.id = "s";
  stiff.particle = 0;
  stiff.target = rig.loop->lattice().restPositions()[0];
  stiff.stiffness = 1e12;
  const CommandOutcome o = rig.run(stiff);
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("N/m"), std::string::npos) << o.message;
  EXPECT_EQ(rig.rejected("spring_too_stiff"), 1u);

  ApplyForceCommand huge;
  huge.particle = 3;
  huge.force = Eigen::Vector3d(1e30, 0, 0);
  huge.duration = 0.1;
  EXPECT_FALSE(rig.run(huge).accepted);
  huge.impulse = true;
  EXPECT_FALSE(rig.run(huge).accepted);
  EXPECT_EQ(rig.rejected("too_large"), 2u);

  ApplyForceCommand nowhere;
  nowhere.point = Eigen::Vector3d(0.5, 0.5, 0.5);  // 40 cm from a 6 cm box
  nowhere.radius = 0.01;
  nowhere.duration = 0.1;
  EXPECT_FALSE(rig.run(nowhere).accepted);
  EXPECT_EQ(rig.rejected("empty_selection"), 1u);

  SolverParams heavier = weightless();
  heavier.density = 2000.0;  // defines the masses: cannot change at run time
  EXPECT_FALSE(rig.run(ParamsCommand{heavier}).accepted);
  EXPECT_EQ(rig.rejected("invalid_params"), 1u);
  EXPECT_EQ(rig.stats->counts().accepted, 0u);
}

TEST(SimulationLoop, SensibleForceAndImpulseAreApplied) {
  Rig rig;
  rig.loop->start();
  ApplyForceCommand f;
  f.point = rig.loop->lattice().restPositions()[0];
  f.radius = 0.015;
  f.force = Eigen::Vector3d(0.0, 0.0, 0.5);
  f.duration = 0.5;
  const CommandOutcome o = rig.run(f);
  ASSERT_TRUE(o.accepted) << o.message;
  EXPECT_GE(o.particles, 4u);  // the corner and its neighbours within 1.5 cells
  EXPECT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.forces == 1; }));
  EXPECT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.kineticEnergy > 0.0; }));
  f.impulse = true;
  f.force = Eigen::Vector3d(0.0, 1e-3, 0.0);
  EXPECT_TRUE(rig.run(f).accepted);
}

TEST(SimulationLoop, PinBoxAnswersWithTheCount) {
  Rig rig;
  rig.loop->start();
  // The bottom layer of the 6 x 6 x 6 box: cell centres at z = 0.005.
  const CommandOutcome o =
      rig.run(PinBoxCommand{Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(1, 1, 0.006), true});
  ASSERT_TRUE(o.accepted);
  EXPECT_EQ(o.particles, 36u);
  EXPECT_EQ(o.pinnedTotal, 36u);
  EXPECT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.pinned == 36; }));
}

TEST(SimulationLoop, FullQueueRejectsAndAnswers) {
  Rig rig;  // not started: nothing drains the queue
  std::vector<std::future<CommandOutcome>> answers;
  for (std::size_t i = 0; i < CommandLimits::kQueueCapacity + 10; ++i) {
    Command c{ResetCommand{}, std::make_shared<std::promise<CommandOutcome>>(), std::string()};
    answers.push_back(c.outcome->get_future());
    rig.loop->submit(std::move(c));
  }
  EXPECT_EQ(rig.rejected("queue_full"), 10u);
  for (std::size_t i = CommandLimits::kQueueCapacity; i < answers.size(); ++i) {
    ASSERT_EQ(answers[i].wait_for(std::chrono::seconds(0)), std::future_status::ready);
    EXPECT_FALSE(answers[i].get().accepted);
  }
  // Stopping answers the queued ones too, so that no service waits forever.
  rig.loop->stop();
  ASSERT_EQ(answers[0].wait_for(std::chrono::seconds(0)), std::future_status::ready);
  EXPECT_FALSE(answers[0].get().accepted);
}

TEST(SimulationLoop, NonFiniteStateIsResetNeverPublished) {
  LoopSettings settings;
  settings.idleHold = 0.0;
  Rig rig(settings);
  std::vector<Eigen::Vector3d> x = rig.solver->positions();
  x[7].x() = std::numeric_limits<double>::quiet_NaN();
  rig.solver->setPositions(x);  // before start(): the loop does not own the thread yet
  rig.loop->start();
  const Snapshot& first = rig.loop->acquire();
  EXPECT_EQ(first.diag.solverResets, 1u);
  for (const Eigen::Vector3d& p : first.objects[0].positions) ASSERT_TRUE(p.allFinite());
  ASSERT_TRUE(rig.waitFor([](const Snapshot& s) { return s.diag.steps >= 2; }));
  const Snapshot& s = rig.loop->acquire();
  EXPECT_EQ(s.diag.solverResets, 1u);
  for (const Eigen::Vector3d& p : s.objects[0].positions) ASSERT_TRUE(p.allFinite());
}

TEST(SimulationLoop, BlownUpStateIsResetBeforeItOverflowsAFloat) {
  // A state that grows without bound is finite in double for a while, but a coordinate above
  // 3.4e38 is infinity in the published float32 clouds: reset it before that.
  LoopSettings settings;
  settings.idleHold = 0.0;
  Rig rig(settings);
  std::vector<Eigen::Vector3d> x = rig.solver->positions();
  x[3].z() = 1e39;
  rig.solver->setPositions(x);
  rig.loop->start();
  const Snapshot& first = rig.loop->acquire();
  EXPECT_EQ(first.diag.solverResets, 1u);
  for (const Eigen::Vector3d& p : first.objects[0].positions)
    for (int a = 0; a < 3; ++a) ASSERT_TRUE(std::isfinite(static_cast<float>(p[a])));
  // The log says where it went wrong: the particle, and what acted on the object.
  const std::string cause = rig.loop->lastResetCause();
  EXPECT_NE(cause.find("particle 3 at"), std::string::npos) << cause;
  EXPECT_NE(cause.find("colliders"), std::string::npos) << cause;
  // A far but sane coordinate (a long free fall) is left alone.
  Rig far(settings);
  x = far.solver->positions();
  for (Eigen::Vector3d& p : x) p.z() -= 1e6;
  far.solver->setPositions(x);
  far.loop->start();
  EXPECT_EQ(far.loop->acquire().diag.solverResets, 0u);
  EXPECT_TRUE(far.loop->lastResetCause().empty());
}

}  // namespace
}  // namespace deformable_flsm
