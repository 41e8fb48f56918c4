/// @file problem_reporter.h
/// flsm_node's log: what is wrong with the scene at start-up, and what goes wrong while it runs
/// (stiffness saturated, solver resets, dropped steps, a slow loop, slow publishing), each with
/// what to change, throttled so that a lasting problem does not flood the log. It decides what to
/// say; where it goes (rosconsole in the node) is the sink it is given.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/runtime/node_params.h"
#include "deformable_flsm/runtime/scene.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include "deformable_flsm/core/collider.h"

#include <array>
#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <set>
#include <string>

namespace deformable_flsm {

/// How bad a reported problem is.
enum class ProblemSeverity { Warning, Error };

/// Where ProblemReporter's lines go: one complete line per call (no trailing newline).
using ProblemLog = std::function<void(ProblemSeverity, const std::string&)>;

/// Main thread only (the publish timer). Keeps references to `params` (read at each report: the
/// material and rates may be reconfigured), `info` and `lattice`, which must outlive it.
class ProblemReporter {
 public:
  /// Seconds between two lines of the same throttled kind (slow loop, slow publishing).
  static constexpr double kThrottleSeconds = 5.0;

  ProblemReporter(const NodeParams& params, const SceneInfo& info, const Lattice& lattice,
                  ProblemLog log);

  /// Warns about the scene as built: stiffness saturated, pinned boxes holding no particle,
  /// gravity without pins.
  void warnAboutScene() const;
  /// Reports what changed in the loop's diagnostics since the last call.
  void report(const LoopDiagnostics& d);
  /// Where the reason of the last reset of a blown-up state comes from (logged with the reset).
  void setResetCause(std::function<std::string()> cause) { resetCause_ = std::move(cause); }
  /// Warns when publishing took longer than the publish period.
  void publishingTook(double seconds) const;

  /// A collider pressing on fewer particles than this meets a patch under about 3 cells across,
  /// which the lattice does not resolve (docs/method.md: a sphere's force is 1.16 of the FEM's at
  /// 1.8 cells of contact radius at nu 0, and stays 1.12 to 1.16 to 4.8; a 5-cell punch 0.90).
  static constexpr std::size_t kResolvedContacts = 7;
  /// ... for at least this long (s of simulated time): a touch on its way in or out is not warned
  static constexpr double kUnresolvedSeconds = 1.0;
  /// Watches each collider's contact (the wrenches of the newest state, at simulated time
  /// `time`): one warning per collider id that keeps pressing on 1 to kResolvedContacts - 1
  /// particles for kUnresolvedSeconds, with the lattice spacing that would resolve it (the first
  /// object's lattice); and one per collider id placed or moved in one jump deeper than a
  /// particle's radius into the object (ContactWrench::buried), saying to move it in instead.
  void watchContacts(const std::map<std::string, ContactWrench>& wrenches, double time);

 private:
  const NodeParams& params_;
  const SceneInfo& info_;
  const Lattice& lattice_;
  std::uint64_t reportedResets_ = 0, reportedDropped_ = 0;
  std::function<std::string()> resetCause_;
  /// colliders pressing on a patch the lattice does not resolve: since when (simulated s)
  std::map<std::string, double> smallPatchSince_;
  std::set<std::string> warnedSmallPatch_, warnedBuried_;
  bool reportedSaturated_ = false;
  ProblemLog log_;
  /// kinds of throttled line: the loop cannot keep up, the loop runs slow, publishing is slow
  enum Throttled { kDropping, kSlow, kPublishing, kThrottledKinds };
  /// when each kind was last logged (mutable: publishingTook() is const)
  mutable std::array<std::chrono::steady_clock::time_point, kThrottledKinds> lastLogged_{};
  mutable std::array<bool, kThrottledKinds> everLogged_{};
  /// the particles' contact radius (m): the scene's, or half the spacing before it is known
  double contactRadius() const;
  /// logs `line` unless a line of this kind went out less than kThrottleSeconds ago
  void throttled(Throttled kind, const std::string& line) const;
};

}  // namespace deformable_flsm
