// Prints what a World of several objects costs against its objects stepped alone, and what the
// contact between them adds; then a bin of many small objects against real time. Objects: the
// bunny scaled to 5 cm and voxelized at --resolution cells along its longest axis (about 150
// particles at 7), classic FastLSM (alpha 1, w = 1), 30 Hz in 8 sub-steps (--substeps), one thread; render
// mesh: the bunny simplified to --triangles triangles (meshoptimizer, as the node does), embedded
// in each object's lattice (core/embedding.h).
//   1. N objects: "alone" one object resting on the ground stepped by a bare Solver, times N;
//      "apart" a World of N objects resting on the ground apart from each other (no object
//      contact: the broad phase's cost); "pile" a World of N objects dropped into a bin and
//      settled, touching each other (object contact's cost). Ratios: apart / (N alone), and pile /
//      apart, the contact's share; the pile's list builds and Gauss-Seidel passes per sub-step.
//   2. The bin of --objects objects while they fall and tumble, and settled: ms per step and
//      per frame at 30 Hz with the render meshes' update, against FastLSM's 150 penguins of 150
//      particles at 25 frames per second on a Pentium 4 (Rivers & James 2007, figure 1).
//   3. The same bin with sleeping objects (World::setSleepParams(), the node's ~object_sleep):
//      settled, how many sleep and what a step costs; then a finger (a 2 cm sphere) pressed down
//      at 2 cm/s 3 cm into the pile a quarter of the way in from a corner: what the objects it
//      wakes cost.
// Times are the thread's CPU time (the machine is shared: wall time would count the waits).
// A benchmark, not a test: it prints figures and never fails because the machine is slow.
// Entries run in turns, one run each per round; figures are medians over the rounds.
//
//   bench_world [--resolution R] [--objects N] [--triangles T] [--substeps S] [--passes P] [--rounds K]
//               [--only sizes|bin]
//
// --passes: the object contact's Gauss-Seidel passes per sub-step at most (ObjectContactParams::iterations).

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"
#include "deformable_flsm/core/world.h"

#include <meshoptimizer.h>

#include <algorithm>
#include <ctime>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <functional>
#include <memory>
#include <random>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

struct Args {
  int resolution = 7;
  int objects = 150;
  std::size_t triangles = 1000;
  int rounds = 3;
  std::string only;  // "sizes" or "bin": that part alone
};

// sub-steps per step and contact passes per sub-step at most: set once from --substeps and
// --passes, before anything is built
int substepsPerStep = 8;
int passesPerSubstep = ObjectContactParams().iterations;

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    const char* v = argv[i + 1];
    if (k == "--resolution") a.resolution = std::max(2, std::atoi(v));
    else if (k == "--objects") a.objects = std::max(1, std::atoi(v));
    else if (k == "--triangles") a.triangles = std::max<std::size_t>(4, std::strtoul(v, nullptr, 10));
    else if (k == "--substeps") substepsPerStep = std::max(1, std::atoi(v));
    else if (k == "--passes") passesPerSubstep = std::max(1, std::atoi(v));
    else if (k == "--rounds") a.rounds = std::max(1, std::atoi(v));
    else if (k == "--only" && (std::string(v) == "sizes" || std::string(v) == "bin")) a.only = v;
    else {
      std::fprintf(stderr, "unknown option %s\n", k.c_str());
      std::exit(2);
    }
  }
  return a;
}

double median(std::vector<double> x) {
  std::sort(x.begin(), x.end());
  return x[x.size() / 2];
}

constexpr double kStep = 1.0 / 30.0;
constexpr double kSize = 0.05;  // the bunny's longest extent (m)

/// A World of kStep in substepsPerStep sub-steps, its object contact's passes at most
/// passesPerSubstep, its contact's parts timed (World::contactTimes()).
std::unique_ptr<World> makeWorld() {
  ObjectContactParams contact;
  contact.iterations = passesPerSubstep;
  auto world = std::make_unique<World>(kStep, substepsPerStep, contact);
  world->setContactTiming(true);
  return world;
}

/// The object: the bunny at kSize, Z up, its lower corner at the origin, voxelized; its render
/// mesh simplified.
struct Shape {
  Voxelization voxels;
  std::vector<Eigen::Vector3d> renderVertices;
  std::size_t renderTriangles = 0;
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();
};

Shape makeShape(const Args& args) {
  TriMesh mesh = loadMesh(kBunnyMeshPath, 1.0);
  for (auto& v : mesh.vertices) v = Eigen::Vector3d(v.x(), -v.z(), v.y());
  const Eigen::Vector3d lo = mesh.boundsMin(), hi = mesh.boundsMax();
  const double scale = kSize / (hi - lo).maxCoeff();
  for (auto& v : mesh.vertices) v = (v - lo) * scale;
  Shape shape;
  shape.extent = (hi - lo) * scale;
  VoxelizeOptions options;
  options.resolution = args.resolution;
  shape.voxels = voxelize(mesh, options);
  // the render mesh as the node simplifies it (meshopt_simplify on float positions)
  std::vector<float> positions;
  for (const auto& v : mesh.vertices)
    for (int a = 0; a < 3; ++a) positions.push_back(static_cast<float>(v[a]));
  std::vector<unsigned> indices;
  for (const auto& t : mesh.triangles)
    for (int a = 0; a < 3; ++a) indices.push_back(t[a]);
  std::vector<unsigned> simplified(indices.size());
  const std::size_t count =
      meshopt_simplify(simplified.data(), indices.data(), indices.size(), positions.data(), mesh.vertices.size(),
                       3 * sizeof(float), 3 * args.triangles, 0.05f, 0, nullptr);
  std::vector<char> used(mesh.vertices.size(), 0);
  for (std::size_t i = 0; i < count; ++i) used[simplified[i]] = 1;
  for (std::size_t v = 0; v < used.size(); ++v)
    if (used[v]) shape.renderVertices.push_back(mesh.vertices[v]);
  shape.renderTriangles = count / 3;
  return shape;
}

SolverParams params(const Lattice& lattice) {
  SolverParams p;
  p.regionHalfWidth = lattice.regionHalfWidth();
  p.stiffness = 1.0;
  p.timeStep = kStep;
  p.substeps = substepsPerStep;
  p.ambientDamping = 2.0;
  return p;
}

/// The shape's lattice and render vertices moved by `offset` (a translation of the grid: the
/// same cells).
struct Placed {
  std::shared_ptr<const Lattice> lattice;
  std::vector<Eigen::Vector3d> vertices;
};

Placed place(const Shape& shape, const Eigen::Vector3d& offset) {
  Voxelization v = shape.voxels;
  v.origin += offset;
  Placed p;
  p.lattice = std::make_shared<const Lattice>(v, 1000.0, 1);
  p.vertices = shape.renderVertices;
  for (auto& x : p.vertices) x += offset;
  return p;
}

Collider groundCollider() { return Collider(); }

Collider boxCollider(const Eigen::Vector3d& centre, const Eigen::Vector3d& half) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = half;
  c.pose.translation() = centre;
  return c;
}

/// N objects on the ground in a square grid, two sizes apart.
std::unique_ptr<World> apart(const Shape& shape, int n) {
  auto world = makeWorld();
  world->setCollider("ground", groundCollider());
  const int side = static_cast<int>(std::ceil(std::sqrt(double(n))));
  for (int i = 0; i < n; ++i) {
    const Placed p = place(shape, Eigen::Vector3d(2.0 * kSize * (i % side), 2.0 * kSize * (i / side), 0.0));
    world->addObject("o" + std::to_string(i), p.lattice, params(*p.lattice));
  }
  return world;
}

/// A bin of floor and four walls sized for n objects in about three layers, the objects in a grid of layers above
/// its floor, each spinning; `vertices` receives each object's render vertices.
std::unique_ptr<World> bin(const Shape& shape, int n, std::vector<Placed>* placed) {
  auto world = makeWorld();
  const int side = std::max(1, static_cast<int>(std::lround(std::sqrt(n / 3.0))));
  const double pitch = 1.15 * shape.extent.head<2>().maxCoeff();
  const double inner = 0.5 * side * pitch + 0.01, wall = 0.05, height = 0.3;
  world->setCollider("floor", boxCollider(Eigen::Vector3d(0, 0, -wall), Eigen::Vector3d(inner + 2 * wall, inner + 2 * wall, wall)));
  world->setCollider("wall_x+", boxCollider(Eigen::Vector3d(inner + wall, 0, height / 2), Eigen::Vector3d(wall, inner + 2 * wall, height / 2)));
  world->setCollider("wall_x-", boxCollider(Eigen::Vector3d(-inner - wall, 0, height / 2), Eigen::Vector3d(wall, inner + 2 * wall, height / 2)));
  world->setCollider("wall_y+", boxCollider(Eigen::Vector3d(0, inner + wall, height / 2), Eigen::Vector3d(inner + 2 * wall, wall, height / 2)));
  world->setCollider("wall_y-", boxCollider(Eigen::Vector3d(0, -inner - wall, height / 2), Eigen::Vector3d(inner + 2 * wall, wall, height / 2)));
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < n; ++i) {
    const int layer = i / (side * side), k = i % (side * side);
    const double shift = layer % 2 == 0 ? 0.0 : 0.3 * pitch;
    const Eigen::Vector3d offset(-inner + 0.01 + pitch * (k % side) + 0.5 * shift, -inner + 0.01 + pitch * (k / side) + shift,
                                 0.005 + 1.2 * shape.extent.z() * layer);
    Placed p = place(shape, offset);
    Solver& s = world->addObject("o" + std::to_string(i), p.lattice, params(*p.lattice));
    const Eigen::Vector3d centre = offset + 0.5 * shape.extent;
    const Eigen::Vector3d spin = 4.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    std::vector<Eigen::Vector3d> v(p.lattice->size());
    for (std::size_t j = 0; j < v.size(); ++j) v[j] = spin.cross(s.positions()[j] - centre);
    s.setVelocities(v);
    if (placed) placed->push_back(std::move(p));
  }
  return world;
}

/// CPU time of this thread (s): on a machine shared with other jobs, the time the work took
/// rather than the time it waited for a core.
double threadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

double secondsOf(const std::function<void()>& f) {
  const double t0 = threadSeconds();
  f();
  return threadSeconds() - t0;
}

/// The deepest overlap of two particle spheres of different objects (fraction of the radius),
/// brute force over the pairs of objects whose bounds meet.
double deepestOverlap(const World& world) {
  const auto& names = world.objectNames();
  std::vector<Eigen::Vector3d> lo, hi;
  for (const std::string& n : names) {
    const Solver& s = *world.object(n);
    Eigen::Vector3d l = s.positions()[0], h = l;
    for (const auto& x : s.positions()) {
      l = l.cwiseMin(x);
      h = h.cwiseMax(x);
    }
    lo.push_back(l.array() - 2.0 * s.contactRadius());
    hi.push_back(h.array() + 2.0 * s.contactRadius());
  }
  double deepest = 0.0;
  for (std::size_t a = 0; a < names.size(); ++a)
    for (std::size_t b = a + 1; b < names.size(); ++b) {
      if ((lo[a].array() > hi[b].array()).any() || (lo[b].array() > hi[a].array()).any()) continue;
      const Solver& A = *world.object(names[a]);
      const Solver& B = *world.object(names[b]);
      const double R = A.contactRadius() + B.contactRadius();
      for (const auto& x : A.positions())
        for (const auto& y : B.positions()) deepest = std::max(deepest, (R - (x - y).norm()) / A.contactRadius());
    }
  return deepest;
}

/// Means per sub-step over a phase of `frames` steps that took `stepSeconds` in all: the object
/// contact's parts, and the rest of the step (the objects' own sub-steps, mostly).
void printParts(const World& world, const World::ContactTimes& before, double stepSeconds, int frames) {
  const World::ContactTimes t = world.contactTimes().since(before);
  const double n = double(frames) * substepsPerStep, contact = t.list + t.pairs + t.passes + t.rest;
  std::printf("    per sub-step (means): objects and the rest of the step %.2f ms; object contact %.2f ms: candidate list "
              "%.2f ms, contacts found %.2f ms, passes %.2f ms, the rest %.2f ms\n",
              1e3 * (stepSeconds - contact) / n, 1e3 * contact / n, 1e3 * t.list / n, 1e3 * t.pairs / n, 1e3 * t.passes / n,
              1e3 * t.rest / n);
}

double sum(const std::vector<double>& x) {
  double s = 0.0;
  for (double v : x) s += v;
  return s;
}

std::size_t pairContacts(const World& world) {
  std::size_t c = 0;
  for (const ObjectPairWrench& w : world.objectWrenches()) c += w.wrench.contacts;
  return c / 2;
}

/// Prints table 1: N objects alone, apart and in a pile, ms per step and the pile's contact figures.
void sizesTable(const Shape& shape, const Args& args) {
  const int steps = 20;
  std::printf("\nN objects: ms per step (median of %d rounds of %d steps)\n", args.rounds, steps);
  std::printf("%6s %10s %10s %10s %12s %12s %14s %10s %12s %8s\n", "N", "N x alone", "apart", "pile", "apart/Nx1",
              "pile/apart", "pile contacts", "overlap/r", "list builds", "passes");
  for (int n : {1, 10, 50, args.objects}) {
    const Placed one = place(shape, Eigen::Vector3d::Zero());
    Solver alone(one.lattice, params(*one.lattice));
    alone.setCollider("ground", groundCollider());
    auto spread = apart(shape, n);
    auto pile = bin(shape, n, nullptr);
    for (int i = 0; i < 90; ++i) {  // settle: 3 s
      alone.step();
      spread->step();
      pile->step();
    }
    std::vector<double> tAlone, tApart, tPile, ratioApart, ratioPile;
    const std::size_t builds0 = pile->contactListBuilds();
    const World::ContactPasses passes0 = pile->contactPasses();
    for (int r = 0; r < args.rounds; ++r) {
      const double a = n * secondsOf([&] { for (int i = 0; i < steps; ++i) alone.step(); }) / steps;
      const double b = secondsOf([&] { for (int i = 0; i < steps; ++i) spread->step(); }) / steps;
      const double c = secondsOf([&] { for (int i = 0; i < steps; ++i) pile->step(); }) / steps;
      tAlone.push_back(a);
      tApart.push_back(b);
      tPile.push_back(c);
      ratioApart.push_back(b / a);
      ratioPile.push_back(c / b);
    }
    // the pile's candidate list builds per sub-step over the timed steps
    const double builds = double(pile->contactListBuilds() - builds0) / (args.rounds * steps * substepsPerStep);
    std::printf("%6d %10.3f %10.3f %10.3f %12.3f %12.3f %14zu %10.3f %12.2f %8.2f\n", n, 1e3 * median(tAlone),
                1e3 * median(tApart), 1e3 * median(tPile), median(ratioApart), median(ratioPile), pairContacts(*pile),
                deepestOverlap(*pile), builds, pile->contactPasses().since(passes0).perSubstep());
  }
}

/// The bin of tables 2 and 3: its World, its objects as placed, and their render meshes embedded in
/// the first bin's lattices (table 3's bin places its objects alike).
struct RenderedBin {
  std::vector<Placed> placed;
  std::unique_ptr<World> world;
  std::vector<Embedding> embeddings;
  std::vector<std::vector<Eigen::Vector3d>> vertices;

  /// One step and the render meshes' update: the CPU seconds of each.
  std::pair<double, double> frame() {
    const double step = secondsOf([&] { world->step(); });
    const double render = secondsOf([&] {
      for (std::size_t o = 0; o < placed.size(); ++o) {
        const Solver& s = *world->object(world->objectNames()[o]);
        embeddings[o].deform(s.positions(), s.regionRotations(), vertices[o]);
      }
    });
    return std::make_pair(step, render);
  }
};

/// Prints table 2: the bin falling and settled, ms per step and per frame against real time.
void realTimeTable(RenderedBin& scene, const Shape& shape, const Args& args) {
  std::size_t particles = 0;
  for (const Placed& p : scene.placed) particles += p.lattice->size();
  std::printf("\nbin of %d objects, %zu particles, %zu render vertices per frame:\n", args.objects, particles,
              scene.placed.size() * shape.renderVertices.size());
  for (const char* phase : {"falling (first 1.5 s)", "settled (after 4 s)"}) {
    std::vector<double> step, render;
    const int frames = 45;
    const std::size_t builds0 = scene.world->contactListBuilds();
    const World::ContactPasses passes0 = scene.world->contactPasses();
    const World::ContactTimes times0 = scene.world->contactTimes();
    for (int f = 0; f < frames; ++f) {
      const auto t = scene.frame();
      step.push_back(t.first);
      render.push_back(t.second);
    }
    // over the timed frames only
    const double builds = double(scene.world->contactListBuilds() - builds0) / (frames * substepsPerStep);
    const double passes = scene.world->contactPasses().since(passes0).perSubstep();
    const double ms = 1e3 * median(step), msr = 1e3 * median(render);
    std::printf("  %-22s step %.2f ms, render meshes %.2f ms, frame %.2f ms (%s 33.3 ms at 30 Hz), %.3f ms per "
                "object, object contacts %zu, deepest overlap %.3f r, list builds per sub-step %.2f, contact passes "
                "per sub-step %.2f\n",
                phase, ms, msr, ms + msr, ms + msr <= 1e3 / 30.0 ? "within" : "over", (ms + msr) / args.objects,
                pairContacts(*scene.world), deepestOverlap(*scene.world), builds, passes);
    printParts(*scene.world, times0, sum(step), frames);
    if (phase[0] == 'f')
      for (int f = 0; f < 75; ++f) scene.world->step();  // on to 4 s
  }
  std::printf("  FastLSM's penguins: 150 objects of 150 particles at 25 frames per second on a Pentium 4, 0.27 ms per "
              "object per frame, no contact between them\n");
}

/// Prints a row of table 3: 45 frames of the sleeping bin, `before` called before each. Also: the
/// objects awake at some step of the phase, and how many of them moved less than 0.03 r
/// (mass-weighted RMS) over it.
void sleepRow(RenderedBin& scene, const char* phase, const std::function<void()>& before) {
  std::vector<double> step, render;
  std::size_t awake = 0;
  const int frames = 45;
  const std::vector<std::string> names = scene.world->objectNames();
  std::vector<std::vector<Eigen::Vector3d>> start;
  for (const std::string& name : names) start.push_back(scene.world->object(name)->positions());
  std::vector<char> woke(names.size(), 0);
  const World::ContactTimes times0 = scene.world->contactTimes();
  for (int f = 0; f < frames; ++f) {
    before();
    const auto t = scene.frame();
    step.push_back(t.first);
    render.push_back(t.second);
    awake = std::max(awake, scene.placed.size() - scene.world->sleepingCount());
    for (std::size_t o = 0; o < names.size(); ++o) woke[o] |= !scene.world->asleep(names[o]);
  }
  std::size_t woken = 0, still = 0;
  for (std::size_t o = 0; o < names.size(); ++o) {
    if (!woke[o]) continue;
    const Solver& s = *scene.world->object(names[o]);
    const auto& m = s.lattice().masses();
    double d = 0.0, mass = 0.0;
    for (std::size_t i = 0; i < m.size(); ++i) {
      d += m[i] * (s.positions()[i] - start[o][i]).squaredNorm();
      mass += m[i];
    }
    ++woken;
    if (std::sqrt(d / mass) < 0.03 * s.contactRadius()) ++still;
  }
  const double ms = 1e3 * median(step), msr = 1e3 * median(render);
  std::printf("  %-30s step %.2f ms, render meshes %.2f ms, frame %.2f ms (%s 33.3 ms at 30 Hz), at most %zu of %zu "
              "objects awake (%zu at some step, %zu of them moved less than 0.03 r), deepest overlap %.3f r\n",
              phase, ms, msr, ms + msr, ms + msr <= 1e3 / 30.0 ? "within" : "over", awake, scene.placed.size(), woken,
              still, deepestOverlap(*scene.world));
  printParts(*scene.world, times0, sum(step), frames);
}

/// The finger: a 2 cm sphere resting on the pile's top at (x, y) a quarter of the way in from a
/// corner of its bounds (`first`: the world's first object).
Collider fingerOver(World& world, const std::string& first) {
  Eigen::Vector3d lo = world.object(first)->positions()[0], hi = lo;
  for (const std::string& name : world.objectNames())
    for (const Eigen::Vector3d& x : world.object(name)->positions()) {
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
  const Eigen::Vector2d at = lo.head<2>() + 0.25 * (hi - lo).head<2>();
  double top = lo.z();
  for (const std::string& name : world.objectNames())
    for (const Eigen::Vector3d& x : world.object(name)->positions())
      if ((x.head<2>() - at).norm() < 0.01) top = std::max(top, x.z());
  Collider finger;
  finger.shape.type = ColliderType::Sphere;
  finger.shape.radius = 0.02;
  finger.pose.translation() = Eigen::Vector3d(at.x(), at.y(), top + finger.shape.radius);
  return finger;
}

/// Prints table 3: a new bin with sleeping objects, settled, then with a finger pressed into it.
void sleepTable(RenderedBin& scene, const Shape& shape, const Args& args) {
  scene.placed.clear();
  scene.world = bin(shape, args.objects, &scene.placed);
  SleepParams sleep;
  sleep.fraction = 2e-5;  // the node's rest (LoopSettings)
  sleep.hold = 1.0;
  scene.world->setSleepParams(sleep);
  int settle = 0;
  const std::size_t most = (9 * scene.placed.size()) / 10;
  for (; settle < 240 || (scene.world->sleepingCount() < most && settle < 600); ++settle) scene.world->step();
  std::printf("\nthe bin with sleeping objects (rest: 2e-5 of an object's size over 1 s):\n");
  char settled[64];
  std::snprintf(settled, sizeof settled, "settled (after %.1f s)", settle * kStep);
  sleepRow(scene, settled, [] {});
  // a finger over the pile at (x, y) a quarter of the way in from a corner
  const std::string first = scene.world->objectNames().front();
  scene.world->setCollider("finger", fingerOver(*scene.world, first));
  // 45 frames at 2 cm/s: 3 cm down into the pile from its top there
  sleepRow(scene, "a finger pressed into it", [&] {
    scene.world->moveCollider("finger", scene.world->object(first)->colliders().at("finger").pose,
                              Eigen::Vector3d(0, 0, -0.02), Eigen::Vector3d::Zero());
  });
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  const Shape shape = makeShape(args);
  std::printf("object: the bunny at %.0f mm, resolution %d: %zu particles; render mesh %zu triangles, %zu vertices; "
              "%.0f Hz in %d sub-steps, one thread\n",
              1000 * kSize, args.resolution, shape.voxels.cells.size(), shape.renderTriangles,
              shape.renderVertices.size(), 1.0 / kStep, substepsPerStep);

  // --- 1. N objects against one alone ---
  if (args.only != "bin") sizesTable(shape, args);

  // --- 2. the bin against real time ---
  if (args.only == "sizes") return 0;
  RenderedBin scene;
  scene.world = bin(shape, args.objects, &scene.placed);
  scene.vertices.resize(scene.placed.size());
  for (const Placed& p : scene.placed) scene.embeddings.emplace_back(*p.lattice, p.vertices);
  realTimeTable(scene, shape, args);

  // --- 3. the bin with sleeping objects ---
  sleepTable(scene, shape, args);
  return 0;
}
