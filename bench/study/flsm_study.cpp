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
//
// The program's parts, header-only in bench/study/: config.h (the grid, the peers' settings),
// args.h (the command line), peers.h (the methods by name), runs.h (one timed run),
// calibration.h (the physical references, the peers' calibration), accuracy_panel.h,
// stress_panel.h and indentation_panel.h (each panel's runs), report.h (the log's first lines and
// the CSV files).

#include "study/accuracy_panel.h"
#include "study/args.h"
#include "study/calibration.h"
#include "study/csv.h"
#include "study/indentation_panel.h"
#include "study/report.h"
#include "study/runs.h"
#include "study/scenarios.h"
#include "study/stress_panel.h"

#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::study;

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
