/// @file problem_reporter.h
/// flsm_node's log: what is wrong with the scene at start-up, and what goes wrong while it runs
/// (stiffness saturated, solver resets, dropped steps, a slow loop, slow publishing), each with
/// what to change, throttled so that a lasting problem does not flood the log.
#pragma once


#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/ros/scene.h"
#include "deformable_flsm/ros/simulation_loop.h"

#include <cstdint>
#include <functional>
#include <string>

namespace deformable_flsm {

/// Main thread only (the publish timer). Keeps references to `params` (read at each report: the
/// material and rates may be reconfigured), `info` and `lattice`, which must outlive it.
class ProblemReporter {
 public:
  ProblemReporter(const NodeParams& params, const SceneInfo& info, const Lattice& lattice);

  /// Warns about the scene as built: stiffness saturated, pinned boxes holding no particle,
  /// gravity without pins.
  void warnAboutScene() const;
  /// Reports what changed in the loop's diagnostics since the last call.
  void report(const LoopDiagnostics& d);
  /// Where the reason of the last reset of a blown-up state comes from (logged with the reset).
  void setResetCause(std::function<std::string()> cause) { resetCause_ = std::move(cause); }
  /// Warns when publishing took longer than the publish period.
  void publishingTook(double seconds) const;

 private:
  const NodeParams& params_;
  const SceneInfo& info_;
  const Lattice& lattice_;
  std::uint64_t reportedResets_ = 0, reportedDropped_ = 0;
  std::function<std::string()> resetCause_;
  bool reportedSaturated_ = false;
};

}  // namespace deformable_flsm
