// Prints the cost of a FastLSM solver step, in ns per particle-step, for the fast and naive
// solvers at region half-widths w = 1..4, on the bunny voxelized to about --particles particles.
// A benchmark, not a test: it prints figures and never fails because the machine is slow.
//
// Then the fast solver at w = 2 across lattice sizes (1k to 200k particles: cost per particle
// should stay flat), and with every hardware thread against one thread (same results) at the
// benchmark's size and at 50k particles. Threads pay only on idle cores: a sub-step's region
// pass has one barrier, and a worker that another process has descheduled stalls it for a time
// slice (the chunk boundaries follow a slower thread, a descheduled one they cannot). Run it on
// a quiet machine; SolverParams::threads defaults to 1 for that reason.
//
//   bench_solver [--mesh PATH] [--particles N] [--steps N] [--repeats N] [--max-naive-w W]

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <malloc.h>
#include <string>
#include <thread>
#include <vector>

using namespace deformable_flsm;

namespace {

struct Args {
  std::string mesh = "/usr/share/glmark2/models/bunny.obj";
  std::size_t particles = 10000;
  int steps = 40;
  int repeats = 11;
  int maxNaiveW = 4;
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

/// The voxelization whose particle count is nearest to `target`.
Voxelization voxelizeNear(const TriMesh& mesh, std::size_t target) { return nearestResolution(mesh, target).voxels; }

/// Median ns per particle-step over `repeats` runs of `steps` steps, after one warm-up step;
/// the fastest run in `best` if given (what the step costs when the machine leaves it alone).
double measure(const std::shared_ptr<const Lattice>& lattice, const SolverParams& params, int steps,
               int repeats, std::vector<Eigen::Vector3d>* finalPositions = nullptr, double* best = nullptr) {
  Solver s(lattice, params);
  // a deformed, moving state so that the rotation extraction does real work
  std::vector<Eigen::Vector3d> x = s.positions();
  for (std::size_t i = 0; i < x.size(); ++i) x[i] += 0.05 * lattice->spacing() * Eigen::Vector3d(std::sin(7.0 * i), std::cos(3.0 * i), std::sin(5.0 * i));
  s.setPositions(x);
  s.step();
  std::vector<double> samples;
  for (int r = 0; r < repeats; ++r) {
    const auto t0 = std::chrono::steady_clock::now();
    for (int i = 0; i < steps; ++i) s.step();
    const auto t1 = std::chrono::steady_clock::now();
    const double ns = std::chrono::duration<double, std::nano>(t1 - t0).count();
    samples.push_back(ns / (double(steps) * params.substeps * double(lattice->size())));
  }
  if (finalPositions != nullptr) *finalPositions = s.positions();
  std::sort(samples.begin(), samples.end());
  if (best != nullptr) *best = samples.front();
  return samples[samples.size() / 2];
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  const TriMesh mesh = loadMesh(args.mesh, 0.1);
  const Voxelization vox = voxelizeNear(mesh, args.particles);
  std::printf("mesh %s: %zu triangles; lattice %d x %d x %d cells, spacing %.4g m, %zu particles\n",
              args.mesh.c_str(), mesh.triangles.size(), vox.dims.x(), vox.dims.y(), vox.dims.z(), vox.spacing,
              vox.cells.size());
  {
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
  std::printf("single thread, double precision, one sub-step per step, median of %d runs of %d steps\n",
              args.repeats, args.steps);
  std::printf("%3s %16s %16s %10s\n", "w", "fast ns/p-step", "naive ns/p-step", "naive/fast");
  double fast1 = 0.0;
  for (int w = 1; w <= 4; ++w) {
    auto lattice = std::make_shared<const Lattice>(vox, 1000.0, w);
    SolverParams p;
    p.regionHalfWidth = w;
    p.substeps = 1;
    p.kind = SolverKind::Fast;
    const double fast = measure(lattice, p, args.steps, args.repeats);
    if (w == 1) fast1 = fast;
    if (w <= args.maxNaiveW) {
      p.kind = SolverKind::Naive;
      const double naive = measure(lattice, p, std::max(1, args.steps / (w * w)), args.repeats);
      std::printf("%3d %16.1f %16.1f %10.1f\n", w, fast, naive, naive / fast);
    } else {
      std::printf("%3d %16.1f %16s %10s\n", w, fast, "-", "-");
    }
    if (w == 4) std::printf("fast w=4 / w=1 cost ratio: %.2f\n", fast / fast1);
  }

  std::printf("\nfast, w=2, single thread, across lattice sizes (median and fastest of %d runs)\n%10s %10s %16s %10s %14s\n",
              args.repeats, "particles", "resolution", "ns/p-step", "fastest", "ms per step");
  for (std::size_t target : {1000u, 5000u, 10000u, 50000u, 100000u, 200000u}) {
    const Voxelization v = voxelizeNear(mesh, target);
    auto lat = std::make_shared<const Lattice>(v, 1000.0, 2);
    SolverParams q;
    q.substeps = 1;
    // about 0.1 s of stepping per run, at least 2 steps
    const int steps = std::max(2, static_cast<int>(1e8 / (400.0 * double(lat->size()))));
    double fastest = 0.0;
    const double ns = measure(lat, q, steps, args.repeats, nullptr, &fastest);
    std::printf("%10zu %10d %16.1f %10.1f %14.2f\n", lat->size(), v.dims.maxCoeff(), ns, fastest,
                ns * double(lat->size()) * 1e-6);
  }

  // Threads: every hardware thread against one, at the benchmark's size and at 50k particles.
  const unsigned hw = std::max(1u, std::thread::hardware_concurrency());
  std::printf("\nfast, w=2: %u threads against 1 (same results required)\n%10s %14s %14s %9s %22s\n", hw,
              "particles", "1: ns/p-step", "all: ns/p-step", "speed-up", "max position difference");
  for (std::size_t target : {args.particles, std::size_t{50000}}) {
    const Voxelization v = target == args.particles ? vox : voxelizeNear(mesh, target);
    auto lat = std::make_shared<const Lattice>(v, 1000.0, 2);
    SolverParams p;
    p.substeps = 1;
    const int steps = std::max(5, static_cast<int>(1e8 / (400.0 * double(lat->size()))));
    // the two solvers step in turns, so that a busy spell of the machine hits both alike; the
    // speed-up is the median of the turns' ratios
    Solver one(lat, p);
    p.threads = static_cast<int>(hw);
    Solver all(lat, p);
    for (Solver* s : {&one, &all}) {
      std::vector<Eigen::Vector3d> x = s->positions();
      for (std::size_t i = 0; i < x.size(); ++i) x[i] += 0.05 * lat->spacing() * Eigen::Vector3d(std::sin(7.0 * i), std::cos(3.0 * i), std::sin(5.0 * i));
      s->setPositions(x);
      s->step();
    }
    auto time = [&](Solver& s) {
      const auto t0 = std::chrono::steady_clock::now();
      for (int i = 0; i < steps; ++i) s.step();
      return std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count() /
             (double(steps) * double(lat->size()));
    };
    std::vector<double> t1, tn, ratio;
    for (int r = 0; r < 3 * args.repeats; ++r) {
      t1.push_back(time(one));
      tn.push_back(time(all));
      ratio.push_back(t1.back() / tn.back());
    }
    double diff = 0.0;
    for (std::size_t i = 0; i < lat->size(); ++i) diff = std::max(diff, (one.positions()[i] - all.positions()[i]).norm());
    auto median = [](std::vector<double> x) {
      std::sort(x.begin(), x.end());
      return x[x.size() / 2];
    };
    std::printf("%10zu %14.1f %14.1f %8.2fx %22.3g\n", lat->size(), median(t1), median(tn), median(ratio), diff);
  }
  return 0;
}
