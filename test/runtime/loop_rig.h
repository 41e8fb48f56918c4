/// @file loop_rig.h
/// The rig of the SimulationLoop tests on one weightless box (test_simulation_loop,
/// test_simulation_loop_pace): its parameters, the loop with its command statistics, settings
/// that rest soon.
#pragma once

#include "deformable_flsm/runtime/simulation_loop.h"

#include "../core/fixtures.h"
#include "loop_harness.h"

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>

namespace deformable_flsm {
namespace loop_rig {

inline SolverParams weightless() {
  SolverParams p;
  p.gravity.setZero();
  p.regionHalfWidth = 1;
  // Strong ambient damping lets the rest tests finish in a second or two (these tests are about
  // the loop, not about damping); a free box keeps the momentum a drag gives it (see
  // Rig::holdByFarCorner()).
  p.ambientDamping = 5.0;
  return p;
}

struct Rig {
  explicit Rig(LoopSettings settings = LoopSettings(), SolverParams params = weightless(),
               int n = 6, std::shared_ptr<LoopClock> clock = nullptr) {
    auto lattice = std::make_shared<const Lattice>(test::makeBox(n, n, n, 0.01), 1000.0, params.regionHalfWidth);
    auto world = std::make_unique<World>(params.timeStep, params.substeps);
    solver = &world->addObject("box", lattice, params);
    stats = std::make_shared<CommandStats>();
    loop = std::make_unique<SimulationLoop>(std::move(world), settings, stats, std::move(clock));
  }
  /// Pins the particle farthest from particle 0 (before start()): ambient damping acts on the
  /// motion relative to a free object's rigid motion, so a free box would keep the momentum a drag
  /// or a kick gives it and never rest; held by the world, it comes to rest.
  void holdByFarCorner() { solver->setPinned(static_cast<std::uint32_t>(solver->lattice().size() - 1), true); }
  /// Submits and waits for the outcome (the loop must be running).
  CommandOutcome run(CommandBody body) { return test::runCommand(*loop, std::move(body)); }
  /// Polls snapshots until `done` or `timeout` seconds; returns whether `done` held.
  bool waitFor(const std::function<bool(const Snapshot&)>& done, double timeout = 5.0) {
    return test::waitForSnapshot(*loop, done, timeout);
  }
  std::uint64_t rejected(const std::string& reason) const { return test::rejectedCount(*stats, reason); }

  Solver* solver = nullptr;  // owned by the loop; touched only before start()
  std::shared_ptr<CommandStats> stats;
  std::unique_ptr<SimulationLoop> loop;
};

inline LoopSettings quickIdle() {
  LoopSettings s;
  s.idleHold = 0.2;
  return s;
}

}  // namespace loop_rig
}  // namespace deformable_flsm
