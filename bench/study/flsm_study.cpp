// Speed against accuracy: runs the study's scenarios headless with FastLSM, naive LSM,
// an explicit mass-spring lattice and (when built with Bullet) Bullet's soft body, and writes
//   <out>/calibration.csv  the baselines' stiffness, matched to FastLSM's cantilever
//   <out>/accuracy.csv     one row per run: error against the method's reference, Euler-Bernoulli
//                          profile error, rest-shape recovery, volume change, cost
//   <out>/stability.csv    one row per method and stress scenario (1/30 s, one sub-step)
// A benchmark, not a test: it prints figures and never fails because the machine is slow.
//
//   flsm_study [--out DIR] [--mesh PATH] [--repeats N] [--quick] [--no-bullet]
//
// --quick runs a small grid (coarse resolutions, few sub-steps) to check the pipeline; --repeats
// (default 3) repeats every run that took under 2 s and reports the median time.
// Definitions of every figure: docs/study.md.

#include "deformable_flsm/core/lattice.h"
#include "study/mass_spring.h"
#include "study/method.h"
#include "study/metrics.h"
#include "study/scenarios.h"
#include "study/setting.h"
#ifdef FLSM_STUDY_WITH_BULLET
#include "study/bullet_soft_body.h"
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
constexpr int kBarReferenceResolution = 80;
const std::vector<int> kBunnyResolutions = {12, 24};
constexpr int kBunnyReferenceResolution = 36;
/// Bunny resolution of the stress scenarios.
constexpr int kStressResolution = 24;

/// Sub-steps per 1/60 s frame of FastLSM and Bullet, and of their reference runs.
const std::vector<int> kSubsteps = {1, 2, 4, 8};
constexpr int kReferenceSubsteps = 16;
/// Naive LSM: the region sums cost O(w^3) per particle; the study runs it where w <= this.
constexpr int kNaiveMaxHalfWidth = 2;
/// Mass-spring: sub-steps are multiples of the fewest that are stable, s_min = the smallest
/// power of two with h omega_max <= kMassSpringStepMargin (symplectic Euler is stable below 2).
constexpr double kMassSpringStepMargin = 1.5;
const std::vector<int> kMassSpringSubstepFactors = {1, 2};
constexpr int kMassSpringReferenceFactor = 4;
/// Bullet's position iterations per sub-step.
constexpr int kBulletIterations = 4;

/// Calibration setting: the bar at this resolution, FastLSM at the reference sub-steps, where
/// alpha is below its cap and the bar has the modulus it is given.
constexpr int kCalibrationResolution = 40;
constexpr int kCalibrationSubsteps = kReferenceSubsteps;
/// Runs whose first repetition took less wall time than this (s) are repeated (--repeats):
/// cheap runs are the ones that other processes on the machine disturb most.
constexpr double kRepeatBelowSeconds = 2.0;
/// Trajectory samples of the ear drag: every this many frames (10 Hz).
constexpr int kSampleEvery = 6;

struct Args {
  std::string out = "docs/study";
  std::string mesh = "/usr/share/glmark2/models/bunny.obj";
  int repeats = 3;
  bool quick = false;
  bool bullet = true;
};

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
    else {
      std::fprintf(stderr, "flsm_study: unknown option %s\n"
                           "usage: flsm_study [--out DIR] [--mesh PATH] [--repeats N] [--quick] [--no-bullet]\n",
                   k.c_str());
      std::exit(2);
    }
  }
  return a;
}

// --- methods ---------------------------------------------------------------------------------

/// Stiffness and damping of the baselines, found by calibrate(). Both baselines get the
/// setting's Young's modulus E through a dimensionless constant, so that they follow the material
/// across objects, resolutions and steps as FastLSM does:
///  - mass-spring: kappa = springRatio E (a spring lattice's modulus is proportional to kappa);
///  - Bullet: kLST = bulletRatio E h^2 / (rho dx^2), capped at 1. A position iteration removes
///    the fraction kLST of a link's error, i.e. pulls with acceleration ~ kLST err / h^2, a
///    spring of stiffness ~ kLST m / h^2 and a modulus ~ kLST rho dx^2 / h^2: the same scaling
///    as FastLSM's alpha.
struct Calibration {
  double fastlsmTip = 0.0;    // FastLSM tip deflection / L at the calibration setting
  double springRatio = 0.0;   // kappa / E
  double dashpotTime = 0.0;   // beta (s)
  double massSpringTip = 0.0;
  double omegaMax = 0.0;      // rad/s, calibration lattice
  double bulletRatio = 0.0;   // kLST rho dx^2 / (E h^2)
  double bulletTip = 0.0;
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

BulletParams bulletParams(const Setting& s, double spacing, const Calibration& c) {
  BulletParams p;
  p.linearStiffness = bulletStiffness(s, spacing, c);
  p.positionIterations = kBulletIterations;
  p.ambientDamping = s.ambientDamping;
  p.gravity = s.gravity;
  p.timeStep = s.frameStep;
  p.substeps = s.substeps;
  return p;
}
#endif

std::unique_ptr<Method> makeMethod(const std::string& name, const std::shared_ptr<const Lattice>& lattice,
                                   const Setting& s, const Calibration& c) {
  if (name == "fastlsm") return std::make_unique<FlsmMethod>(lattice, flsmParams(s, lattice->spacing(), SolverKind::Fast));
  if (name == "naive-lsm")
    return std::make_unique<FlsmMethod>(lattice, flsmParams(s, lattice->spacing(), SolverKind::Naive));
  if (name == "mass-spring") return std::make_unique<MassSpringMethod>(lattice, massSpringParams(s, c));
#ifdef FLSM_STUDY_WITH_BULLET
  if (name == "bullet") return std::make_unique<BulletSoftBodyMethod>(lattice, bulletParams(s, lattice->spacing(), c));
#endif
  throw std::invalid_argument("unknown method " + name);
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
  double secondsPerFrame = 0.0;  // median over frames, then over repeats
  int repeats = 0;
  /// FastLSM only: the alpha used, and whether the step was too long for the modulus (-1 n/a)
  double alpha = std::numeric_limits<double>::quiet_NaN();
  int saturated = -1;
};

Run runOnce(Scenario scenario, const StudyObject& object, const std::string& method, int resolution, int substeps,
            const Calibration& calib, int repeats, bool reference) {
  Run r;
  r.scenario = scenario;
  r.method = method;
  r.resolution = resolution;
  r.substeps = substeps;
  r.reference = reference;
  const auto lattice = buildLattice(object, resolution);
  r.particles = lattice->size();
  r.halfWidth = lattice->regionHalfWidth();
  const Setting s = scenarioSetting(scenario, object, resolution, substeps);
  r.substep = s.substep();
  std::vector<double> perRepeat;
  for (int k = 0; k < repeats; ++k) {
    auto m = makeMethod(method, lattice, s, calib);
    if (const auto* flsm = dynamic_cast<const FlsmMethod*>(m.get())) {
      r.alpha = flsm->solver().alpha();
      r.saturated = flsm->solver().stiffnessSaturated() ? 1 : 0;
    }
    RunRecord rec = runScenario(scenario, object, *lattice, *m, s.frameStep,
                                scenario == Scenario::EarDrag ? kSampleEvery : 0);
    perRepeat.push_back(median(rec.frameSeconds));
    double wall = 0.0;
    for (double t : rec.frameSeconds) wall += t;
    if (k == 0) r.record = std::move(rec);
    if (r.record.blewUp || wall > kRepeatBelowSeconds) break;  // nothing to time, or timed enough
  }
  r.secondsPerFrame = median(perRepeat);
  r.repeats = static_cast<int>(perRepeat.size());
  const double frameStep = s.frameStep;
  std::printf("  %-11s %-11s res %3d  sub %4d  %6zu particles  w %d  %s  %9.4f s/sim-s  %8.1f ns/p-step\n",
              toString(scenario), method.c_str(), resolution, substeps, r.particles, r.halfWidth,
              r.record.blewUp ? "BLEW UP " : "        ", r.secondsPerFrame / frameStep,
              1e9 * r.secondsPerFrame / (double(substeps) * double(r.particles)));
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

/// Matches the baselines' static stiffness to FastLSM's: the cantilever's tip deflection at the
/// calibration setting (bar at kCalibrationResolution, FastLSM at kCalibrationSubsteps).
Calibration calibrate(const StudyObject& bar, bool withBullet) {
  Calibration c;
  c.fastlsmTip = calibrationTip(bar, "fastlsm", kCalibrationSubsteps, c);
  std::printf("calibration: FastLSM tip deflection %.5f L (bar at resolution %d, %d sub-steps)\n", c.fastlsmTip,
              kCalibrationResolution, kCalibrationSubsteps);
  const auto lattice = buildLattice(bar, kCalibrationResolution);
  // Mass-spring: deflection ~ 1 / kappa for small deflections, so kappa <- kappa * tip / target
  // converges in a few rounds (the dashpots do not change the rest state).
  c.springRatio = 1.0;
  for (int round = 0; round < 8; ++round) {
    MassSpringParams p;
    p.springModulus = c.springRatio * bar.youngsModulus;
    c.omegaMax = MassSpringLattice(lattice, p).maxFrequency();
    // dashpots damp the highest mode of the calibration lattice at FastLSM's region damping
    // rate (SolverParams::damping): rate = beta omega_max^2 / 2
    c.dashpotTime = 2.0 * SolverParams().damping / (c.omegaMax * c.omegaMax);
    const int sub = massSpringMinSubsteps(lattice, c, bar.youngsModulus, kAccuracyFrameStep);
    c.massSpringTip = calibrationTip(bar, "mass-spring", sub, c);
    std::printf("  mass-spring kappa / E = %.6g (%d sub-steps): tip %.5f L\n", c.springRatio, sub, c.massSpringTip);
    if (std::abs(c.massSpringTip / c.fastlsmTip - 1.0) < 1e-3) break;
    c.springRatio *= c.massSpringTip / c.fastlsmTip;
  }
#ifdef FLSM_STUDY_WITH_BULLET
  if (withBullet) {
    // Bullet: deflection falls as kLST grows; bisection on log kLST in [1e-6, 1] at the
    // calibration setting, then expressed as the ratio that maps E to kLST.
    const Setting s = scenarioSetting(Scenario::Cantilever, bar, kCalibrationResolution, kCalibrationSubsteps);
    const double unit = bulletStiffness(s, lattice->spacing(), Calibration{0, 0, 0, 0, 0, 1.0, 0});
    double lo = std::log(1e-6), hi = 0.0;
    c.bulletRatio = 1.0 / unit;  // kLST = 1
    c.bulletTip = calibrationTip(bar, "bullet", kCalibrationSubsteps, c);
    std::printf("  bullet kLST 1: tip %.5f L\n", c.bulletTip);
    if (c.bulletTip < c.fastlsmTip) {
      for (int it = 0; it < 24; ++it) {
        const double mid = 0.5 * (lo + hi);
        c.bulletRatio = std::exp(mid) / unit;
        c.bulletTip = calibrationTip(bar, "bullet", kCalibrationSubsteps, c);
        if (c.bulletTip > c.fastlsmTip) lo = mid;
        else hi = mid;
        if (std::abs(c.bulletTip / c.fastlsmTip - 1.0) < 2e-3) break;
      }
      std::printf("  bullet kLST %.6g (ratio %.6g): tip %.5f L\n", c.bulletRatio * unit, c.bulletRatio, c.bulletTip);
    } else {
      std::printf("  bullet is softer than FastLSM even at kLST = 1: kept at 1\n");
    }
  }
#else
  (void)withBullet;
#endif
  return c;
}

/// Euler-Bernoulli tip deflection over L of the clamped bar under its body load:
/// y(Lf) = q Lf^4 / (8 E I), q = rho g a^2, I = a^4 / 12, Lf = L - clamp.
double eulerBernoulliTip(const StudyObject& bar) {
  const double a = kBarLength / kBarAspect, lf = (1.0 - kBarClampFraction) * kBarLength;
  const double q = kStudyDensity * kBarLoad * a * a, I = a * a * a * a / 12.0;
  return q * std::pow(lf, 4) / (8.0 * bar.youngsModulus * I) / kBarLength;
}

// --- output ----------------------------------------------------------------------------------

std::string num(double v) {
  if (std::isnan(v)) return "";
  if (std::isinf(v)) return "inf";
  std::ostringstream os;
  os << std::setprecision(6) << v;
  return os.str();
}

struct Row {
  const Run* run;
  double errorRef = std::numeric_limits<double>::quiet_NaN();
  double ebRms = std::numeric_limits<double>::quiet_NaN();
  double tip = std::numeric_limits<double>::quiet_NaN();
  double diffVsFast = std::numeric_limits<double>::quiet_NaN();
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

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  const auto start = std::chrono::steady_clock::now();
  bool withBullet = false;
#ifdef FLSM_STUDY_WITH_BULLET
  withBullet = args.bullet;
#endif
  const StudyObject bar = makeBar(kBarLength);
  const StudyObject bunny = makeBunny(args.mesh, kStudyBunnyScale);
  std::printf("flsm_study: bar %.3g x %.3g x %.3g m (%zu render vertices); bunny %s x %.2g, size %.4f m (%zu vertices, "
              "%zu sampled)\n",
              kBarLength, kBarLength / kBarAspect, kBarLength / kBarAspect, bar.mesh.vertices.size(), args.mesh.c_str(),
              kStudyBunnyScale, bunny.size, bunny.mesh.vertices.size(), bunny.sampleVertices.size());
  std::printf("single thread; times are medians over the frames of a run%s\n",
              args.repeats > 1 ? ", then over up to --repeats runs (runs under 2 s)" : "");
  if (!withBullet) std::printf("Bullet's soft body: not built in (no Bullet found, or --no-bullet)\n");

  const Calibration calib = calibrate(bar, withBullet);

  std::vector<std::string> methods = {"fastlsm", "naive-lsm", "mass-spring"};
  if (withBullet) methods.push_back("bullet");

  const std::vector<int> barRes = args.quick ? std::vector<int>{20} : kBarResolutions;
  const int barRef = args.quick ? 40 : kBarReferenceResolution;
  const std::vector<int> bunnyRes = args.quick ? std::vector<int>{12} : kBunnyResolutions;
  const int bunnyRef = args.quick ? 24 : kBunnyReferenceResolution;
  const std::vector<int> subs = args.quick ? std::vector<int>{1, 4} : kSubsteps;
  const int refSubs = args.quick ? 8 : kReferenceSubsteps;

  std::vector<std::unique_ptr<Run>> runs;
  std::vector<Row> rows;
  for (Scenario scenario : {Scenario::Cantilever, Scenario::EarDrag}) {
    const StudyObject& object = scenario == Scenario::Cantilever ? bar : bunny;
    const std::vector<int>& resolutions = scenario == Scenario::Cantilever ? barRes : bunnyRes;
    const int refRes = scenario == Scenario::Cantilever ? barRef : bunnyRef;
    std::printf("%s:\n", toString(scenario));
    std::map<std::string, const Run*> fastBySetting;
    const Run* fastRef = nullptr;
    for (const std::string& method : methods) {
      // the method's own sub-step lists at each resolution, and its reference
      auto substepsAt = [&](int res) {
        if (method != "mass-spring") return subs;
        const int smin = massSpringMinSubsteps(buildLattice(object, res), calib, object.youngsModulus, kAccuracyFrameStep);
        std::vector<int> out;
        for (int f : kMassSpringSubstepFactors) out.push_back(smin * f);
        return out;
      };
      const Run* ref = nullptr;
      if (method == "naive-lsm") {
        ref = fastRef;  // same algorithm as FastLSM (sums in another order): same reference
      } else {
        const int rs = method == "mass-spring"
                           ? massSpringMinSubsteps(buildLattice(object, refRes), calib, object.youngsModulus,
                                                   kAccuracyFrameStep) *
                                 kMassSpringReferenceFactor
                           : refSubs;
        runs.push_back(std::make_unique<Run>(runOnce(scenario, object, method, refRes, rs, calib, 1, true)));
        ref = runs.back().get();
        rows.push_back(Row{ref});
        if (method == "fastlsm") fastRef = ref;
      }
      for (int res : resolutions) {
        if (method == "naive-lsm" && buildLattice(object, res)->regionHalfWidth() > kNaiveMaxHalfWidth)
          continue;
        for (int sub : substepsAt(res)) {
          runs.push_back(std::make_unique<Run>(runOnce(scenario, object, method, res, sub, calib, args.repeats, false)));
          const Run& run = *runs.back();
          Row row{&run};
          row.errorRef = errorAgainst(run, *ref, object.size);
          const std::string key = std::to_string(res) + "/" + std::to_string(sub);
          if (method == "fastlsm") fastBySetting[key] = &run;
          if (method == "naive-lsm" && fastBySetting.count(key))
            row.diffVsFast = errorAgainst(run, *fastBySetting[key], object.size);
          rows.push_back(row);
        }
      }
    }
  }
  for (Row& row : rows) {
    if (row.run->scenario == Scenario::Cantilever && !row.run->record.blewUp) {
      const CantileverProfile p = cantileverProfile(bar, row.run->record.finalPoints);
      row.tip = p.tipDeflection;
      row.ebRms = p.eulerBernoulliRms;
    }
  }

  // stress: every method at 1/30 s in one sub-step
  std::printf("stress (bunny at resolution %d, %.4g s, one sub-step):\n", kStressResolution, kStressFrameStep);
  std::vector<std::unique_ptr<Run>> stress;
  for (const std::string& method : methods)
    for (Scenario scenario : {Scenario::DragFar, Scenario::Plane, Scenario::Scrambled})
      stress.push_back(std::make_unique<Run>(runOnce(scenario, bunny, method, kStressResolution, 1, calib, 1, false)));

  // --- files
  const std::string dir = args.out;
  {
    std::ofstream f(dir + "/calibration.csv");
    if (!f) {
      std::fprintf(stderr, "flsm_study: cannot write %s/calibration.csv (does the directory exist?)\n", dir.c_str());
      return 1;
    }
    f << "quantity,value,unit,meaning\n"
      << "bar_length," << num(kBarLength) << ",m,cantilever bar length (section L/10)\n"
      << "euler_bernoulli_tip," << num(eulerBernoulliTip(bar)) << ",1,Euler-Bernoulli tip deflection / L of the bar "
         "(free length L - clamp, E, load)\n"
      << "fastlsm_tip," << num(calib.fastlsmTip) << ",1,FastLSM tip deflection / L at the calibration setting (res "
      << kCalibrationResolution << ", " << kCalibrationSubsteps << " sub-steps)\n"
      << "spring_ratio," << num(calib.springRatio) << ",1,mass-spring kappa / E: spring stiffness k = kappa h fill\n"
      << "bar_youngs_modulus," << num(bar.youngsModulus) << ",Pa,bar material\n"
      << "bunny_youngs_modulus," << num(bunny.youngsModulus) << ",Pa,bunny material\n"
      << "dashpot_time," << num(calib.dashpotTime) << ",s,mass-spring beta: dashpot c = beta k\n"
      << "omega_max," << num(calib.omegaMax) << ",rad/s,highest mass-spring frequency at the calibration resolution\n"
      << "mass_spring_tip," << num(calib.massSpringTip) << ",1,mass-spring tip deflection / L after calibration\n";
    if (withBullet)
      f << "bullet_ratio," << num(calib.bulletRatio) << ",1,Bullet kLST = ratio E h^2 / (rho dx^2) capped at 1 ("
        << kBulletIterations << " position iterations)\n"
        << "bullet_tip," << num(calib.bulletTip) << ",1,Bullet tip deflection / L after calibration\n";
  }
  {
    std::ofstream f(dir + "/accuracy.csv");
    f << "scenario,method,resolution,substeps,reference,particles,half_width,substep_s,blew_up,error_ref,"
         "eb_rms,tip_deflection,shape_error,volume_change,peak_kinetic_energy_J,wall_s_per_sim_s,"
         "ns_per_particle_step,repeats,diff_vs_fast,alpha,saturated\n";
    for (const Row& row : rows) {
      const Run& r = *row.run;
      const double frameStep = scenarioSetting(r.scenario, bar, r.resolution, r.substeps).frameStep;
      f << toString(r.scenario) << ',' << r.method << ',' << r.resolution << ',' << r.substeps << ','
        << (r.reference ? 1 : 0) << ',' << r.particles << ',' << r.halfWidth << ',' << num(r.substep) << ','
        << (r.record.blewUp ? 1 : 0) << ',' << num(row.errorRef) << ',' << num(row.ebRms) << ',' << num(row.tip) << ','
        << num(r.scenario == Scenario::Cantilever ? std::numeric_limits<double>::quiet_NaN() : r.record.shapeError)
        << ',' << num(r.record.volumeChange) << ',' << num(r.record.peakKineticEnergy) << ','
        << num(r.secondsPerFrame / frameStep) << ','
        << num(1e9 * r.secondsPerFrame / (double(r.substeps) * double(r.particles))) << ',' << r.repeats << ','
        << num(row.diffVsFast) << ',' << num(r.alpha) << ',' << (r.saturated < 0 ? std::string() : std::to_string(r.saturated))
        << '\n';
    }
  }
  {
    std::ofstream f(dir + "/stability.csv");
    f << "scenario,method,resolution,particles,frame_step_s,substeps,outcome,blow_up_time_s,shape_error,"
         "peak_kinetic_energy_J,volume_change_held,volume_change_final\n";
    for (const auto& rp : stress) {
      const Run& r = *rp;
      const std::string outcome =
          r.record.blewUp ? "blew up" : (r.record.shapeError < kRecoveredTolerance ? "recovered" : "distorted");
      f << toString(r.scenario) << ',' << r.method << ',' << r.resolution << ',' << r.particles << ','
        << num(kStressFrameStep) << ',' << r.substeps << ',' << outcome << ','
        << num(r.record.blewUp ? (r.record.blowUpFrame + 1) * kStressFrameStep
                               : std::numeric_limits<double>::quiet_NaN())
        << ',' << num(r.record.shapeError) << ',' << num(r.record.peakKineticEnergy) << ','
        << num(r.scenario == Scenario::DragFar ? r.record.volumeChange : std::numeric_limits<double>::quiet_NaN())
        << ',' << num(r.record.finalVolumeChange) << '\n';
    }
  }
  const double total = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("wrote %s/{calibration,accuracy,stability}.csv in %.0f s\n", dir.c_str(), total);
  return 0;
}
