/// @file test_simulation_loop_objects.cpp
/// Tests of adding and removing objects in a running SimulationLoop (AddObjectCommand,
/// RemoveObjectCommand in runtime/commands.h): an added object is stepped, shows in the
/// snapshots and takes commands by its name; a removed one goes with its drags; a duplicate
/// name, an object that starts inside another, an unknown name and the last object are refused
/// with a reason and counted while the loop keeps stepping.
#include "deformable_flsm/runtime/simulation_loop.h"

#include "../core/fixtures.h"
#include "loop_harness.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <string>

namespace deformable_flsm {
namespace {

using test::makeBox;

SolverParams weightless() {
  SolverParams p;
  p.gravity.setZero();
  p.regionHalfWidth = 1;
  return p;
}

/// A 4 x 4 x 4 box lattice of 1 cm cells, its lowest corner moved by `offset` (m).
std::shared_ptr<const Lattice> boxAt(const Eigen::Vector3d& offset, const SolverParams& params) {
  Voxelization v = makeBox(4, 4, 4, 0.01);
  v.origin += offset;
  return std::make_shared<const Lattice>(v, 1000.0, params.regionHalfWidth);
}

const ObjectSnapshot* find(const Snapshot& s, const std::string& name) {
  const auto it = std::find_if(s.objects.begin(), s.objects.end(),
                               [&](const ObjectSnapshot& o) { return o.name == name; });
  return it == s.objects.end() ? nullptr : &*it;
}

struct TwoObjectRig {
  TwoObjectRig() {
    auto world = std::make_unique<World>(params.timeStep, params.substeps);
    world->addObject("a", boxAt(Eigen::Vector3d::Zero(), params), params);
    LoopSettings settings;
    settings.idleHold = 0.0;  // keeps stepping: the tests watch the steps go on
    stats = std::make_shared<CommandStats>();
    loop = std::make_unique<SimulationLoop>(std::move(world), settings, stats);
    loop->start();
  }
  CommandOutcome run(CommandBody body, const std::string& object = std::string()) {
    Command c{std::move(body), std::make_shared<std::promise<CommandOutcome>>(), object};
    auto f = c.outcome->get_future();
    loop->submit(std::move(c));
    EXPECT_EQ(f.wait_for(std::chrono::seconds(5)), std::future_status::ready);
    return f.get();
  }
  std::uint64_t steps() { return loop->acquire().diag.steps; }
  bool stepsGoOn() {
    const std::uint64_t before = steps();
    return test::waitForSnapshot(*loop, [&](const Snapshot& s) { return s.diag.steps > before + 2; }, 5.0);
  }

  SolverParams params = weightless();
  std::shared_ptr<CommandStats> stats;
  std::unique_ptr<SimulationLoop> loop;
};

TEST(SimulationLoopObjects, AnAddedObjectIsSteppedAndCommandedByNameAndGoesWhenRemoved) {
  TwoObjectRig rig;
  auto lattice = boxAt(Eigen::Vector3d(1.0, 0.0, 0.0), rig.params);
  const CommandOutcome added = rig.run(AddObjectCommand{"b", lattice, rig.params});
  ASSERT_TRUE(added.accepted) << added.message;
  EXPECT_EQ(added.particles, lattice->size());
  ASSERT_TRUE(test::waitForSnapshot(*rig.loop, [](const Snapshot& s) { return find(s, "b") != nullptr; }, 5.0));
  {
    const Snapshot& s = rig.loop->acquire();
    ASSERT_EQ(s.objects.size(), 2u);
    EXPECT_EQ(s.objects[1].name, "b");  // in the World's order: added last
    EXPECT_EQ(s.objects[1].positions.size(), lattice->size());
  }
  // its rest centre of mass, for the range checks of commands to it
  const Eigen::Vector3d restCom = boxAt(Eigen::Vector3d(1.0, 0.0, 0.0), rig.params)->restPositions()[0] +
                                  Eigen::Vector3d::Constant(0.015);
  EXPECT_LT((rig.loop->centerOfMass("b") - restCom).norm(), 1e-9);

  // a drag of b by name moves b's particle to its target
  GrabCommand grab;
  grab.id = "hand";
  grab.particle = 0;
  grab.target = lattice->restPositions()[0] + Eigen::Vector3d(0.0, 0.0, 0.005);
  ASSERT_TRUE(rig.run(grab, "b").accepted);
  ASSERT_TRUE(test::waitForSnapshot(*rig.loop, [&](const Snapshot& s) {
    const ObjectSnapshot* b = find(s, "b");
    return b != nullptr && (b->positions[0] - grab.target).norm() < 1e-9;
  }, 5.0)) << "b was not dragged";
  EXPECT_EQ(rig.loop->acquire().diag.drags, 1u);

  // removed: out of the snapshots with its drag, commands to it refused, a stepped on
  const CommandOutcome removed = rig.run(RemoveObjectCommand{"b"});
  ASSERT_TRUE(removed.accepted) << removed.message;
  ASSERT_TRUE(test::waitForSnapshot(*rig.loop, [](const Snapshot& s) { return find(s, "b") == nullptr; }, 5.0));
  EXPECT_EQ(rig.loop->acquire().objects.size(), 1u);
  EXPECT_EQ(rig.loop->acquire().diag.drags, 0u);
  EXPECT_FALSE(rig.run(ReleaseCommand{"hand"}, "b").accepted);
  EXPECT_EQ(test::rejectedCount(*rig.stats, "unknown_object"), 1u);
  EXPECT_TRUE(rig.stepsGoOn());

  // the name is free again
  EXPECT_TRUE(rig.run(AddObjectCommand{"b", lattice, rig.params}).accepted);
}

TEST(SimulationLoopObjects, BadAdditionsAndRemovalsAreRefusedWithAReasonAndCounted) {
  TwoObjectRig rig;
  // a's name again
  CommandOutcome o = rig.run(AddObjectCommand{"a", boxAt(Eigen::Vector3d(1.0, 0.0, 0.0), rig.params), rig.params});
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("'a'"), std::string::npos) << o.message;
  // starting inside a (half a box over it)
  o = rig.run(AddObjectCommand{"c", boxAt(Eigen::Vector3d(0.02, 0.0, 0.0), rig.params), rig.params});
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("'c'"), std::string::npos) << o.message;
  EXPECT_NE(o.message.find("a"), std::string::npos) << o.message;
  // a time step other than the world's
  SolverParams other = rig.params;
  other.timeStep *= 2.0;
  EXPECT_FALSE(rig.run(AddObjectCommand{"d", boxAt(Eigen::Vector3d(1.0, 0.0, 0.0), rig.params), other}).accepted);
  EXPECT_EQ(test::rejectedCount(*rig.stats, "invalid_object"), 3u);

  // an unknown name, and the last object
  o = rig.run(RemoveObjectCommand{"nobody"});
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("'nobody'"), std::string::npos) << o.message;
  EXPECT_EQ(test::rejectedCount(*rig.stats, "unknown_object"), 1u);
  o = rig.run(RemoveObjectCommand{"a"});
  EXPECT_FALSE(o.accepted);
  EXPECT_NE(o.message.find("last"), std::string::npos) << o.message;
  EXPECT_EQ(test::rejectedCount(*rig.stats, "invalid_object"), 4u);

  // nothing changed, and the loop steps on
  const Snapshot& s = rig.loop->acquire();
  ASSERT_EQ(s.objects.size(), 1u);
  EXPECT_EQ(s.objects[0].name, "a");
  EXPECT_TRUE(rig.stepsGoOn());
}

TEST(SimulationLoopObjects, RemovingTheFirstObjectHandsTheSceneCommandsToTheNext) {
  // Commands without an object name address the first object: once it is removed, the next.
  TwoObjectRig rig;
  ASSERT_TRUE(rig.run(AddObjectCommand{"b", boxAt(Eigen::Vector3d(1.0, 0.0, 0.0), rig.params), rig.params}).accepted);
  ASSERT_TRUE(rig.run(RemoveObjectCommand{"a"}).accepted);
  GrabCommand grab;
  grab.id = "hand";
  grab.particle = 0;
  grab.target = boxAt(Eigen::Vector3d(1.0, 0.0, 0.0), rig.params)->restPositions()[0];
  const CommandOutcome o = rig.run(grab);
  EXPECT_TRUE(o.accepted) << o.message;
  ASSERT_TRUE(test::waitForSnapshot(*rig.loop, [](const Snapshot& s) {
    return s.objects.size() == 1 && s.objects[0].name == "b" && s.objects[0].drags.size() == 1;
  }, 5.0));
  // the start-up list is what it was
  EXPECT_EQ(rig.loop->objectNames(), (std::vector<std::string>{"a"}));
}

}  // namespace
}  // namespace deformable_flsm
