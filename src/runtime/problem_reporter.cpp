#include "deformable_flsm/runtime/problem_reporter.h"

#include "deformable_flsm/runtime/format.h"

#include <cmath>
#include <cstdarg>
#include <cstdio>
#include <string>

namespace deformable_flsm {

namespace {

/// Warn when the achieved real-time factor falls below this fraction of the requested one.
constexpr double kSlowFraction = 0.9;
/// printf into a std::string, prefixed with the node's name as every line of its log is.
[[gnu::format(printf, 1, 2)]] std::string line(const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::string text = "flsm_node: " + vformatted(format, args);
  va_end(args);
  return text;
}

}  // namespace

ProblemReporter::ProblemReporter(const NodeParams& params, const SceneInfo& info, const Lattice& lattice,
                                 ProblemLog log)
    : params_(params),
      info_(info),
      lattice_(lattice),
      reportedSaturated_(info.substepsForModulus > 0),  // warned about by warnAboutScene()
      log_(std::move(log)) {}

void ProblemReporter::throttled(Throttled kind, const std::string& text) const {
  const auto now = std::chrono::steady_clock::now();
  if (everLogged_[kind] &&
      std::chrono::duration<double>(now - lastLogged_[kind]).count() < kThrottleSeconds)
    return;
  everLogged_[kind] = true;
  lastLogged_[kind] = now;
  log_(ProblemSeverity::Warning, text);
}

void ProblemReporter::warnAboutScene() const {
  const std::string saturated = saturationWarning(info_, params_);
  if (!saturated.empty()) log_(ProblemSeverity::Warning, "flsm_node: " + saturated);
  for (std::size_t b = 0; b < info_.pinnedPerBox.size(); ++b) {
    if (info_.pinnedPerBox[b] == 0) {
      log_(ProblemSeverity::Warning, line("~pinned box %zu holds no particle (rest positions are in frame '%s', "
               "after ~mesh_scale and ~mesh_rpy; the lattice spans [%.3g, %.3g, %.3g] to "
               "[%.3g, %.3g, %.3g] m)",
               b, params_.frameId.c_str(), lattice_.restMin().x(), lattice_.restMin().y(),
               lattice_.restMin().z(), lattice_.restMax().x(), lattice_.restMax().y(),
               lattice_.restMax().z()));
    }
  }
  if (info_.pinned == 0 && !params_.ground && params_.colliders.empty() &&
      !params_.solver.gravity.isZero(0.0)) {
    log_(ProblemSeverity::Warning,
         "flsm_node: gravity is on, no particle is pinned and there is no collider: the object "
         "falls forever. Set ~ground to true, pin a box (~pinned) or set ~gravity to [0, 0, 0].");
  }
}

void ProblemReporter::report(const LoopDiagnostics& d) {
  if (d.stiffnessSaturated != reportedSaturated_) {
    reportedSaturated_ = d.stiffnessSaturated;
    if (d.stiffnessSaturated) {
      log_(ProblemSeverity::Warning, line("~youngs_modulus %.4g Pa now asks for more stiffness than the time "
               "step allows (alpha capped at %.3g): the material is softer than asked; more "
               "~substeps (restart) would fix it", params_.solver.youngsModulus, d.alpha));
    }
  }
  if (d.solverResets > reportedResets_) {
    reportedResets_ = d.solverResets;
    const std::string cause = resetCause_ ? resetCause_() : std::string();
    log_(ProblemSeverity::Error, line("the solver state became non-finite (or grew beyond 1e12 m or m/s) and was reset to rest (%llu "
              "times so far). This should not happen: please report it with the commands sent "
              "and this: %s",
              static_cast<unsigned long long>(d.solverResets), cause.c_str()));
  }
  if (d.droppedSteps > reportedDropped_) {
    reportedDropped_ = d.droppedSteps;
    throttled(kDropping,
              line("the machine cannot keep up: %.2f simulated s per wall s (asked "
                      "%.2f), a step takes %.1f ms for %.1f ms of simulated time; %llu steps "
                      "dropped so far. Lower ~real_time_factor, ~substeps or ~particle_budget.",
                      d.achievedRealTimeFactor, d.requestedRealTimeFactor, 1e3 * d.stepSeconds,
                      1e3 * params_.solver.timeStep,
                      static_cast<unsigned long long>(d.droppedSteps)));
  } else if (!d.idle && !d.paused && params_.clock != NodeParams::Clock::Follow &&
             d.achievedRealTimeFactor < kSlowFraction * d.requestedRealTimeFactor && d.steps > 10) {
    // (a followed clock sets the pace, not ~real_time_factor; paused, nothing is paced)
    // A step may take the wall time it stands for; if it takes (nearly) all of it, the scene is too
    // big for the asked rate (or the machine too busy to give it a core); if not, something else
    // holds the loop up.
    const double budget = params_.solver.timeStep / d.requestedRealTimeFactor;
    const bool stepsTooLong = d.stepSeconds > kSlowFraction * budget;
    throttled(kSlow,
              line("running at %.2f of the asked real-time factor %.2f (a step takes "
                      "%.1f ms of the %.1f ms it may); %s",
                      d.achievedRealTimeFactor / d.requestedRealTimeFactor, d.requestedRealTimeFactor,
                      1e3 * d.stepSeconds, 1e3 * budget,
                      stepsTooLong ? "the steps take too long: lower ~real_time_factor, ~substeps or "
                                     "~particle_budget, or free a core"
                                   : "the steps fit, so other work on this machine holds the loop up"));
  }
}

void ProblemReporter::publishingTook(double seconds) const {
  if (seconds > 1.0 / params_.publishRate) {
    throttled(kPublishing,
              line("publishing took %.1f ms, longer than the %.1f ms period of "
                      "~publish_rate: lower ~publish_rate or ~render_triangle_budget",
                      1e3 * seconds, 1e3 / params_.publishRate));
  }
}

double ProblemReporter::contactRadius() const {
  return info_.contactRadius > 0.0 ? info_.contactRadius : 0.5 * lattice_.spacing();
}

void ProblemReporter::watchContacts(const std::map<std::string, ContactWrench>& wrenches, double time) {
  for (const auto& [id, w] : wrenches) {
    if (w.buried > 0 && warnedBuried_.insert(id).second)
      log_(ProblemSeverity::Warning,
           line("collider '%s' found %zu particle%s deeper than their radius (%.3g m) inside it at the "
                "start of a sub-step: it was placed, or moved in one jump, into the object, so they are "
                "pushed out through its nearest face (a pad set into a surface sends the particles under "
                "its edges out sideways, and its force is not that of the pad pressed in). Move a "
                "collider into the object over several steps (poses closer than %.3g m apart, or a "
                "velocity).",
                id.c_str(), w.buried, w.buried == 1 ? "" : "s", contactRadius(), contactRadius()));
    const bool small = w.contacts > 0 && w.contacts < kResolvedContacts && w.force.squaredNorm() > 0.0;
    if (!small) {
      smallPatchSince_.erase(id);
      continue;
    }
    const auto since = smallPatchSince_.emplace(id, time).first->second;
    if (time - since < kUnresolvedSeconds || warnedSmallPatch_.count(id) != 0) continue;
    warnedSmallPatch_.insert(id);
    const double dx = lattice_.spacing();
    const double across = 2.0 * std::sqrt(static_cast<double>(w.contacts) / 3.14159265358979) * dx;
    log_(ProblemSeverity::Warning,
         line("collider '%s' has pressed on only %zu particle%s for %.1f s: a patch about %.3g m "
              "across, under 3 cells of %.3g m, which the lattice does not resolve, so its force "
              "(%.3g N) is only roughly what ~youngs_modulus gives (a sphere at 1.8 cells of contact "
              "radius reads 1.16 of a finite element solution's). A lattice of ~spacing %.3g m (about %.0f times the "
              "particles) or a larger ~particle_budget resolves it.",
              id.c_str(), w.contacts, w.contacts == 1 ? "" : "s", time - since, across, dx, w.force.norm(),
              across / 3.0, std::pow(3.0 * dx / across, 3)));
  }
}

}  // namespace deformable_flsm
