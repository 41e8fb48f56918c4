/// @file report.h
/// What the speed/accuracy study (flsm_study) prints and writes besides its runs' lines: the
/// log's first lines, the columns and lines of accuracy.csv and stability.csv, and
/// calibration.csv.
#pragma once

#include "study/accuracy_panel.h"
#include "study/args.h"
#include "study/bar_physics.h"
#include "study/config.h"
#include "study/csv.h"
#include "study/peers.h"
#include "study/runs.h"
#include "study/scenarios.h"
#include "study/setting.h"

#include <cstdio>
#include <fstream>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

/// The columns of accuracy.csv and stability.csv (docs/study.md defines them).
inline const std::string kAccuracyHeader =
    "scenario,method,resolution,substeps,reference,particles,half_width,substep_s,blew_up,error_ref,eb_rms,"
    "tip_deflection,shape_error,volume_change,peak_kinetic_energy_J,cpu_s_per_sim_s,ns_per_particle_step,repeats,"
    "diff_vs_fast,alpha,saturated,tip_vs_fem,profile_vs_fem,tip_vs_analytic,profile_vs_analytic,cg_iterations,"
    "wall_s_per_sim_s";
inline const std::string kStabilityHeader =
    "scenario,method,resolution,particles,frame_step_s,substeps,outcome,blow_up_time_s,shape_error,"
    "recovered_after_s,peak_kinetic_energy_J,volume_change_held,volume_change_final,youngs_modulus_Pa,cg_iterations";

/// Prints the first lines of the log: the objects, how cost is measured, whether Bullet runs.
inline void printIntro(const Args& args, const StudyObject& bar, const StudyObject& bunny, bool withBullet) {
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
inline void printPhysics(const Physics& ph) {
  std::printf("physics: FEM oracle (resolution %d, %d^3 elements per cell, %.1f s) tip %.5f L, at resolution %d "
              "%.5f L; Timoshenko %.5f L; Euler-Bernoulli %.5f L\n",
              kFemResolution, kFemSubdivision, ph.femSeconds, ph.femTip, kFemCheckResolution, ph.femCheckTip,
              ph.timoshenkoTip, ph.eulerBernoulliTip);
  std::printf("physics: column shortening, FEM oracle %.5f L; uniaxial stress (nu = 0) %.5f L\n", ph.columnFemTop,
              ph.columnUniaxialTop);
}

/// With --methods: checks that the existing files can be merged and prints the methods run;
/// false after printing why not.
inline bool announceSubset(const Args& args) {
  if (!(mergeable(args.out + "/accuracy.csv", kAccuracyHeader) &&
        mergeable(args.out + "/stability.csv", kStabilityHeader)))
    return false;
  std::string list;
  for (const auto& m : args.methods) list += " " + m;
  std::printf("methods:%s (the other methods' rows and calibration.csv are kept)\n", list.c_str());
  return true;
}

/// Writes <dir>/calibration.csv: the physical references and the calibration of the peers.
/// Returns false after printing why it could not.
inline bool writeCalibration(const std::string& dir, const Physics& ph, const Calibration& calib, const StudyObject& bar,
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
inline std::vector<std::string> accuracyLines(const std::vector<Row>& rows, const StudyObject& bar) {
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
inline std::vector<std::string> stabilityLines(const std::vector<std::unique_ptr<Run>>& stress) {
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

}  // namespace study
}  // namespace deformable_flsm
