/// @file runs.h
/// One run of the speed/accuracy study (flsm_study): a method on a scenario at a resolution and
/// sub-step count, timed (Run, runOnce()); and the wall time of a stage.
#pragma once

#include "study/config.h"
#include "study/metrics.h"
#include "study/peers.h"
#include "study/scenarios.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

struct Run {
  Scenario scenario;
  std::string method;
  int resolution = 0, substeps = 0;
  bool reference = false;
  std::size_t particles = 0;
  int halfWidth = 0;
  double substep = 0.0;
  RunRecord record;
  /// CPU time of the stepping thread per frame (s): the mean over the frames (the cost of the
  /// whole run, a stiff start included), then the median over repeats
  double secondsPerFrame = 0.0;
  /// wall time per frame (s): the median over the frames, then over repeats (on a busy machine
  /// it includes the time the thread waited for a core)
  double wallSecondsPerFrame = 0.0;
  int repeats = 0;
  /// FastLSM only: the alpha used, and whether the step was too long for the modulus (-1 n/a)
  double alpha = std::numeric_limits<double>::quiet_NaN();
  int saturated = -1;
  /// Young's modulus of the run (Pa)
  double youngsModulus = 0.0;
  /// implicit step only: conjugate-gradient iterations of a frame's last sub-step, mean over the
  /// frames of the first repetition (FlsmMethod::meanIterations())
  double iterations = std::numeric_limits<double>::quiet_NaN();
};

/// One run of `method` on `scenario` at a resolution and sub-step count, repeated up to `repeats`
/// times while cheap (kRepeatBelowSeconds); `youngsModulus` (Pa) replaces the object's when
/// positive.
inline Run runOnce(Scenario scenario, const StudyObject& object, const std::string& method, int resolution, int substeps,
                   const Calibration& calib, int repeats, bool reference, double youngsModulus = 0.0) {
  Run r;
  r.scenario = scenario;
  r.method = method;
  r.resolution = resolution;
  r.substeps = substeps;
  r.reference = reference;
  const auto lattice = buildLattice(object, resolution);
  r.particles = lattice->size();
  r.halfWidth = lattice->regionHalfWidth();
  Setting s = scenarioSetting(scenario, object, resolution, substeps);
  if (youngsModulus > 0.0) s.youngsModulus = youngsModulus;
  r.youngsModulus = s.youngsModulus;
  r.substep = s.substep();
  std::vector<double> perRepeat, perRepeatWall;
  for (int k = 0; k < repeats; ++k) {
    auto m = makeMethod(method, lattice, s, calib);
    if (const auto* flsm = dynamic_cast<const FlsmMethod*>(m.get())) {
      r.alpha = flsm->solver().alpha();
      r.saturated = flsm->solver().stiffnessSaturated() ? 1 : 0;
    }
    RunRecord rec = runScenario(scenario, object, *lattice, *m, s.frameStep,
                                scenario == Scenario::EarDrag ? kSampleEvery : 0);
    if (const auto* flsm = dynamic_cast<const FlsmMethod*>(m.get()); flsm && k == 0 &&
        flsm->solver().params().integrator == Integrator::Implicit)
      r.iterations = flsm->meanIterations();
    double cpu = 0.0;
    for (double t : rec.frameCpuSeconds) cpu += t;
    perRepeat.push_back(cpu / double(std::max<std::size_t>(1, rec.frameCpuSeconds.size())));
    perRepeatWall.push_back(median(rec.frameSeconds));
    if (k == 0) r.record = std::move(rec);
    if (r.record.blewUp || cpu > kRepeatBelowSeconds) break;  // nothing to time, or timed enough
  }
  r.secondsPerFrame = median(perRepeat);
  r.wallSecondsPerFrame = median(perRepeatWall);
  r.repeats = static_cast<int>(perRepeat.size());
  const double frameStep = s.frameStep;
  std::printf("  %-11s %-16s E %7.3g  res %3d  sub %4d  %6zu particles  w %d  %s  %9.4f CPU s/sim-s  %8.1f ns/p-step",
              toString(scenario), method.c_str(), r.youngsModulus, resolution, substeps, r.particles, r.halfWidth,
              r.record.blewUp ? "BLEW UP " : "        ", r.secondsPerFrame / frameStep,
              1e9 * r.secondsPerFrame / (double(substeps) * double(r.particles)));
  if (std::isfinite(r.iterations)) std::printf("  %5.1f CG iterations", r.iterations);
  std::printf("\n");
  std::fflush(stdout);
  return r;
}

/// Wall time (s) since `t0`.
inline double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

}  // namespace study
}  // namespace deformable_flsm
