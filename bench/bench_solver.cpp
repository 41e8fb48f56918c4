// Prints the cost of a FastLSM solver step, in ns per particle-step, for the fast and naive
// solvers at region half-widths w = 1..4, on the bunny voxelized to about --particles particles.
// A benchmark, not a test: it prints figures and never fails because the machine is slow.
// Each table's entries run in turns, one run each per round: on a shared machine whose speed
// drifts by tens of percent within a minute, a busy spell then hits every entry alike, and the
// ratios (naive/fast, w = 4 / w = 1, each size against 10k, threads) are taken within a round.
//
// Then the fast solver at w = 2 at each SIMD level the CPU runs (simd.h: chosen at run time, so
// that a build for the x86-64 baseline runs the CPU's own instructions; FLSM_SIMD lowers it).
// Then the fast solver at w = 2 across lattice sizes (1k to 200k particles: cost per particle
// should stay flat), on boxes that hold the slices' cross-section while the particle count grows
// and the other way round (what the cost per particle follows), and with every hardware thread
// against one thread (same results) at the benchmark's size and at 50k particles, next to what
// the machine gives just then to as many independent one-thread solvers (its ceiling in that
// spell). Threads pay only on idle cores: a sub-step's region pass ends when every thread's chunk
// is done, and a worker that another process has descheduled holds it up for a time slice (the
// chunk boundaries follow a slower thread, and the blocks near them go to whichever thread is
// free first; a descheduled one they cannot help), which is why a threaded solver times its steps
// and runs them on one thread while that is faster (ThreadGovernor). The last table repeats the
// threads' figures with a busy loop of the benchmark's own in another process.
//
// Last, the implicit step (SolverParams::Integrator::Implicit, one sub-step of 1/60 s) against the
// explicit step at the sub-steps it needs for the same material (the fewest at which alpha is not
// capped), at 30 kPa, 1 MPa and 10 MPa (nu 0.3, w = 2), on the bunny at --particles and at a
// quarter of it, dropped 2 cm onto a ground plane and left to settle (2 s): ns per particle per
// 1/60 s step, and the implicit step's conjugate-gradient iterations per step (mean and largest).
// Then the node's demo on the ground with the implicit step (the bunny upright, dropped, its ear
// dragged round flsm_demo's circle, released, poked and pushed) at 30 kPa and 1 MPa, w = 1 and 2,
// at --particles and a quarter of it: CPU ms per step and CG iterations in each phase, the figure
// that says whether the node keeps real time at 60 steps a second (--demo-step 0.0333: at 30, the
// implicit scene's config/implicit.yaml).
// --only implicit prints those two tables alone; --only simd the table of SIMD levels alone.
// Last, what the implicit step's numerical damping does to the bunny's sway after a poke (every
// other damping off) at 1/240, 1/60 and 1/30 s, against the explicit step; --only sway prints it
// alone.
//
//   bench_solver [--mesh PATH] [--particles N] [--steps N] [--repeats N] [--max-naive-w W]
//                [--only implicit|sway|simd] [--implicit-alone 1] [--moduli E1,E2,...] [--w W] [--demo-step S]
// --implicit-alone 1 leaves the explicit runs out of the implicit table (its iterations and cost
// alone, quicker); --moduli replaces its 30 kPa, 1 MPa, 10 MPa; --w its region half-width 2;
// --demo-step the demo's step, 1/60 s.

#include "deformable_flsm/core/fast_summation.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/simd.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"
#include "bench_solver_implicit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <limits>
#include <ctime>
#include <csignal>
#include <malloc.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <unistd.h>
#include <memory>
#include <string>
#include <thread>
#include <vector>

using namespace deformable_flsm;

namespace {

struct Args {
  std::string mesh = deformable_flsm::kBunnyMeshPath;
  std::size_t particles = 10000;
  int steps = 40;
  int repeats = 11;
  int maxNaiveW = 4;
  bool onlyImplicit = false;
  bool onlySway = false;
  bool onlySimd = false;
  bool implicitAlone = false;
  int regionHalfWidth = 2;  // of the implicit table
  std::vector<double> moduli = {30e3, 1e6, 10e6};
  double demoStep = 1.0 / 60.0;  // the demo table's step (s)
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    const char* v = argv[i + 1];
    if (k == "--mesh") a.mesh = v;
    else if (k == "--particles") a.particles = std::strtoul(v, nullptr, 10);
    else if (k == "--steps") a.steps = std::atoi(v);
    else if (k == "--repeats") a.repeats = std::atoi(v);
    else if (k == "--max-naive-w") a.maxNaiveW = std::atoi(v);
    else if (k == "--only" && std::string(v) == "implicit") a.onlyImplicit = true;
    else if (k == "--only" && std::string(v) == "sway") a.onlySway = true;
    else if (k == "--only" && std::string(v) == "simd") a.onlySimd = true;
    else if (k == "--implicit-alone") a.implicitAlone = std::atoi(v) != 0;
    else if (k == "--w") a.regionHalfWidth = std::max(1, std::atoi(v));
    else if (k == "--demo-step") {
      a.demoStep = std::strtod(v, nullptr);
      if (!(a.demoStep > 0.0 && a.demoStep <= 0.1)) {
        std::fprintf(stderr, "--demo-step: a step in seconds, > 0 and <= 0.1, got %s\n", v);
        std::exit(2);
      }
    }
    else if (k == "--moduli") {
      a.moduli.clear();
      for (const char* c = v; *c != '\0';) {
        char* end = nullptr;
        a.moduli.push_back(std::strtod(c, &end));
        if (end == c || !(a.moduli.back() > 0.0)) {
          std::fprintf(stderr, "--moduli: a comma-separated list of positive moduli (Pa), got %s\n", v);
          std::exit(2);
        }
        c = *end == ',' ? end + 1 : end;
      }
    }
    else {
      std::fprintf(stderr, "unknown option %s\n", k.c_str());
      std::exit(2);
    }
  }
  return a;
}

/// Bytes currently allocated from the heap (glibc).
std::size_t heapInUse() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

using bench::voxelizeNear;

/// A solver in a deformed, moving state (so that the rotation extraction does real work), stepped
/// once, and how many steps make one timed run of it.
struct Timed {
  std::shared_ptr<const Lattice> lattice;
  std::unique_ptr<Solver> solver;
  int steps = 1;
  std::vector<double> samples;  // ns per particle-step of each run

  Timed(std::shared_ptr<const Lattice> l, const SolverParams& params, int runSteps)
      : lattice(std::move(l)), solver(std::make_unique<Solver>(lattice, params)), steps(runSteps) {
    std::vector<Eigen::Vector3d> x = solver->positions();
    for (std::size_t i = 0; i < x.size(); ++i) x[i] += 0.05 * lattice->spacing() * Eigen::Vector3d(std::sin(7.0 * i), std::cos(3.0 * i), std::sin(5.0 * i));
    solver->setPositions(x);
    solver->step();
  }
  /// One untimed run, before the timed ones: a long-running node is past its first steps (the
  /// first touches of its memory, its thread governor's opening of six steps) when it is measured.
  /// threadedShare() counts the steps after it.
  void warmUp() {
    for (int i = 0; i < steps; ++i) solver->step();
    if (const ThreadGovernor* g = solver->threadGovernor()) {
      warmThreaded = g->threadedSteps();
      warmSingle = g->singleSteps();
    }
  }
  std::size_t warmThreaded = 0, warmSingle = 0;  // governor's steps up to the end of warmUp()
  /// One timed run; returns and records its ns per particle-step.
  double run() {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i) solver->step();
    const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
    samples.push_back(ns / (double(steps) * solver->params().substeps * double(lattice->size())));
    return samples.back();
  }
};

/// Steps in one timed run of the sizes and boxes tables: about 50 ms of stepping, at least 2.
int stepsPerRun(const Lattice& lattice) { return std::max(2, static_cast<int>(5e5 / double(lattice.size()))); }

double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x[x.size() / 2];
}

double fastest(const std::vector<double>& x) { return *std::min_element(x.begin(), x.end()); }

/// Runs every entry once per round, `rounds` times, so that a busy spell of the machine hits all
/// entries alike; ratios between entries are taken within a round (see ratioMedian()).
void interleave(std::vector<Timed*> entries, int rounds) {
  for (int r = 0; r < rounds; ++r)
    for (Timed* e : entries) e->run();
}

/// The median over rounds of a's time / b's time in the same round.
double ratioMedian(const Timed& a, const Timed& b) {
  std::vector<double> r;
  for (std::size_t i = 0; i < a.samples.size() && i < b.samples.size(); ++i) r.push_back(a.samples[i] / b.samples[i]);
  return median(r);
}

/// Another process spinning on a core while it lives: the machine as a busy neighbour leaves it.
class BusyLoop {
 public:
  BusyLoop() : pid_(fork()) {
    if (pid_ == 0) {
      volatile unsigned long spin = 0;
      for (;;) spin = spin + 1;
    }
    // Let the scheduler place it before the measurement.
    std::this_thread::sleep_for(std::chrono::milliseconds(20));
  }
  ~BusyLoop() {
    if (pid_ > 0) {
      kill(pid_, SIGKILL);
      waitpid(pid_, nullptr, 0);
    }
  }
  BusyLoop(const BusyLoop&) = delete;
  BusyLoop& operator=(const BusyLoop&) = delete;

 private:
  pid_t pid_;
};

/// The share of a solver's timed steps (after warmUp()) that its governor ran on the threads (1
/// without one).
double threadedShare(const Timed& t) {
  const ThreadGovernor* g = t.solver->threadGovernor();
  if (!g) return 1.0;
  const double threaded = double(g->threadedSteps() - t.warmThreaded);
  const double n = threaded + double(g->singleSteps() - t.warmSingle);
  return n > 0.0 ? threaded / n : 1.0;
}

/// The fast solver (w = 2, one thread) at each SIMD level this CPU runs and the build has code
/// for (simd.h), entries in turns: what the run-time choice gives a build for the x86-64 baseline.
void simdTable(const Voxelization& vox, const Args& args) {
  const SimdLevel chosen = simdLevel();
  std::vector<SimdLevel> levels;
  for (SimdLevel l : {SimdLevel::Baseline, SimdLevel::X86_64_V3, SimdLevel::X86_64_V4})
    if (setSimdLevel(l) == l) levels.push_back(l);
  auto lattice = std::make_shared<const Lattice>(vox, 1000.0, 2);
  SolverParams p;
  p.substeps = 1;
  std::vector<std::unique_ptr<Timed>> entries;
  for (SimdLevel l : levels) {
    setSimdLevel(l);
    entries.push_back(std::make_unique<Timed>(lattice, p, args.steps));
  }
  for (int r = 0; r < args.repeats; ++r)
    for (std::size_t i = 0; i < levels.size(); ++i) {
      setSimdLevel(levels[i]);
      entries[i]->run();
    }
  setSimdLevel(chosen);
  std::printf("\nfast, w=2, single thread, at each SIMD level (median of %d rounds, entries in turns; x chosen: the\n"
              "median of the ratios to the chosen level's run in the same round)\n%12s %12s %10s\n",
              args.repeats, "level", "ns/p-step", "x chosen");
  const std::size_t ref = static_cast<std::size_t>(
      std::find(levels.begin(), levels.end(), chosen) - levels.begin());
  for (std::size_t i = 0; i < levels.size(); ++i)
    std::printf("%12s %12.1f %10.2f\n", toString(levels[i]), median(entries[i]->samples),
                ref < levels.size() ? ratioMedian(*entries[i], *entries[ref]) : 0.0);
}

/// Memory a step works in (bytes per particle).
void memoryLine(const Voxelization& vox) {
  // Memory a step works in: the solver's per-particle state and scratch arrays, measured as the
  // heap growth of building one (lattice and mesh excluded), divided by the particle count.
  auto lattice = std::make_shared<const Lattice>(vox, 1000.0, 2);
  const std::size_t before = heapInUse();
  {
    Solver s(lattice, SolverParams());
    s.step();
    std::printf("solver memory: %.0f bytes per particle (fast, w=2, after one step)\n",
                double(heapInUse() - before) / double(lattice->size()));
  }
}

/// The fast and naive solvers at w = 1 to 4.
void regionWidthTable(const Voxelization& vox, const Args& args) {
  // Every table's entries run in turns (one run each per round, `repeats` rounds): the figures are
  // medians over the rounds, and ratios between entries are medians of the ratios within a round.
  std::printf("single thread, double precision, one sub-step per step, median of %d rounds (entries in turns)\n",
              args.repeats);
  std::printf("%3s %16s %16s %10s\n", "w", "fast ns/p-step", "naive ns/p-step", "naive/fast");
  std::vector<std::unique_ptr<Timed>> fast, naive;
  std::vector<Timed*> all;
  for (int w = 1; w <= 4; ++w) {
    auto lattice = std::make_shared<const Lattice>(vox, 1000.0, w);
    SolverParams p;
    p.regionHalfWidth = w;
    p.substeps = 1;
    p.kind = SolverKind::Fast;
    fast.push_back(std::make_unique<Timed>(lattice, p, args.steps));
    all.push_back(fast.back().get());
    if (w <= args.maxNaiveW) {
      p.kind = SolverKind::Naive;
      naive.push_back(std::make_unique<Timed>(lattice, p, std::max(1, args.steps / (w * w))));
      all.push_back(naive.back().get());
    }
  }
  interleave(all, args.repeats);
  for (int w = 1; w <= 4; ++w) {
    const Timed& f = *fast[static_cast<std::size_t>(w - 1)];
    if (w <= static_cast<int>(naive.size())) {
      const Timed& n = *naive[static_cast<std::size_t>(w - 1)];
      std::printf("%3d %16.1f %16.1f %10.1f\n", w, median(f.samples), median(n.samples), ratioMedian(n, f));
    } else {
      std::printf("%3d %16.1f %16s %10s\n", w, median(f.samples), "-", "-");
    }
  }
  std::printf("fast w=4 / w=1 cost ratio: %.2f\n", ratioMedian(*fast[3], *fast[0]));
}

/// The fast solver across lattice sizes, 1k to 200k particles.
void sizeTable(const TriMesh& mesh, const Args& args) {
  std::printf("\nfast, w=2, single thread, across lattice sizes (median and fastest of %d rounds; x 10k: the\n"
              "median of the ratios to the 10k lattice's run in the same round)\n%10s %10s %16s %10s %8s %14s\n",
              args.repeats, "particles", "resolution", "ns/p-step", "fastest", "x 10k", "ms per step");
  std::vector<std::unique_ptr<Timed>> sizes;
  std::vector<int> resolution;
  std::size_t reference = 0;
  for (std::size_t target : {1000u, 5000u, 10000u, 50000u, 100000u, 200000u}) {
    const Voxelization v = voxelizeNear(mesh, target);
    auto lat = std::make_shared<const Lattice>(v, 1000.0, 2);
    SolverParams q;
    q.substeps = 1;
    if (target == 10000u) reference = sizes.size();
    sizes.push_back(std::make_unique<Timed>(lat, q, stepsPerRun(*lat)));
    resolution.push_back(v.dims.maxCoeff());
  }
  std::vector<Timed*> all;
  for (auto& t : sizes) all.push_back(t.get());
  interleave(all, args.repeats);
  for (std::size_t i = 0; i < sizes.size(); ++i) {
    const Timed& t = *sizes[i];
    const double ns = median(t.samples);
    std::printf("%10zu %10d %16.1f %10.1f %8.2f %14.2f\n", t.lattice->size(), resolution[i], ns, fastest(t.samples),
                ratioMedian(t, *sizes[reference]), ns * double(t.lattice->size()) * 1e-6);
  }
}

/// The fast solver on boxes of full cells.
void boxTable(const Args& args) {
  // Boxes of full cells: the cost per particle against the particle count with the slices' cross-
  // section held, and against the cross-section with the count held (the region pass's working set
  // is a few slices: 2w + 2 in each direction's ring, and the slice buffers).
  std::printf("\nfast, w=2, single thread, boxes of full cells (median of %d rounds; x first: the median of the\n"
              "ratios to the first box's run in the same round)\n%16s %10s %8s %12s %8s %6s\n",
              args.repeats, "box", "particles", "slice", "ns/p-step", "x first", "bands");
  std::vector<std::unique_ptr<Timed>> boxes;
  const std::vector<Eigen::Vector3i> dims = {{20, 20, 25}, {20, 20, 125}, {20, 20, 500},
                                             {30, 30, 220}, {45, 45, 100}, {64, 64, 49}};
  for (const Eigen::Vector3i& d : dims) {
    auto lat = std::make_shared<const Lattice>(boxVoxels(d, 0.01), 1000.0, 2);
    SolverParams q;
    q.substeps = 1;
    boxes.push_back(std::make_unique<Timed>(lat, q, stepsPerRun(*lat)));
  }
  std::vector<Timed*> all;
  for (auto& t : boxes) all.push_back(t.get());
  interleave(all, args.repeats);
  for (std::size_t i = 0; i < boxes.size(); ++i) {
    const Timed& t = *boxes[i];
    const Eigen::Vector3i& d = dims[i];
    const std::string name = std::to_string(d.x()) + " x " + std::to_string(d.y()) + " x " + std::to_string(d.z());
    std::printf("%16s %10zu %8d %12.1f %8.2f %6zu\n", name.c_str(), t.lattice->size(), d.x() * d.y(),
                median(t.samples), ratioMedian(t, *boxes[0]), SliceStreamSummer(*t.lattice).bandCount());
  }
}

/// A row of the busy table: one thread and every thread beside another process's busy loop.
struct BusyRow {
  std::size_t particles;
  double one, all, cost, threaded, diff, msThreads, msOne;
};

/// The threads' quiet row for lattice `v` (printed) and their busy row (returned), `hw` threads.
BusyRow threadRow(const TriMesh& mesh, const Voxelization& v, const Args& args, unsigned hw) {
  auto lat = std::make_shared<const Lattice>(v, 1000.0, 2);
  SolverParams p;
  p.substeps = 1;
  // At least 20 steps a run: the governor's probes are a few steps in a hundred.
  const int steps = std::max(20, static_cast<int>(1e8 / (400.0 * double(lat->size()))));
  Timed one(lat, p, steps), oneBusy(lat, p, steps);
  // The machine's ceiling: hw independent one-thread solvers of 1/hw of the particles each (the
  // same state and work in all as the one lattice), one after the other, then at once.
  const Voxelization part = voxelizeNear(mesh, lat->size() / hw);
  auto partLattice = std::make_shared<const Lattice>(part, 1000.0, 2);
  std::vector<std::unique_ptr<Timed>> apart;
  for (unsigned k = 0; k < hw; ++k) apart.push_back(std::make_unique<Timed>(partLattice, p, steps));
  p.threads = static_cast<int>(hw);
  Timed all(lat, p, steps), allBusy(lat, p, steps);
  one.warmUp();
  all.warmUp();
  for (auto& a : apart) a->warmUp();
  {
    const BusyLoop busy;
    oneBusy.warmUp();
    allBusy.warmUp();
  }
  std::vector<double> machine, ofMachine;
  for (int r = 0; r < 3 * args.repeats; ++r) {
    one.run();
    all.run();
    const auto t0 = std::chrono::steady_clock::now();
    for (auto& a : apart) a->run();
    const auto t1 = std::chrono::steady_clock::now();
    std::vector<std::thread> others;
    for (std::size_t k = 1; k < apart.size(); ++k) others.emplace_back([&apart, k] { apart[k]->run(); });
    apart[0]->run();
    for (auto& t : others) t.join();
    const auto t2 = std::chrono::steady_clock::now();
    machine.push_back(std::chrono::duration<double>(t1 - t0).count() / std::chrono::duration<double>(t2 - t1).count());
    ofMachine.push_back(one.samples.back() / all.samples.back() / machine.back());
    {
      const BusyLoop busy;
      oneBusy.run();
      allBusy.run();
    }
  }
  double diff = 0.0;
  for (std::size_t i = 0; i < lat->size(); ++i)
    diff = std::max(diff, (one.solver->positions()[i] - all.solver->positions()[i]).norm());
  std::printf("%10zu %14.1f %14.1f %8.2fx %8.2fx %8.2fx %9.0f%% %8.0f%% %22.3g\n", lat->size(), median(one.samples),
              median(all.samples), ratioMedian(one, all), fastest(one.samples) / fastest(all.samples),
              median(machine), 100.0 * median(ofMachine), 100.0 * threadedShare(all), diff);
  double busyDiff = 0.0;
  for (std::size_t i = 0; i < lat->size(); ++i)
    busyDiff = std::max(busyDiff, (oneBusy.solver->positions()[i] - allBusy.solver->positions()[i]).norm());
  const ThreadGovernor* g = allBusy.solver->threadGovernor();
  return {lat->size(), median(oneBusy.samples), median(allBusy.samples), ratioMedian(allBusy, oneBusy),
          threadedShare(allBusy), busyDiff, g ? 1e3 * g->recentSeconds(true) : 0.0,
          g ? 1e3 * g->recentSeconds(false) : 0.0};
}

/// Every hardware thread against one, quiet and beside a busy loop.
void threadTables(const TriMesh& mesh, const Voxelization& vox, const Args& args) {
  // Threads: every hardware thread against one, at the benchmark's size and at 50k particles,
  // on the machine as it is (quiet, one hopes) and with a busy loop of our own in another
  // process (one core taken), in the same rounds. The threaded solvers choose per step between
  // their threads and one thread (ThreadGovernor); the busy entries keep their own solvers, so
  // that each governor sees one condition, as a long-running node would.
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  std::printf("\nfast, w=2: %u threads against 1 (same results required; speed-up: median of the ratios within a\n"
              "round; fastest: the fastest run of one thread against the fastest of all, what the threads give\n"
              "when the machine leaves both cores alone; machine: %u independent one-thread solvers, each of 1/%u\n"
              "of the particles, stepped at once against one after the other in the same rounds: what this\n"
              "machine's cores give just then to the same work when nothing waits for anything; of machine:\n"
              "the median of the speed-up / machine ratios within a round; threaded: the share of the steps\n"
              "the governor ran on the threads)\n%10s %14s %14s %9s %9s %9s %10s %9s %22s\n",
              hw, hw, hw, "particles", "1: ns/p-step", "all: ns/p-step", "speed-up", "fastest", "machine", "of machine",
              "threaded", "max position difference");
  std::vector<BusyRow> busyRows;
  for (std::size_t target : {args.particles, std::size_t{50000}})
    busyRows.push_back(threadRow(mesh, target == args.particles ? vox : voxelizeNear(mesh, target), args, hw));
  std::printf("\nthe same with another process spinning on one core (started before and stopped after each\n"
              "entry's run, in the same rounds as above; cost: median of the all / 1 time ratios within a round;\n"
              "governor: the threaded solver's recent median step on the threads and on one thread)\n"
              "%10s %14s %14s %9s %9s %22s %22s\n",
              "particles", "1: ns/p-step", "all: ns/p-step", "cost", "threaded", "governor: threads/one", "max position difference");
  for (const BusyRow& b : busyRows)
    std::printf("%10zu %14.1f %14.1f %8.2fx %8.0f%% %11.2f / %.2f ms %22.3g\n", b.particles, b.one, b.all, b.cost,
                100.0 * b.threaded, b.msThreads, b.msOne, b.diff);
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  const TriMesh mesh = loadMesh(args.mesh, 0.1);
  const Voxelization vox = voxelizeNear(mesh, args.particles);
  std::printf("mesh %s: %zu triangles; lattice %d x %d x %d cells, spacing %.4g m, %zu particles\n%s\n",
              args.mesh.c_str(), mesh.triangles.size(), vox.dims.x(), vox.dims.y(), vox.dims.z(), vox.spacing,
              vox.cells.size(), simdLevelNote().c_str());
  if (args.onlySway) {
    bench::swayTable(mesh, args.particles);
    return 0;
  }
  if (args.onlySimd) {
    simdTable(vox, args);
    return 0;
  }
  if (args.onlyImplicit) {
    bench::implicitTable(mesh, args.particles, args.regionHalfWidth, args.moduli, args.implicitAlone);
    bench::demoTable(mesh, args.particles, args.demoStep);
    return 0;
  }
  memoryLine(vox);
  regionWidthTable(vox, args);
  simdTable(vox, args);
  sizeTable(mesh, args);
  boxTable(args);
  threadTables(mesh, vox, args);
  bench::implicitTable(mesh, args.particles, args.regionHalfWidth, args.moduli, args.implicitAlone);
  bench::demoTable(mesh, args.particles, args.demoStep);
  bench::swayTable(mesh, args.particles);
  return 0;
}
