/// @file calibration.h
/// The physical references of the speed/accuracy study's bar (flsm_study: the FEM oracle,
/// Timoshenko, Euler-Bernoulli, uniaxial stress) and the calibration against them of the peers
/// that take no Young's modulus.
#pragma once

#include "study/bar_physics.h"
#include "study/config.h"
#include "study/mass_spring.h"
#include "study/peers.h"
#include "study/scenarios.h"
#include "study/setting.h"
#include "support/fem_oracle.h"

#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

namespace deformable_flsm {
namespace study {

/// Tip deflection / L of the bar for a method at the calibration setting (substeps: the
/// method's own).
inline double calibrationTip(const StudyObject& bar, const std::string& method, int substeps, const Calibration& c) {
  const auto lattice = buildLattice(bar, kCalibrationResolution);
  const Setting s = scenarioSetting(Scenario::Cantilever, bar, kCalibrationResolution, substeps);
  auto m = makeMethod(method, lattice, s, c);
  const RunRecord rec = runScenario(Scenario::Cantilever, bar, *lattice, *m, s.frameStep, 0);
  if (rec.blewUp) return std::numeric_limits<double>::infinity();
  return cantileverProfile(bar, rec.finalPoints).tipDeflection;
}

/// The physical references of the bar (Physics, study/bar_physics.h).
inline Physics physics(const StudyObject& bar) {
  Physics ph;
  const auto t0 = std::chrono::steady_clock::now();
  ph.fem = femProbeDeflections(bar, Scenario::Cantilever, kFemResolution, kFemSubdivision);
  ph.femSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  ph.femCheckTip = femProbeDeflections(bar, Scenario::Cantilever, kFemCheckResolution, kFemSubdivision).back() / kBarLength;
  ph.columnFem = femProbeDeflections(bar, Scenario::Column, kFemResolution, kFemSubdivision);
  ph.columnFemTop = ph.columnFem.back() / kBarLength;
  ph.femTip = ph.fem.back() / kBarLength;
  const double a = kBarLength / kBarAspect, clamp = kBarClampFraction * kBarLength, lf = kBarLength - clamp;
  for (const Eigen::Vector3d& p : bar.probes)
    ph.timoshenko.push_back(analytic::cantileverSelfWeightDeflection(p.x() - clamp, lf, a, a, bar.youngsModulus,
                                                                      kStudyPoissonRatio, kStudyDensity, kBarLoad));
  ph.timoshenkoTip = ph.timoshenko.back() / kBarLength;
  // uniaxial stress: u(x) = rho g (H x - x^2 / 2) / E along a free column of height H
  for (const Eigen::Vector3d& p : bar.probes) {
    const double x = p.x() - clamp;
    ph.columnUniaxial.push_back(kStudyDensity * kColumnLoad * (lf * x - 0.5 * x * x) / bar.youngsModulus);
  }
  ph.columnUniaxialTop = ph.columnUniaxial.back() / kBarLength;
  const double q = kStudyDensity * kBarLoad * a * a, I = a * a * a * a / 12.0;
  ph.eulerBernoulliTip = q * std::pow(lf, 4) / (8.0 * bar.youngsModulus * I) / kBarLength;
  return ph;
}

/// Matches the static stiffness of the peers that take no modulus to physics: the cantilever's
/// tip deflection at the calibration resolution equals the FEM oracle's. Only the peers asked
/// for are calibrated (the others keep their defaults and are not run).
inline Calibration calibrate(const StudyObject& bar, const Physics& ph, bool withMassSpring, bool withBullet) {
  Calibration c;
  c.targetTip = ph.femTip;
  c.fastlsmTip = calibrationTip(bar, "fastlsm", kCalibrationSubsteps, c);
  std::printf("calibration target: FEM oracle tip deflection %.5f L; FastLSM's %.5f L (bar at resolution %d, %d "
              "sub-steps)\n",
              c.targetTip, c.fastlsmTip, kCalibrationResolution, kCalibrationSubsteps);
  const auto lattice = buildLattice(bar, kCalibrationResolution);
  // Mass-spring: deflection ~ 1 / kappa for small deflections, so kappa <- kappa * tip / target
  // converges in a few rounds (the dashpots do not change the rest state).
  c.springRatio = 1.0;
  for (int round = 0; withMassSpring && round < 8; ++round) {
    MassSpringParams p;
    p.springModulus = c.springRatio * bar.youngsModulus;
    c.omegaMax = MassSpringLattice(lattice, p).maxFrequency();
    // dashpots damp the highest mode of the calibration lattice at FastLSM's region damping
    // rate (SolverParams::damping): rate = beta omega_max^2 / 2
    c.dashpotTime = 2.0 * SolverParams().damping / (c.omegaMax * c.omegaMax);
    const int sub = massSpringMinSubsteps(lattice, c, bar.youngsModulus, kAccuracyFrameStep);
    c.massSpringTip = calibrationTip(bar, "mass-spring", sub, c);
    std::printf("  mass-spring kappa / E = %.6g (%d sub-steps): tip %.5f L\n", c.springRatio, sub, c.massSpringTip);
    if (std::abs(c.massSpringTip / c.targetTip - 1.0) < 1e-3) break;
    c.springRatio *= c.massSpringTip / c.targetTip;
  }
#ifdef FLSM_STUDY_WITH_BULLET
  if (withBullet) {
    // Legacy Bullet: deflection falls as kLST grows; bisection on log kLST in
    // [kBulletMinStiffness, 1], then expressed as the ratio that maps E to kLST. Pose matching
    // pulls the bar towards its rigid rest shape whatever kLST is: the softest kLST may still be
    // too stiff, which the calibration reports.
    const Setting s = scenarioSetting(Scenario::Cantilever, bar, kCalibrationResolution, kBulletCalibrationSubsteps);
    Calibration unitCal;
    unitCal.bulletRatio = 1.0;
    const double unit = bulletStiffness(s, lattice->spacing(), unitCal);
    double lo = std::log(kBulletMinStiffness), hi = 0.0;
    c.bulletRatio = std::exp(lo) / unit;
    const double softest = calibrationTip(bar, "bullet", kBulletCalibrationSubsteps, c);
    std::printf("  bullet kLST %.3g: tip %.5f L\n", kBulletMinStiffness, softest);
    if (softest < c.targetTip) {
      c.bulletReached = false;
      c.bulletTip = softest;
      std::printf("  bullet: stiffer than the FEM bar even at kLST = %.3g (pose matching): kept there\n",
                  kBulletMinStiffness);
    } else {
      for (int it = 0; it < 16; ++it) {
        const double mid = 0.5 * (lo + hi);
        c.bulletRatio = std::exp(mid) / unit;
        c.bulletTip = calibrationTip(bar, "bullet", kBulletCalibrationSubsteps, c);
        if (c.bulletTip > c.targetTip) lo = mid;
        else hi = mid;
        if (std::abs(c.bulletTip / c.targetTip - 1.0) < 1e-2) break;
      }
      std::printf("  bullet kLST %.6g (ratio %.6g): tip %.5f L\n", c.bulletRatio * unit, c.bulletRatio, c.bulletTip);
    }
  }
#else
  (void)withBullet;
#endif
  return c;
}

}  // namespace study
}  // namespace deformable_flsm
