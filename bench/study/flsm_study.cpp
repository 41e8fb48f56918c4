// Speed against accuracy: runs the study's scenarios headless with FastLSM (explicit and implicit
// step), naive LSM, an explicit mass-spring lattice and (when built with Bullet) Bullet's implicit
// deformable body
// (btDeformableBody: tetrahedra, corotated linear elasticity, E and nu) and Bullet's legacy soft
// body (links, pose matching, volume conservation), and writes
//   <out>/calibration.csv  the physical references (FEM oracle on the bar's voxels, Timoshenko,
//                          Euler-Bernoulli) and the stiffness of the peers that take no modulus
//                          (mass-spring, legacy Bullet), matched to the FEM cantilever
//   <out>/accuracy.csv     one row per run: error against physics (FEM, Timoshenko) and against
//                          the method's own converged run, rest-shape recovery, volume, cost
//   <out>/stability.csv    one row per method and stress scenario (1/30 s frames)
// A benchmark, not a test: it prints figures and never fails because the machine is slow.
//
//   flsm_study [--out DIR] [--mesh PATH] [--repeats N] [--quick] [--no-bullet] [--methods LIST]
//
// --quick runs a small grid (coarse resolutions, few sub-steps) to check the pipeline; --repeats
// (default 3) repeats every run that took under 2 s and reports the median time. Cost is the CPU
// time of the thread that steps (every method runs on one thread), not wall time: on a machine
// shared with other jobs it leaves out the time the thread waited for a core. --methods
// (comma-separated names of kAllMethods) runs only those methods and replaces only their rows in
// the existing accuracy.csv and stability.csv (the other methods' rows and calibration.csv are
// kept): after a change to one method, its figures are regenerated without the others' runs.
// Definitions of every figure: docs/study.md.

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/voxelizer.h"
#include "study/bar_physics.h"
#include "study/csv.h"
#include "study/indentation.h"
#include "study/mass_spring.h"
#include "study/method.h"
#include "study/metrics.h"
#include "study/scenarios.h"
#include "study/setting.h"
#include "support/fem_oracle.h"
#ifdef FLSM_STUDY_WITH_BULLET
#include "study/bullet_deformable.h"
#endif

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <limits>
#include <map>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::study;

namespace {

// --- configuration of the study ---------------------------------------------------------------

/// Cantilever bar length (m); section L / 10.
constexpr double kBarLength = 1.0;

/// Resolutions of the accuracy runs and of the reference (finest) run. Multiples of the coarsest
/// resolution, so that the region radius is a whole number of cells at every one of them.
const std::vector<int> kBarResolutions = {20, 40, 60};
/// Resolutions of the column (physics only, no reference run).
const std::vector<int> kColumnResolutions = {20, 40};
constexpr int kBarReferenceResolution = 80;
const std::vector<int> kBunnyResolutions = {12, 24};
constexpr int kBunnyReferenceResolution = 36;
/// Bunny resolution of the stress scenarios.
constexpr int kStressResolution = 24;

/// Sub-steps per 1/60 s frame of FastLSM and Bullet, and of their reference runs.
const std::vector<int> kSubsteps = {1, 2, 4, 8};
constexpr int kReferenceSubsteps = 16;
/// FastLSM (and naive LSM) also run at twice the sub-steps, up to this many, while the last
/// count still capped alpha (the node names the sub-steps that would not): where its users
/// would run it for the asked material. The reference run takes the fewest powers of two from
/// kReferenceSubsteps on that leave alpha uncapped, up to kMaxReferenceSubsteps.
constexpr int kMaxFlsmSubsteps = 64;
/// FastLSM's implicit step: sub-steps per frame at every resolution of the explicit runs. No
/// bound on the modulus comes from its sub-step, so its users run it at the frame rate; two
/// sub-steps show what halving its numerical damping buys.
const std::vector<int> kImplicitSubsteps = {1, 2};
/// Resolutions of the implicit step's cantilever: kBarResolutions and the explicit step's
/// reference resolution, where the implicit step at the frame rate costs about what the explicit
/// one pays at 60 cells, at the accurate end of the chart where Bullet's deformable body stands.
const std::vector<int> kImplicitBarResolutions = {20, 40, 60, 80};
/// Stress table: Young's moduli (Pa) of the implicit step's runs beside the study's bunny
/// (kBunnyYoungsModulus), from a soft material to a stiff rubber, which the explicit step at one
/// sub-step could only simulate with alpha capped.
const std::vector<double> kImplicitStressModuli = {3e4, 1e6, 1e7};
constexpr int kMaxReferenceSubsteps = 128;
/// Naive LSM: the region sums cost O(w^3) per particle; the study runs it where w <= this.
constexpr int kNaiveMaxHalfWidth = 2;
/// Mass-spring: sub-steps are multiples of the fewest that are stable, s_min = the smallest
/// power of two with h omega_max <= kMassSpringStepMargin (symplectic Euler is stable below 2).
constexpr double kMassSpringStepMargin = 1.5;
const std::vector<int> kMassSpringSubstepFactors = {1, 2};
constexpr int kMassSpringReferenceFactor = 4;
/// Legacy Bullet: position iterations per sub-step; pose matching kMT per kBulletPoseMatchingStep
/// (Bullet's soft-body demos use kMT = 0.05 at 60 Hz); the softest kLST the calibration tries.
constexpr int kBulletIterations = 4;
constexpr double kBulletPoseMatching = 0.05;
constexpr double kBulletPoseMatchingStep = 1.0 / 60.0;
constexpr double kBulletMinStiffness = 1e-6;
/// Legacy Bullet's volume conservation pulls with this fraction of the material's bulk modulus:
/// its pressure is an explicit force, and the full bulk modulus blows the bunny up within three
/// frames at 1/60 s (a tenth of it within seven); users turn kVC down until the body is stable.
constexpr double kBulletVolumeFraction = 0.005;
/// Legacy Bullet's calibration runs at this many sub-steps (its cost per run is highest).
constexpr int kBulletCalibrationSubsteps = 4;
/// Bullet's deformable body (implicit): sub-steps per frame at each resolution of the bar runs
/// (index as kBarResolutions; none at the finer ones: ~10 s per simulated second at 60 cells). Its users run it at the frame rate; a
/// few sub-steps show what shorter steps buy. No reference run: its cost at the reference
/// resolution is beyond the study's budget, and physics is the reference that counts. It runs
/// the bar scenarios only: on the bunny its conjugate gradients cost ~10 s per simulated second at
/// resolution 12, beyond the study's budget for the ear drag and the stress scenarios.
const std::vector<std::vector<int>> kBulletFemSubsteps = {{1, 2, 4}, {1}};
/// FEM oracle: the bar's voxels at this resolution, each cell split into kFemSubdivision^3
/// linear hexahedra (8 elements across the section); and a coarser one (4 across) to show how
/// far the reference is from converged (trilinear elements are stiff in bending).
constexpr int kFemResolution = 40;
constexpr int kFemSubdivision = 2;
constexpr int kFemCheckResolution = 20;

/// Calibration setting: the bar at this resolution, FastLSM at the reference sub-steps, where
/// alpha is below its cap and the bar has the modulus it is given.
constexpr int kCalibrationResolution = 40;
constexpr int kCalibrationSubsteps = kReferenceSubsteps;
/// Runs whose first repetition took less CPU time than this (s) are repeated (--repeats):
/// cheap runs are the ones that other processes on the machine disturb most.
constexpr double kRepeatBelowSeconds = 2.0;
/// Trajectory samples of the ear drag: every this many frames (10 Hz).
constexpr int kSampleEvery = 6;

/// Every method of the study, in the order of its files and tables. "fastlsm-nu0" runs in the
/// stress table only.
const std::vector<std::string> kAllMethods = {"fastlsm",     "fastlsm-implicit", "fastlsm-nu0", "naive-lsm",
                                              "mass-spring", "bullet",           "bullet-fem"};

struct Args {
  std::string out = "docs/study";
  std::string mesh = deformable_flsm::kBunnyMeshPath;
  int repeats = 3;
  bool quick = false;
  bool bullet = true;
  /// methods to run (--methods); empty: all
  std::vector<std::string> methods;
  /// only the indentation case (--indentation)
  bool indentationOnly = false;
};

/// The names of a comma-separated list, each checked against kAllMethods.
std::vector<std::string> parseMethods(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  std::string name;
  while (std::getline(in, name, ',')) {
    if (std::find(kAllMethods.begin(), kAllMethods.end(), name) == kAllMethods.end()) {
      std::string known;
      for (const auto& m : kAllMethods) known += " " + m;
      std::fprintf(stderr, "flsm_study: unknown method '%s' in --methods (known:%s)\n", name.c_str(), known.c_str());
      std::exit(2);
    }
    out.push_back(name);
  }
  if (out.empty()) {
    std::fprintf(stderr, "flsm_study: --methods needs at least one method name\n");
    std::exit(2);
  }
  return out;
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "flsm_study: %s needs a value\n", k.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (k == "--out") a.out = value();
    else if (k == "--mesh") a.mesh = value();
    else if (k == "--repeats") a.repeats = std::max(1, std::atoi(value().c_str()));
    else if (k == "--quick") a.quick = true;
    else if (k == "--no-bullet") a.bullet = false;
    else if (k == "--methods") a.methods = parseMethods(value());
    else if (k == "--indentation") a.indentationOnly = true;
    else {
      std::fprintf(stderr, "flsm_study: unknown option %s\n"
                           "usage: flsm_study [--out DIR] [--mesh PATH] [--repeats N] [--quick] [--no-bullet] "
                           "[--methods LIST] [--indentation]\n",
                   k.c_str());
      std::exit(2);
    }
  }
  return a;
}

// --- methods ---------------------------------------------------------------------------------

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

MassSpringParams massSpringParams(const Setting& s, const Calibration& c) {
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
double bulletStiffness(const Setting& s, double spacing, const Calibration& c) {
  const double h = s.substep();
  return std::min(1.0, c.bulletRatio * s.youngsModulus * h * h / (kStudyDensity * spacing * spacing));
}

/// Bulk modulus K = E / (3 (1 - 2 nu)) (Pa).
double bulkModulus(const Setting& s) { return s.youngsModulus / (3.0 * (1.0 - 2.0 * s.poissonRatio)); }

/// The legacy soft body as its users set up a volumetric jelly: links at the calibrated kLST,
/// pose matching kMT = kBulletPoseMatching per 1/60 s (the same pull per second at every
/// sub-step count: kMT_h = 1 - (1 - kMT)^(60 h)), volume conservation with the material's bulk
/// modulus times kBulletVolumeFraction, kBulletIterations position iterations.
BulletVolumeParams bulletParams(const Setting& s, double spacing, const Calibration& c) {
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

BulletDeformableParams bulletFemParams(const Setting& s, const Calibration& c) {
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

std::unique_ptr<Method> makeMethod(const std::string& name, const std::shared_ptr<const Lattice>& lattice,
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
bool flsmCapped(const std::shared_ptr<const Lattice>& lattice, const Setting& setting, const Calibration& calib) {
  const auto m = makeMethod("fastlsm", lattice, setting, calib);
  return dynamic_cast<const FlsmMethod&>(*m).solver().stiffnessSaturated();
}
bool flsmCapped(Scenario scenario, const StudyObject& object, int resolution, int substeps, const Calibration& calib) {
  return flsmCapped(buildLattice(object, resolution), scenarioSetting(scenario, object, resolution, substeps), calib);
}

/// Fewest stable mass-spring sub-steps per frame on `lattice` for a material of Young's modulus
/// E (Pa): a power of two.
int massSpringMinSubsteps(const std::shared_ptr<const Lattice>& lattice, const Calibration& c, double E,
                          double frameStep) {
  MassSpringParams p;
  p.springModulus = c.springRatio * E;
  const double omega = MassSpringLattice(lattice, p).maxFrequency();
  int s = 1;
  while (frameStep / s * omega > kMassSpringStepMargin) s *= 2;
  return s;
}

// --- runs ------------------------------------------------------------------------------------

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
Run runOnce(Scenario scenario, const StudyObject& object, const std::string& method, int resolution, int substeps,
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

/// Tip deflection / L of the bar for a method at the calibration setting (substeps: the
/// method's own).
double calibrationTip(const StudyObject& bar, const std::string& method, int substeps, const Calibration& c) {
  const auto lattice = buildLattice(bar, kCalibrationResolution);
  const Setting s = scenarioSetting(Scenario::Cantilever, bar, kCalibrationResolution, substeps);
  auto m = makeMethod(method, lattice, s, c);
  const RunRecord rec = runScenario(Scenario::Cantilever, bar, *lattice, *m, s.frameStep, 0);
  if (rec.blewUp) return std::numeric_limits<double>::infinity();
  return cantileverProfile(bar, rec.finalPoints).tipDeflection;
}

// --- physics -------------------------------------------------------------------------------

/// The physical references of the bar (Physics, study/bar_physics.h).
Physics physics(const StudyObject& bar) {
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
Calibration calibrate(const StudyObject& bar, const Physics& ph, bool withMassSpring, bool withBullet) {
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

// --- output ----------------------------------------------------------------------------------

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
double errorAgainst(const Run& run, const Run& ref, double size) {
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

/// Wall time (s) since `t0`.
double secondsSince(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// The columns of accuracy.csv and stability.csv (docs/study.md defines them).
const std::string kAccuracyHeader =
    "scenario,method,resolution,substeps,reference,particles,half_width,substep_s,blew_up,error_ref,eb_rms,"
    "tip_deflection,shape_error,volume_change,peak_kinetic_energy_J,cpu_s_per_sim_s,ns_per_particle_step,repeats,"
    "diff_vs_fast,alpha,saturated,tip_vs_fem,profile_vs_fem,tip_vs_analytic,profile_vs_analytic,cg_iterations,"
    "wall_s_per_sim_s";
const std::string kStabilityHeader =
    "scenario,method,resolution,particles,frame_step_s,substeps,outcome,blow_up_time_s,shape_error,"
    "recovered_after_s,peak_kinetic_energy_J,volume_change_held,volume_change_final,youngs_modulus_Pa,cg_iterations";

// --- indentation ---------------------------------------------------------------------------

const std::string kIndentationHeader =
    "scenario,method,resolution,substeps,particles,punch_cells,nu,force_N,oracle_N,force_vs_fem,blew_up,cpu_s_per_sim_s,"
    "ns_per_particle_step";
/// Block resolutions (cells along a side) of the indentation case.
const std::vector<int> kBlockResolutions = {9, 13, 17};

/// The sub-steps per 1/60 s frame each method runs the punch at: FastLSM's explicit step at the
/// fewest that leave alpha uncapped (a power of two) and twice that; the mass-spring lattice at
/// its fewest stable and four times that; the implicit steps at 1 and 4.
std::vector<int> punchSubsteps(const std::string& method, const Block& b, const Calibration& c, double nu) {
  if (method == "fastlsm") {
    int s = 1;
    while (s < 1024 && flsmCapped(b.lattice, punchSetting(b.voxels.dims.x(), s, nu), c)) s *= 2;
    return {s, 2 * s};
  }
  if (method == "mass-spring") {
    const int s = massSpringMinSubsteps(b.lattice, c, kBlockYoungsModulus, kPunchFrameStep);
    return {s, 4 * s};
  }
  return {1, 4};
}

/// Runs the indentation case with every selected method (not naive LSM, which gives FastLSM's
/// answer at a higher cost, nor the stress table's nu = 0 run, nor the legacy soft body, which
/// has no force to read) and writes <out>/indentation.csv
/// (with --methods, the other methods' rows kept). Returns false after printing why it could not.
template <typename Selected>
bool runIndentation(const Args& args, const Calibration& calib, const Selected& selected, bool subset) {
  const double nu = kStudyPoissonRatio;
  const std::vector<int> resolutions = args.quick ? std::vector<int>{9} : kBlockResolutions;
  std::printf("indentation: a bonded punch %.0f %% of the side pressed %.1f mm into a %.0f cm cube at E %.3g Pa, "
              "nu %.1f, against the FEM oracle on the same voxels\n",
              100 * kPunchWidthFraction, 1e3 * kPunchDepth, 100 * kBlockSize, kBlockYoungsModulus, nu);
  std::vector<std::string> lines;
  for (int n : resolutions) {
    const Block b = makeBlock(n);
    const double oracle = oraclePunchForce(b, kBlockYoungsModulus, nu);
    for (const std::string& method : kAllMethods) {
      if (method == "naive-lsm" || method == "fastlsm-nu0" || !selected(method)) continue;
      if (method == "bullet") {  // BulletVolumeMethod::grabForce()
        if (n == resolutions.front()) std::printf("  bullet: no force to read (position-based links): not in the panel\n");
        continue;
      }
      for (int sub : punchSubsteps(method, b, calib, nu)) {
        const auto m = makeMethod(method, b.lattice, punchSetting(n, sub, nu), calib);
        const PunchRecord r = runPunch(b, *m);
        const double ratio = r.force / oracle;
        std::printf("  %-17s res %3d sub %4d  %5zu particles  force %.4f N, oracle %.4f N: %+6.1f %%  %9.4f CPU s/sim-s\n",
                    method.c_str(), n, sub, b.lattice->size(), r.force, oracle, 100 * (ratio - 1), r.cpuPerSimSecond);
        std::ostringstream f;
        f << "punch," << method << ',' << n << ',' << sub << ',' << b.lattice->size() << ',' << b.punchCells << ',' << num(nu) << ','
          << num(r.force) << ',' << num(oracle) << ',' << num(ratio) << ',' << (r.blewUp ? 1 : 0) << ','
          << num(r.cpuPerSimSecond) << ','
          << num(1e9 * r.cpuPerSimSecond * kPunchFrameStep / (double(sub) * double(b.lattice->size())));
        lines.push_back(f.str());
      }
    }
  }
  return writeCsv(args.out + "/indentation.csv", kIndentationHeader, std::move(lines), subset, selected, kAllMethods,
                  CsvOrder::Method);
}

// --- stages of main ---------------------------------------------------------------------------

/// The methods of this run: all (the Bullet peers when built in), or those of --methods.
struct Selection {
  const Args& args;
  bool withBullet;
  bool subset;
  bool operator()(const std::string& m) const {
    if ((m == "bullet" || m == "bullet-fem") && !withBullet) return false;
    return !subset || std::find(args.methods.begin(), args.methods.end(), m) != args.methods.end();
  }
};

/// Prints the first lines of the log: the objects, how cost is measured, whether Bullet runs.
void printIntro(const Args& args, const StudyObject& bar, const StudyObject& bunny, bool withBullet) {
  const std::string meshName = args.mesh.substr(args.mesh.find_last_of('/') + 1);  // no machine paths in the log
  std::printf("flsm_study: bar %.3g x %.3g x %.3g m (%zu render vertices); bunny %s x %.2g, size %.4f m (%zu vertices, "
              "%zu sampled)\n",
              kBarLength, kBarLength / kBarAspect, kBarLength / kBarAspect, bar.mesh.vertices.size(), meshName.c_str(),
              kStudyBunnyScale, bunny.size, bunny.mesh.vertices.size(), bunny.sampleVertices.size());
  std::printf("single thread; cost = CPU time of the stepping thread per frame, the mean over the frames of a run%s\n",
              args.repeats > 1 ? ", then the median over up to --repeats runs (runs under 2 s)" : "");
  if (!withBullet) std::printf("Bullet's soft body: not built in (no Bullet found, or --no-bullet)\n");
}

/// Prints the physical references: the FEM oracle's, Timoshenko's and Euler-Bernoulli's tips,
/// and the column's shortening.
void printPhysics(const Physics& ph) {
  std::printf("physics: FEM oracle (resolution %d, %d^3 elements per cell, %.1f s) tip %.5f L, at resolution %d "
              "%.5f L; Timoshenko %.5f L; Euler-Bernoulli %.5f L\n",
              kFemResolution, kFemSubdivision, ph.femSeconds, ph.femTip, kFemCheckResolution, ph.femCheckTip,
              ph.timoshenkoTip, ph.eulerBernoulliTip);
  std::printf("physics: column shortening, FEM oracle %.5f L; uniaxial stress (nu = 0) %.5f L\n", ph.columnFemTop,
              ph.columnUniaxialTop);
}

/// The selected methods of the accuracy runs (all but the stress table's "fastlsm-nu0").
std::vector<std::string> accuracyMethods(const Selection& selected) {
  std::vector<std::string> methods;  // of the accuracy runs
  for (const std::string& m : kAllMethods)
    if (m != "fastlsm-nu0" && selected(m)) methods.push_back(m);
  return methods;
}

/// With --methods: checks that the existing files can be merged and prints the methods run;
/// false after printing why not.
bool announceSubset(const Args& args) {
  if (!(mergeable(args.out + "/accuracy.csv", kAccuracyHeader) &&
        mergeable(args.out + "/stability.csv", kStabilityHeader)))
    return false;
  std::string list;
  for (const auto& m : args.methods) list += " " + m;
  std::printf("methods:%s (the other methods' rows and calibration.csv are kept)\n", list.c_str());
  return true;
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
Grid studyGrid(bool quick) {
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
std::vector<int> substepsAt(const std::string& method, const ScenarioContext& ctx, int res) {
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
const Run* referenceRun(const std::string& method, const ScenarioContext& ctx, bool refOnly, FastRuns& fast,
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
void settingRuns(const std::string& method, const ScenarioContext& ctx, const Run* ref, FastRuns& fast,
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
void runAccuracyScenario(Scenario scenario, const StudyObject& bar, const StudyObject& bunny, const Grid& grid,
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
void addPhysicalErrors(std::vector<Row>& rows, const StudyObject& bar, const Physics& ph) {
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

/// Runs the stress table and returns its runs.
std::vector<std::unique_ptr<Run>> runStress(const StudyObject& bunny, const Calibration& calib,
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

/// Writes <dir>/calibration.csv: the physical references and the calibration of the peers.
/// Returns false after printing why it could not.
bool writeCalibration(const std::string& dir, const Physics& ph, const Calibration& calib, const StudyObject& bar,
                      const StudyObject& bunny, bool withBullet) {
  std::ofstream f(dir + "/calibration.csv");
  if (!f) {
    std::fprintf(stderr, "flsm_study: cannot write %s/calibration.csv (does the directory exist?)\n", dir.c_str());
    return false;
  }
  f << "quantity,value,unit,meaning\n"
    << "bar_length," << num(kBarLength) << ",m,cantilever bar length (section L/10)\n"
    << "euler_bernoulli_tip," << num(ph.eulerBernoulliTip) << ",1,Euler-Bernoulli tip deflection / L of the bar "
       "(free length L - clamp, E, load)\n"
    << "timoshenko_tip," << num(ph.timoshenkoTip) << ",1,Timoshenko tip deflection / L (shear term with nu = "
    << kStudyPoissonRatio << ")\n"
    << "fem_tip," << num(ph.femTip) << ",1,FEM oracle tip deflection / L (bar voxels at resolution " << kFemResolution
    << ", " << kFemSubdivision << "^3 trilinear hexahedra per cell, nu = " << kStudyPoissonRatio << "): the physical reference\n"
    << "fem_check_tip," << num(ph.femCheckTip) << ",1,FEM oracle tip deflection / L at resolution "
    << kFemCheckResolution << " (coarser, convergence check)\n"
    << "column_fem_top," << num(ph.columnFemTop) << ",1,FEM oracle shortening / L of the column (the bar clamped at "
       "its base, load " << kColumnLoad << " m/s^2 along it)\n"
    << "column_uniaxial_top," << num(ph.columnUniaxialTop) << ",1,uniaxial-stress shortening / L of a free column "
       "(rho g H^2 / (2 E), nu = 0)\n"
    << "poisson_ratio," << num(kStudyPoissonRatio) << ",1,Poisson's ratio of FastLSM, the FEM oracle and Bullet's deformable body\n"
    << "fastlsm_tip," << num(calib.fastlsmTip) << ",1,FastLSM tip deflection / L at the calibration setting (res "
    << kCalibrationResolution << ", " << kCalibrationSubsteps << " sub-steps)\n"
    << "spring_ratio," << num(calib.springRatio) << ",1,mass-spring kappa / E: spring stiffness k = kappa h fill\n"
    << "bar_youngs_modulus," << num(bar.youngsModulus) << ",Pa,bar material\n"
    << "bunny_youngs_modulus," << num(bunny.youngsModulus) << ",Pa,bunny material\n"
    << "dashpot_time," << num(calib.dashpotTime) << ",s,mass-spring beta: dashpot c = beta k\n"
    << "omega_max," << num(calib.omegaMax) << ",rad/s,highest mass-spring frequency at the calibration resolution\n"
    << "mass_spring_tip," << num(calib.massSpringTip) << ",1,mass-spring tip deflection / L after calibration\n";
  if (withBullet)
    f << "bullet_ratio," << num(calib.bulletRatio) << ",1,legacy Bullet kLST = ratio E h^2 / (rho dx^2) capped at 1 ("
      << kBulletIterations << " position iterations; pose matching kMT " << kBulletPoseMatching
      << " per 1/60 s; volume conservation kVC = " << kBulletVolumeFraction << " K / V0)\n"
      << "bullet_tip," << num(calib.bulletTip) << ",1,legacy Bullet tip deflection / L after calibration ("
      << kBulletCalibrationSubsteps << " sub-steps)" << (calib.bulletReached ? "" : ": target not reached") << "\n";
  return true;
}

/// The lines of accuracy.csv, one per row (kAccuracyHeader's columns).
std::vector<std::string> accuracyLines(const std::vector<Row>& rows, const StudyObject& bar) {
  std::vector<std::string> lines;
  for (const Row& row : rows) {
    const Run& r = *row.run;
    const double frameStep = scenarioSetting(r.scenario, bar, r.resolution, r.substeps).frameStep;
    std::ostringstream f;
    f << toString(r.scenario) << ',' << r.method << ',' << r.resolution << ',' << r.substeps << ','
      << (r.reference ? 1 : 0) << ',' << r.particles << ',' << r.halfWidth << ',' << num(r.substep) << ','
      << (r.record.blewUp ? 1 : 0) << ',' << num(row.errorRef) << ',' << num(row.ebRms) << ',' << num(row.tip) << ','
      << num(r.scenario != Scenario::EarDrag ? std::numeric_limits<double>::quiet_NaN() : r.record.shapeError)
      << ',' << num(r.record.volumeChange) << ',' << num(r.record.peakKineticEnergy) << ','
      << num(r.secondsPerFrame / frameStep) << ','
      << num(1e9 * r.secondsPerFrame / (double(r.substeps) * double(r.particles))) << ',' << r.repeats << ','
      << num(row.diffVsFast) << ',' << num(r.alpha) << ',' << (r.saturated < 0 ? std::string() : std::to_string(r.saturated))
      << ',' << num(row.vsFem.tip) << ',' << num(row.vsFem.profile) << ',' << num(row.vsAnalytic.tip) << ','
      << num(row.vsAnalytic.profile) << ',' << num(r.iterations) << ',' << num(r.wallSecondsPerFrame / frameStep);
    lines.push_back(f.str());
  }
  return lines;
}

/// The lines of stability.csv, one per stress run (kStabilityHeader's columns).
std::vector<std::string> stabilityLines(const std::vector<std::unique_ptr<Run>>& stress) {
  std::vector<std::string> lines;
  for (const auto& rp : stress) {
    const Run& r = *rp;
    const std::string outcome =
        r.record.blewUp ? "blew up" : (r.record.shapeError < kRecoveredTolerance ? "recovered" : "distorted");
    std::ostringstream f;
    f << toString(r.scenario) << ',' << r.method << ',' << r.resolution << ',' << r.particles << ','
      << num(kStressFrameStep) << ',' << r.substeps << ',' << outcome << ','
      << num(r.record.blewUp ? (r.record.blowUpFrame + 1) * kStressFrameStep
                             : std::numeric_limits<double>::quiet_NaN())
      << ',' << num(r.record.shapeError) << ',' << num(r.record.recoveredAfter) << ','
      << num(r.record.peakKineticEnergy) << ','
      << num(r.scenario == Scenario::DragFar ? r.record.volumeChange : std::numeric_limits<double>::quiet_NaN())
      << ',' << num(r.record.finalVolumeChange) << ',' << num(r.youngsModulus) << ',' << num(r.iterations);
    lines.push_back(f.str());
  }
  return lines;
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  std::setvbuf(stdout, nullptr, _IOLBF, 0);  // progress lines appear as they are printed, also into a pipe
  const auto start = std::chrono::steady_clock::now();
  bool withBullet = false;
#ifdef FLSM_STUDY_WITH_BULLET
  withBullet = args.bullet;
#endif
  const StudyObject bar = makeBar(kBarLength);
  const StudyObject bunny = makeBunny(args.mesh, kStudyBunnyScale);
  printIntro(args, bar, bunny, withBullet);

  const Physics ph = physics(bar);
  printPhysics(ph);
  // the methods of this run: all (the Bullet peers when built in), or those of --methods
  const bool subset = !args.methods.empty();
  const Selection selected{args, withBullet, subset};
  const std::vector<std::string> methods = accuracyMethods(selected);  // of the accuracy runs
  if (subset && !announceSubset(args)) return 1;
  // Bullet's deformable body damps its stiff modes with the mass-spring's calibrated dashpot time
  const Calibration calib =
      calibrate(bar, ph, selected("mass-spring") || selected("bullet-fem"), selected("bullet"));
  std::printf("  (physics and calibration: %.0f s)\n", secondsSince(start));
  if (!runIndentation(args, calib, selected, subset)) return 1;
  if (args.indentationOnly) {
    std::printf("wrote indentation.csv in %.0f s\n", secondsSince(start));
    return 0;
  }

  const Grid grid = studyGrid(args.quick);
  AccuracyRuns accuracy;
  for (Scenario scenario : {Scenario::Cantilever, Scenario::Column, Scenario::EarDrag})
    runAccuracyScenario(scenario, bar, bunny, grid, methods, selected, args, calib, accuracy);
  addPhysicalErrors(accuracy.rows, bar, ph);
  const std::vector<std::unique_ptr<Run>> stress = runStress(bunny, calib, selected);

  // --- files
  const std::string dir = args.out;
  if (!subset && !writeCalibration(dir, ph, calib, bar, bunny, withBullet)) return 1;
  if (!writeCsv(dir + "/accuracy.csv", kAccuracyHeader, accuracyLines(accuracy.rows, bar), subset, selected,
                kAllMethods, CsvOrder::ScenarioThenMethod))
    return 1;
  if (!writeCsv(dir + "/stability.csv", kStabilityHeader, stabilityLines(stress), subset, selected, kAllMethods,
                CsvOrder::Method))
    return 1;
  const double total = secondsSince(start);
  std::printf("wrote %saccuracy.csv, stability.csv in %.0f s\n", subset ? "" : "calibration.csv, ", total);
  return 0;
}
