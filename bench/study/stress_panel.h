/// @file stress_panel.h
/// The stress panel of the speed/accuracy study (flsm_study): every method on the bunny's
/// stress scenarios (a drag far beyond it, a collapse onto a plane, a scrambled start) at
/// 1/30 s frames.
#pragma once

#include "study/args.h"
#include "study/config.h"
#include "study/peers.h"
#include "study/runs.h"
#include "study/scenarios.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

/// Runs the stress table and returns its runs.
inline std::vector<std::unique_ptr<Run>> runStress(const StudyObject& bunny, const Calibration& calib,
                                                   const Selection& selected) {
  // stress: every method at 1/30 s frames in one sub-step, and the explicit mass-spring also at
  // the fewest sub-steps that its linear stability bound allows (how its users would run it);
  // the implicit step at the bunny's modulus and at stiffer ones (kImplicitStressModuli)
  std::printf("stress (bunny at resolution %d, %.4g s frames):\n", kStressResolution, kStressFrameStep);
  const auto stressStart = std::chrono::steady_clock::now();
  std::vector<std::unique_ptr<Run>> stress;
  const int massSpringStressSubsteps =
      massSpringMinSubsteps(buildLattice(bunny, kStressResolution), calib, bunny.youngsModulus, kStressFrameStep);
  for (const std::string& method : kAllMethods) {
    if (!selected(method) || method == "bullet-fem") continue;  // see kBulletFemSubsteps
    std::vector<int> subsList = {1};
    if (method == "mass-spring") subsList.push_back(massSpringStressSubsteps);
    std::vector<double> moduli = {bunny.youngsModulus};
    if (method == "fastlsm-implicit") moduli.insert(moduli.end(), kImplicitStressModuli.begin(), kImplicitStressModuli.end());
    for (double E : moduli)
      for (int sub : subsList)
        for (Scenario scenario : {Scenario::DragFar, Scenario::Plane, Scenario::Scrambled})
          stress.push_back(
              std::make_unique<Run>(runOnce(scenario, bunny, method, kStressResolution, sub, calib, 1, false, E)));
  }

  std::printf("  (stress: %.0f s)\n", secondsSince(stressStart));
  return stress;
}

}  // namespace study
}  // namespace deformable_flsm
