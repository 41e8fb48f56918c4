// FastLSM against Bullet's soft body at equal particle count: the cost of a particle-step of
// each, on the same lattice, in the same scenario, single thread. A benchmark, not a test: it
// prints figures and never fails because the machine is slow.
//
//   bench_peer [--mesh PATH] [--particles N] [--repeats N] [--w W] [--substeps N]
//              [--iterations I,J,...] [--bullet-ratio R]
//
// The bunny (scale 0.1, as in the study) is voxelized at the resolution whose particle count is
// closest to --particles (default 10000), and the lattice is built with region half-width --w
// (default 2). Both methods then run the study's ear drag (scenarios.h: base pinned, ear dragged
// by 30% of the size over 0.5 s, held to 1.5 s, released, to 3.5 s; weightless; 1/60 s frames,
// --substeps sub-steps per frame, default 1), driven by study::runScenario() as in flsm_study:
//  - FastLSM: SolverKind::Fast with the study's parameters (study::flsmParams(): E = 5 kPa in
//    metres, alpha capped at 1, ambient damping 0.5/s, one thread), except the region
//    half-width, which is --w here rather than the study's radius of 1/12 of the bunny;
//  - Bullet: BulletSoftBodyMethod, one node per particle and one link per pair of touching cells,
//    kLST = min(1, R E h^2 / (rho dx^2)) with the study's calibrated R (flsm_study's
//    calibration.csv, bullet_ratio, found at 4 iterations), at each of --iterations position
//    iterations per sub-step (default 1, 4, 10; the study uses 4).
// Cost: wall time of step() only; the median over the 210 frames of a run, then over --repeats
// runs (default 3, interleaved over the methods so that a busy spell of the machine hits them
// alike), divided by sub-steps and particles. Next to the cost, each row shows its work units
// (regions, links) and what the run produced (volume change at the end of the hold, rest-shape
// error 2 s after release, blow-up), so that no cost is read off a run that went wrong.

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/voxelizer.h"
#include "study/mass_spring.h"
#include "study/metrics.h"
#include "study/method.h"
#include "study/scenarios.h"
#include "study/setting.h"
#ifdef FLSM_STUDY_WITH_BULLET
#include "study/bullet_soft_body.h"
#endif

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <functional>
#include <limits>
#include <memory>
#include <numeric>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::study;

namespace {

/// Bullet's kLST = ratio E h^2 / (rho dx^2), capped at 1: the ratio that flsm_study's calibration
/// found (docs/study/calibration.csv, bullet_ratio), so that Bullet's cantilever bends as far as
/// FastLSM's. At ~10k bunny particles and 1/60 s the cap is reached, and kLST is 1 whatever the
/// ratio.
constexpr double kStudyBulletRatio = 0.318316;
/// A run whose volume change exceeds this fraction at the end of the hold or of the run is
/// reported as collapsed: its cost is not that of a usable simulation.
constexpr double kCollapsedVolume = 0.5;

struct Args {
  std::string mesh = deformable_flsm::kBunnyMeshPath;
  std::size_t particles = 10000;
  int repeats = 3;
  int halfWidth = 2;
  int substeps = 1;
  std::vector<int> iterations = {1, 4, 10};
  double bulletRatio = kStudyBulletRatio;
};

[[noreturn]] void usage(int code) {
  std::fprintf(code ? stderr : stdout,
               "usage: bench_peer [--mesh PATH] [--particles N] [--repeats N] [--w W] [--substeps N]\n"
               "                  [--iterations I,J,...] [--bullet-ratio R]\n");
  std::exit(code);
}

/// A whole number >= `min` from option `key`, or exit 2.
long positive(const std::string& key, const std::string& v, long min) {
  char* end = nullptr;
  const long n = std::strtol(v.c_str(), &end, 10);
  if (v.empty() || *end != '\0' || n < min) {
    std::fprintf(stderr, "bench_peer: %s expects a whole number >= %ld, got '%s'\n", key.c_str(), min, v.c_str());
    std::exit(2);
  }
  return n;
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    if (k == "-h" || k == "--help") usage(0);
    if (i + 1 >= argc) {
      std::fprintf(stderr, "bench_peer: %s needs a value\n", k.c_str());
      usage(2);
    }
    const std::string v = argv[++i];
    if (k == "--mesh") a.mesh = v;
    else if (k == "--particles") a.particles = static_cast<std::size_t>(positive(k, v, 10));
    else if (k == "--repeats") a.repeats = static_cast<int>(positive(k, v, 1));
    else if (k == "--w") a.halfWidth = static_cast<int>(positive(k, v, 1));
    else if (k == "--substeps") a.substeps = static_cast<int>(positive(k, v, 1));
    else if (k == "--iterations") {
      a.iterations.clear();
      std::stringstream ss(v);
      for (std::string item; std::getline(ss, item, ',');) a.iterations.push_back(static_cast<int>(positive(k, item, 1)));
    } else if (k == "--bullet-ratio") {
      char* end = nullptr;
      a.bulletRatio = std::strtod(v.c_str(), &end);
      if (v.empty() || *end != '\0' || !(a.bulletRatio > 0.0) || !std::isfinite(a.bulletRatio)) {
        std::fprintf(stderr, "bench_peer: --bullet-ratio expects a number > 0, got '%s'\n", v.c_str());
        std::exit(2);
      }
    } else {
      std::fprintf(stderr, "bench_peer: unknown option %s\n", k.c_str());
      usage(2);
    }
  }
  return a;
}

/// A fraction as a percentage with two decimals; "-" when it is not finite (a blown-up run
/// has no volume or shape to report).
std::string percent(double fraction) {
  if (!std::isfinite(fraction)) return "-";
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.2f", 100.0 * fraction);
  return buf;
}

/// One row of the table: a method configuration, how to build it, what it measured.
struct Entry {
  std::string label;
  int iterations = 0;                             // Bullet's position iterations; 0 for FastLSM
  std::size_t workUnits = 0;                      // FastLSM regions, Bullet links
  std::function<std::unique_ptr<Method>()> make;  // a fresh method at rest, per run
  std::vector<double> nsPerParticleStep;          // one per repeat
  RunRecord first;                                // the first run's record (runs are deterministic)
};

/// Prints the set-up: the mesh and lattice, the scenario's setting, how cost is measured.
void printSetup(const Args& args, const StudyObject& bunny, int resolution, const Voxelization& voxels,
                const Lattice& lattice, Scenario scenario, const Setting& setting, int frames) {
  const std::size_t P = lattice.size();
  const double dx = lattice.spacing();
  const double h = setting.substep();
  std::printf("bench_peer: mesh %s x %.2g, size %.4f m; resolution %d, lattice %d x %d x %d, spacing %.4g m, "
              "%zu particles, w = %d (the study's region radius would give w = %d here)\n",
              args.mesh.c_str(), kStudyBunnyScale, bunny.size, resolution, voxels.dims.x(), voxels.dims.y(),
              voxels.dims.z(), dx, P, args.halfWidth, static_cast<int>(std::lround(bunny.regionRadius / dx)));
  std::printf("scenario %s (study::runScenario): %d frames of %.4g s, %d sub-step(s) of %.4g s, E = %.3g Pa, "
              "ambient damping %.2g/s, %zu base particles pinned, %zu ear particles dragged\n",
              toString(scenario), frames, setting.frameStep, args.substeps, h, setting.youngsModulus,
              setting.ambientDamping, baseParticles(lattice, bunny).size(), earParticles(lattice, bunny).size());
  std::printf("single thread; cost = wall time of step() only, median over the frames of a run, then over %d "
              "run(s), per particle and sub-step\n",
              args.repeats);
}

/// Adds FastLSM's entry to `entries` and prints its regions and alpha.
void addFastLsm(std::vector<Entry>& entries, const Args& args, const std::shared_ptr<const Lattice>& lattice,
                const SolverParams& flsm) {
  const std::size_t P = lattice->size();
  // FastLSM: one region per particle; its sums cost O(1) per particle whatever w, but the
  // mean region size says how much each shape match covers.
  const std::vector<int>& counts = lattice->regionCounts();
  const double members = std::accumulate(counts.begin(), counts.end(), 0.0) / double(P);
  Entry e;
  e.label = "FastLSM fast, w " + std::to_string(args.halfWidth);
  e.workUnits = P;
  e.make = [lattice, flsm]() -> std::unique_ptr<Method> { return std::make_unique<FlsmMethod>(lattice, flsm); };
  entries.push_back(std::move(e));
  const FlsmMethod probe(lattice, flsm);
  std::printf("FastLSM: %zu regions of %.1f particles on average (up to %d), alpha %.3g%s, double precision\n", P,
              members, (2 * args.halfWidth + 1) * (2 * args.halfWidth + 1) * (2 * args.halfWidth + 1),
              probe.solver().alpha(),
              probe.solver().stiffnessSaturated() ? " (capped: the step is too long for E, the material is softer)"
                                                  : "");
}

#ifdef FLSM_STUDY_WITH_BULLET
/// Adds Bullet's entries to `entries`, one per --iterations count, and prints its links and kLST.
void addBullet(std::vector<Entry>& entries, const Args& args, const std::shared_ptr<const Lattice>& lattice,
               const Setting& setting) {
  const std::size_t P = lattice->size();
  const double dx = lattice->spacing();
  const double h = setting.substep();
  const std::size_t links = latticeLinks(*lattice).size();
  const double kLST = std::min(1.0, args.bulletRatio * setting.youngsModulus * h * h / (kStudyDensity * dx * dx));
  BulletParams base;
  base.linearStiffness = kLST;
  base.ambientDamping = setting.ambientDamping;
  base.gravity = setting.gravity;
  base.timeStep = setting.frameStep;
  base.substeps = setting.substeps;
  for (int it : args.iterations) {
    Entry e;
    e.label = "Bullet soft body";
    e.iterations = it;
    e.workUnits = links;
    BulletParams p = base;
    p.positionIterations = it;
    e.make = [lattice, p]() -> std::unique_ptr<Method> {
      return std::make_unique<BulletSoftBodyMethod>(lattice, p);
    };
    entries.push_back(std::move(e));
  }
  std::printf("Bullet %d.%02d: btSoftBody, %zu nodes, %zu links (%.2f per particle: face, edge and corner "
              "neighbours), kLST %.3g%s, %zu-byte btScalar, no collision world\n",
              BT_BULLET_VERSION / 100, BT_BULLET_VERSION % 100, P, links, double(links) / double(P), kLST,
              kLST >= 1.0 ? " (capped at 1)" : "", sizeof(btScalar));
}
#endif

/// Runs every entry --repeats times, in turns, recording its cost per run and its first record.
void runEntries(std::vector<Entry>& entries, const Args& args, Scenario scenario, const StudyObject& bunny,
                const Lattice& lattice, const Setting& setting) {
  const std::size_t P = lattice.size();
  for (int r = 0; r < args.repeats; ++r)
    for (Entry& e : entries) {
      auto method = e.make();
      RunRecord rec = runScenario(scenario, bunny, lattice, *method, setting.frameStep, 0);
      e.nsPerParticleStep.push_back(1e9 * median(rec.frameSeconds) / (double(args.substeps) * double(P)));
      if (r == 0) e.first = std::move(rec);
    }
}

/// The cost table: each entry's work units and cost per particle-step, against FastLSM's.
void costTable(const std::vector<Entry>& entries, const Args& args, std::size_t P) {
  const double fastNs = median(entries.front().nsPerParticleStep);
  std::printf("\ncost (single thread):\n%-17s %5s %10s %9s %11s %10s %9s %9s %12s  %s\n", "method", "iter",
              "work units", "per part.", "unit-iters", "ns/p-step", "x FastLSM", "ms/frame", "ns/unit-iter",
              "ns/p-step of each run");
  for (const Entry& e : entries) {
    const double ns = median(e.nsPerParticleStep);
    const double unitIters = double(e.iterations > 0 ? e.iterations : 1) * double(e.workUnits) / double(P);
    std::string runs;
    for (double v : e.nsPerParticleStep) runs += (runs.empty() ? "" : " ") + std::to_string(std::lround(v));
    std::printf("%-17s %5s %10zu %9.2f %11.2f %10.1f %9.2f %9.2f %12.2f  %s\n", e.label.c_str(),
                e.iterations > 0 ? std::to_string(e.iterations).c_str() : "-", e.workUnits,
                double(e.workUnits) / double(P), unitIters, ns, ns / fastNs, ns * 1e-6 * double(P) * args.substeps,
                ns / unitIters, runs.c_str());
  }
  std::printf("work units: FastLSM regions (one per particle), Bullet links; unit-iters: work units x position "
              "iterations (one pass for FastLSM) per particle-step.\n");
}

/// The result table: what each entry's first run produced (volume, shape, energy, outcome).
void resultTable(const std::vector<Entry>& entries) {
  // What the (first) runs produced: the costs above are only comparable between runs that
  // stayed finite and kept the bunny's shape.
  std::printf("\nresult of the same runs:\n%-17s %5s %12s %11s %13s %12s  %s\n", "method", "iter", "vol hold (%)",
              "vol end (%)", "shape end (%)", "peak KE (J)", "outcome");
  for (const Entry& e : entries) {
    const RunRecord& rec = e.first;
    std::string outcome = "finite";
    if (rec.blewUp) outcome = "BLEW UP at frame " + std::to_string(rec.blowUpFrame + 1);
    else if (std::abs(rec.volumeChange) > kCollapsedVolume || std::abs(rec.finalVolumeChange) > kCollapsedVolume)
      outcome = "collapsed";
    std::printf("%-17s %5s %12s %11s %13s %12.3g  %s\n", e.label.c_str(),
                e.iterations > 0 ? std::to_string(e.iterations).c_str() : "-", percent(rec.volumeChange).c_str(),
                percent(rec.finalVolumeChange).c_str(), percent(rec.shapeError).c_str(), rec.peakKineticEnergy,
                outcome.c_str());
  }
  std::printf("vol hold: volume change of the embedded render mesh at the end of the hold (ear 30%% of the size "
              "away); vol end, shape end: %.0f s after release (shape = RMS distance to the best rigid fit of the "
              "rest shape, over the size; the soft bunny still wobbles then). collapsed: volume change beyond "
              "+-%.0f%%; blew up: non-finite, or %.0f sizes away.\n",
              kEarDragEnd - kEarDragHoldUntil, 100.0 * kCollapsedVolume, kBlowUpSizes);
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  try {
    const StudyObject bunny = makeBunny(args.mesh, kStudyBunnyScale);
    ResolutionChoice near = nearestResolution(bunny.mesh, args.particles);
    const int resolution = near.resolution;
    const Voxelization voxels = std::move(near.voxels);
    const auto lattice = std::make_shared<const Lattice>(voxels, kStudyDensity, args.halfWidth);
    const std::size_t P = lattice->size();

    // The study's ear-drag setting at this resolution, on the lattice's regions (w as given).
    const Scenario scenario = Scenario::EarDrag;
    const Setting setting = scenarioSetting(scenario, bunny, resolution, args.substeps);
    const SolverParams flsm = flsmParams(setting, lattice->regionHalfWidth(), SolverKind::Fast);
    const int frames = static_cast<int>(std::lround(scenarioDuration(scenario) / setting.frameStep));
    printSetup(args, bunny, resolution, voxels, *lattice, scenario, setting, frames);

    std::vector<Entry> entries;
    addFastLsm(entries, args, lattice, flsm);
#ifdef FLSM_STUDY_WITH_BULLET
    addBullet(entries, args, lattice, setting);
#else
    std::printf("Bullet: not built in (pkg-config found no 'bullet'; install libbullet-dev): FastLSM only\n");
#endif
    std::fflush(stdout);

    runEntries(entries, args, scenario, bunny, *lattice, setting);
    costTable(entries, args, P);
    resultTable(entries);
    return 0;
  } catch (const std::exception& ex) {
    std::fprintf(stderr, "bench_peer: %s\n", ex.what());
    return 1;
  }
}
