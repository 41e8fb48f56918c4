/// @file peers.h
/// The methods of the speed/accuracy study (flsm_study) made by name: FastLSM, and the peers
/// with the calibrated stiffness of those that take no Young's modulus (Calibration); and the
/// sub-step counts that FastLSM's cap on alpha and the mass-spring lattice's stability ask for.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "study/config.h"
#include "study/mass_spring.h"
#include "study/method.h"
#include "study/scenarios.h"
#include "study/setting.h"
#ifdef FLSM_STUDY_WITH_BULLET
#include "study/bullet_deformable.h"
#endif

#include <algorithm>
#include <cmath>
#include <memory>
#include <stdexcept>
#include <string>

namespace deformable_flsm {
namespace study {

/// Stiffness and damping of the peers that take no Young's modulus, found by calibrate() so
/// that their cantilever sags as far as the FEM oracle's (physics, not FastLSM). Both get the
/// setting's Young's modulus E through a dimensionless constant, so that they follow the material
/// across objects, resolutions and steps as FastLSM does:
///  - mass-spring: kappa = springRatio E (a spring lattice's modulus is proportional to kappa);
///  - legacy Bullet: kLST = bulletRatio E h^2 / (rho dx^2), capped at 1. A position iteration
///    removes the fraction kLST of a link's error, i.e. pulls with acceleration ~ kLST err / h^2,
///    a spring of stiffness ~ kLST m / h^2 and a modulus ~ kLST rho dx^2 / h^2: the same scaling
///    as FastLSM's alpha.
/// Bullet's deformable body and the FEM oracle take E and nu as they are.
struct Calibration {
  double targetTip = 0.0;     // FEM oracle tip deflection / L (the physics the peers are matched to)
  double fastlsmTip = 0.0;    // FastLSM tip deflection / L at the calibration setting
  double springRatio = 0.0;   // kappa / E
  double dashpotTime = 0.0;   // beta (s)
  double massSpringTip = 0.0;
  double omegaMax = 0.0;      // rad/s, calibration lattice
  double bulletRatio = 0.0;   // kLST rho dx^2 / (E h^2)
  double bulletTip = 0.0;
  bool bulletReached = true;  // false when even the softest kLST leaves the bar stiffer
};

inline MassSpringParams massSpringParams(const Setting& s, const Calibration& c) {
  MassSpringParams p;
  p.springModulus = c.springRatio * s.youngsModulus;
  p.dashpotTime = c.dashpotTime;
  p.ambientDamping = s.ambientDamping;
  p.gravity = s.gravity;
  p.timeStep = s.frameStep;
  p.substeps = s.substeps;
  return p;
}

#ifdef FLSM_STUDY_WITH_BULLET
inline double bulletStiffness(const Setting& s, double spacing, const Calibration& c) {
  const double h = s.substep();
  return std::min(1.0, c.bulletRatio * s.youngsModulus * h * h / (kStudyDensity * spacing * spacing));
}

/// Bulk modulus K = E / (3 (1 - 2 nu)) (Pa).
inline double bulkModulus(const Setting& s) { return s.youngsModulus / (3.0 * (1.0 - 2.0 * s.poissonRatio)); }

/// The legacy soft body as its users set up a volumetric jelly: links at the calibrated kLST,
/// pose matching kMT = kBulletPoseMatching per 1/60 s (the same pull per second at every
/// sub-step count: kMT_h = 1 - (1 - kMT)^(60 h)), volume conservation with the material's bulk
/// modulus times kBulletVolumeFraction, kBulletIterations position iterations.
inline BulletVolumeParams bulletParams(const Setting& s, double spacing, const Calibration& c) {
  BulletVolumeParams p;
  p.linearStiffness = std::max(kBulletMinStiffness, bulletStiffness(s, spacing, c));
  p.poseMatching = 1.0 - std::pow(1.0 - kBulletPoseMatching, s.substep() / kBulletPoseMatchingStep);
  p.bulkModulus = kBulletVolumeFraction * bulkModulus(s);
  p.positionIterations = kBulletIterations;
  p.ambientDamping = s.ambientDamping;
  p.gravity = s.gravity;
  p.timeStep = s.frameStep;
  p.substeps = s.substeps;
  return p;
}

inline BulletDeformableParams bulletFemParams(const Setting& s, const Calibration& c) {
  BulletDeformableParams p;
  p.youngsModulus = s.youngsModulus;
  p.poissonRatio = s.poissonRatio;
  p.stiffnessDamping = c.dashpotTime;  // the mass-spring's dashpot time: the same damping of the stiff modes
  p.ambientDamping = s.ambientDamping;
  p.gravity = s.gravity;
  p.timeStep = s.frameStep;
  p.substeps = s.substeps;
  return p;
}
#endif

inline std::unique_ptr<Method> makeMethod(const std::string& name, const std::shared_ptr<const Lattice>& lattice,
                                          const Setting& s, const Calibration& c) {
  if (name == "fastlsm") return std::make_unique<FlsmMethod>(lattice, flsmParams(s, lattice->regionHalfWidth(), SolverKind::Fast));
  if (name == "fastlsm-implicit")
    return std::make_unique<FlsmMethod>(lattice,
                                        flsmParams(s, lattice->regionHalfWidth(), SolverKind::Fast, Integrator::Implicit));
  if (name == "fastlsm-nu0") {  // the stress table's FastLSM without the Poisson term
    Setting s0 = s;
    s0.poissonRatio = 0.0;
    return std::make_unique<FlsmMethod>(lattice, flsmParams(s0, lattice->regionHalfWidth(), SolverKind::Fast));
  }
  if (name == "naive-lsm")
    return std::make_unique<FlsmMethod>(lattice, flsmParams(s, lattice->regionHalfWidth(), SolverKind::Naive));
  if (name == "mass-spring") return std::make_unique<MassSpringMethod>(lattice, massSpringParams(s, c));
#ifdef FLSM_STUDY_WITH_BULLET
  if (name == "bullet") return std::make_unique<BulletVolumeMethod>(lattice, bulletParams(s, lattice->spacing(), c));
  if (name == "bullet-fem") return std::make_unique<BulletDeformableMethod>(lattice, bulletFemParams(s, c));
#endif
  throw std::invalid_argument("unknown method " + name);
}

/// Does FastLSM cap alpha (simulate a softer material than asked) on this lattice in this
/// setting; for this scenario, object, resolution and sub-step count?
inline bool flsmCapped(const std::shared_ptr<const Lattice>& lattice, const Setting& setting, const Calibration& calib) {
  const auto m = makeMethod("fastlsm", lattice, setting, calib);
  return dynamic_cast<const FlsmMethod&>(*m).solver().stiffnessSaturated();
}
inline bool flsmCapped(Scenario scenario, const StudyObject& object, int resolution, int substeps, const Calibration& calib) {
  return flsmCapped(buildLattice(object, resolution), scenarioSetting(scenario, object, resolution, substeps), calib);
}

/// Fewest stable mass-spring sub-steps per frame on `lattice` for a material of Young's modulus
/// E (Pa): a power of two.
inline int massSpringMinSubsteps(const std::shared_ptr<const Lattice>& lattice, const Calibration& c, double E,
                                 double frameStep) {
  MassSpringParams p;
  p.springModulus = c.springRatio * E;
  const double omega = MassSpringLattice(lattice, p).maxFrequency();
  int s = 1;
  while (frameStep / s * omega > kMassSpringStepMargin) s *= 2;
  return s;
}

}  // namespace study
}  // namespace deformable_flsm
