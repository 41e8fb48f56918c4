/// @file accuracy_panel.h
/// The accuracy panel of the speed/accuracy study (flsm_study): every method on the cantilever,
/// the column and the ear drag at each resolution and sub-step count of its grid, each run
/// measured against its reference run and (on the bar) against physics.
#pragma once

#include "study/args.h"
#include "study/bar_physics.h"
#include "study/config.h"
#include "study/metrics.h"
#include "study/peers.h"
#include "study/runs.h"
#include "study/scenarios.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

struct Row {
  const Run* run = nullptr;
  double errorRef = std::numeric_limits<double>::quiet_NaN();
  double ebRms = std::numeric_limits<double>::quiet_NaN();
  double tip = std::numeric_limits<double>::quiet_NaN();
  double diffVsFast = std::numeric_limits<double>::quiet_NaN();
  PhysicalError vsFem, vsAnalytic;
};

/// RMS distance / size between two runs' samples: the final points for the cantilever, the
/// whole sampled trajectory for the ear drag.
inline double errorAgainst(const Run& run, const Run& ref, double size) {
  if (run.record.blewUp || ref.record.blewUp) return std::numeric_limits<double>::infinity();
  if (run.scenario == Scenario::Cantilever) return rmsDistance(run.record.finalPoints, ref.record.finalPoints) / size;
  const auto& a = run.record.trajectory;
  const auto& b = ref.record.trajectory;
  const std::size_t n = std::min(a.size(), b.size());
  double e = 0.0;
  std::size_t count = 0;
  for (std::size_t k = 0; k < n; ++k)
    for (std::size_t i = 0; i < a[k].size(); ++i, ++count) e += (a[k][i] - b[k][i]).squaredNorm();
  return count ? std::sqrt(e / double(count)) / size : std::numeric_limits<double>::quiet_NaN();
}

/// Resolutions and sub-steps of the accuracy runs and of their reference runs.
struct Grid {
  std::vector<int> barRes;
  int barRef = 0;
  std::vector<int> bunnyRes;
  int bunnyRef = 0;
  std::vector<int> subs;
  int refSubs = 0;
  std::vector<int> columnRes;
};

/// The study's grid, or with --quick a small one that checks the pipeline.
inline Grid studyGrid(bool quick) {
  Grid g;
  g.barRes = quick ? std::vector<int>{20} : kBarResolutions;
  g.barRef = quick ? 40 : kBarReferenceResolution;
  g.bunnyRes = quick ? std::vector<int>{12} : kBunnyResolutions;
  g.bunnyRef = quick ? 24 : kBunnyReferenceResolution;
  g.subs = quick ? std::vector<int>{1, 4} : kSubsteps;
  g.refSubs = quick ? 8 : kReferenceSubsteps;
  g.columnRes = quick ? std::vector<int>{20} : kColumnResolutions;
  return g;
}

/// The accuracy runs (each owned here) and their rows (each pointing to its run).
struct AccuracyRuns {
  std::vector<std::unique_ptr<Run>> runs;
  std::vector<Row> rows;
};

/// What the accuracy runs of one scenario share.
struct ScenarioContext {
  Scenario scenario;
  const StudyObject& object;
  const std::vector<int>& resolutions;
  int refRes;
  const Grid& grid;
  const Args& args;
  const Calibration& calib;
};

/// FastLSM's runs of a scenario, which naive LSM and the implicit step are compared with: by
/// "resolution/sub-steps", and its reference run.
struct FastRuns {
  std::map<std::string, const Run*> fastBySetting;
  const Run* fastRef = nullptr;
};

/// The method's own sub-step lists at each resolution.
inline std::vector<int> substepsAt(const std::string& method, const ScenarioContext& ctx, int res) {
  const Args& args = ctx.args;
  const std::vector<int>& resolutions = ctx.resolutions;
  if (method == "bullet-fem") {
    const std::size_t k = static_cast<std::size_t>(
        std::find(resolutions.begin(), resolutions.end(), res) - resolutions.begin());
    if (args.quick) return std::vector<int>{1};
    return k < kBulletFemSubsteps.size() ? kBulletFemSubsteps[k] : std::vector<int>{};
  }
  if ((method == "fastlsm" || method == "naive-lsm") && !args.quick) {
    std::vector<int> out = ctx.grid.subs;
    while (out.back() < kMaxFlsmSubsteps && flsmCapped(ctx.scenario, ctx.object, res, out.back(), ctx.calib))
      out.push_back(2 * out.back());
    return out;
  }
  if (method == "fastlsm-implicit") return args.quick ? std::vector<int>{1} : kImplicitSubsteps;
  if (method != "mass-spring") return ctx.grid.subs;
  const int smin = massSpringMinSubsteps(buildLattice(ctx.object, res), ctx.calib, ctx.object.youngsModulus, kAccuracyFrameStep);
  std::vector<int> out;
  for (int f : kMassSpringSubstepFactors) out.push_back(smin * f);
  return out;
}

/// The run `method`'s runs are measured against (nullptr: none): FastLSM's reference for naive
/// LSM and the implicit step, else the method's own reference run, run here (and given a row
/// unless `refOnly`), except for Bullet's deformable body and the column (physics only).
inline const Run* referenceRun(const std::string& method, const ScenarioContext& ctx, bool refOnly, FastRuns& fast,
                               AccuracyRuns& out) {
  const Run* ref = nullptr;
  if (method == "naive-lsm") {
    ref = fast.fastRef;  // same algorithm as FastLSM (sums in another order): same reference
  } else if (method == "fastlsm-implicit") {
    // the same model (regions, material, damping) in time steps that tend to zero: both
    // integrators converge to FastLSM's converged run
    ref = fast.fastRef;
  } else if (method != "bullet-fem" && ctx.scenario != Scenario::Column) {  // the column: physics only
    int rs = method == "mass-spring"
                 ? massSpringMinSubsteps(buildLattice(ctx.object, ctx.refRes), ctx.calib, ctx.object.youngsModulus,
                                         kAccuracyFrameStep) *
                       kMassSpringReferenceFactor
                 : ctx.grid.refSubs;
    if (method == "fastlsm" && !ctx.args.quick)
      while (rs < kMaxReferenceSubsteps && flsmCapped(ctx.scenario, ctx.object, ctx.refRes, rs, ctx.calib)) rs *= 2;
    out.runs.push_back(std::make_unique<Run>(runOnce(ctx.scenario, ctx.object, method, ctx.refRes, rs, ctx.calib, 1, true)));
    ref = out.runs.back().get();
    if (!refOnly) {
      out.rows.emplace_back();
      out.rows.back().run = ref;
    }
    if (method == "fastlsm") fast.fastRef = ref;
  }
  return ref;
}

/// Runs `method` at every resolution and sub-step count of the scenario, one row each, measured
/// against `ref` (and naive LSM against FastLSM at the same setting).
inline void settingRuns(const std::string& method, const ScenarioContext& ctx, const Run* ref, FastRuns& fast,
                        AccuracyRuns& out) {
  const StudyObject& object = ctx.object;
  const std::vector<int>& runResolutions =
      method == "fastlsm-implicit" && ctx.scenario == Scenario::Cantilever && !ctx.args.quick ? kImplicitBarResolutions
                                                                                             : ctx.resolutions;
  for (int res : runResolutions) {
    if (method == "naive-lsm" && buildLattice(object, res)->regionHalfWidth() > kNaiveMaxHalfWidth)
      continue;
    for (int sub : substepsAt(method, ctx, res)) {
      out.runs.push_back(
          std::make_unique<Run>(runOnce(ctx.scenario, object, method, res, sub, ctx.calib, ctx.args.repeats, false)));
      const Run& run = *out.runs.back();
      Row row;
      row.run = &run;
      if (ref) row.errorRef = errorAgainst(run, *ref, object.size);
      const std::string key = std::to_string(res) + "/" + std::to_string(sub);
      if (method == "fastlsm") fast.fastBySetting[key] = &run;
      if (method == "naive-lsm" && fast.fastBySetting.count(key))
        row.diffVsFast = errorAgainst(run, *fast.fastBySetting[key], object.size);
      out.rows.push_back(row);
    }
  }
}

/// Runs the accuracy grid of one scenario (the cantilever, the column or the ear drag) with
/// every method, adding its runs and rows to `out`.
inline void runAccuracyScenario(Scenario scenario, const StudyObject& bar, const StudyObject& bunny, const Grid& grid,
                                const std::vector<std::string>& methods, const Selection& selected, const Args& args,
                                const Calibration& calib, AccuracyRuns& out) {
  const bool onBar = scenario != Scenario::EarDrag;
  const StudyObject& object = onBar ? bar : bunny;
  const std::vector<int>& resolutions =
      scenario == Scenario::Cantilever ? grid.barRes : (scenario == Scenario::Column ? grid.columnRes : grid.bunnyRes);
  const int refRes = onBar ? grid.barRef : grid.bunnyRef;
  std::printf("%s:\n", toString(scenario));
  const auto scenarioStart = std::chrono::steady_clock::now();
  FastRuns fast;
  // naive LSM and the implicit step are measured against FastLSM's reference run: without
  // FastLSM among the methods, that run alone (its row is kept from the existing file)
  std::vector<std::string> scenarioMethods = methods;
  const bool fastRefOnly = !selected("fastlsm") && (selected("naive-lsm") || selected("fastlsm-implicit"));
  if (fastRefOnly && scenario != Scenario::Column) scenarioMethods.insert(scenarioMethods.begin(), "fastlsm");
  const ScenarioContext ctx{scenario, object, resolutions, refRes, grid, args, calib};
  for (const std::string& method : scenarioMethods) {
    if (method == "bullet-fem" && !onBar) continue;
    const bool refOnly = method == "fastlsm" && fastRefOnly;
    const Run* ref = referenceRun(method, ctx, refOnly, fast, out);
    if (refOnly) continue;
    settingRuns(method, ctx, ref, fast, out);
  }
  std::printf("  (%s: %.0f s)\n", toString(scenario), secondsSince(scenarioStart));
}

/// Fills the rows of the bar scenarios' runs with their errors against physics (FEM oracle,
/// Timoshenko or uniaxial stress) and the cantilever's profile.
inline void addPhysicalErrors(std::vector<Row>& rows, const StudyObject& bar, const Physics& ph) {
  for (Row& row : rows) {
    const Scenario sc = row.run->scenario;
    if (row.run->record.blewUp) continue;
    if (sc == Scenario::Cantilever) {
      const CantileverProfile p = cantileverProfile(bar, row.run->record.finalPoints);
      row.tip = p.tipDeflection;
      row.ebRms = p.eulerBernoulliRms;
      row.vsFem = physicalError(bar, sc, row.run->record.finalPoints, ph.fem);
      row.vsAnalytic = physicalError(bar, sc, row.run->record.finalPoints, ph.timoshenko);
    } else if (sc == Scenario::Column) {
      row.vsFem = physicalError(bar, sc, row.run->record.finalPoints, ph.columnFem);
      row.vsAnalytic = physicalError(bar, sc, row.run->record.finalPoints, ph.columnUniaxial);
    }
  }
}

}  // namespace study
}  // namespace deformable_flsm
