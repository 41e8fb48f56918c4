// Prints what contact with colliders adds to a FastLSM step, in ns per particle-step and as the
// ratio to the same step without colliders, on the bunny voxelized to about --particles
// particles (the package's default material: E = 14 kPa, regions of 4.8 cm, 60 Hz in 4 sub-steps).
// Entries: no collider, the bunny's bottom layer pinned instead (as the default scene holds it:
// the same load and deformation as standing on the ground, so that the shape matching does the
// same work); the ground under the bunny; 8 primitives (the ground, two boxes, three spheres and
// two capsules, each touching the bunny); the ground and a mesh collider (a second, rigid bunny
// of half the size pressed into its side); a robot mostly far from the object: the ground and two
// box fingers touching the bunny, without and with 22 more links beside it (tilted cylinders,
// boxes, spheres and box meshes, as a URDF's collision model gives them, none within reach), to
// show what the far links cost once the broad phase has skipped them. A benchmark, not a test: it prints figures and never fails because
// the machine is slow. Entries run in turns, one run each per round, and each ratio is the median
// of the ratios within a round, so that a busy spell of a shared machine hits all entries alike.
//
//   bench_contact [--mesh PATH] [--particles N] [--rounds N]

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/mesh_distance_field.h"
#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"
#include "support/params.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

struct Args {
  std::string mesh = deformable_flsm::kBunnyMeshPath;
  std::size_t particles = 10000;
  int rounds = 11;
};

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string k = argv[i];
    const char* v = argv[i + 1];
    if (k == "--mesh") a.mesh = v;
    else if (k == "--particles") a.particles = std::strtoul(v, nullptr, 10);
    else if (k == "--rounds") a.rounds = std::max(1, std::atoi(v));
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

struct Entry {
  std::string name;
  std::unique_ptr<Solver> solver;
  std::vector<double> samples;  // ns per particle-step of each run
  std::size_t contacts = 0;     // particles in contact after the last run
};

/// Steps in one timed run: about 50 ms of stepping at 10k particles, at least 2.
int stepsPerRun(std::size_t particles) { return std::max(2, static_cast<int>(2e5 / double(particles))); }

void run(Entry& e, int steps) {
  const auto t0 = std::chrono::steady_clock::now();
  for (int i = 0; i < steps; ++i) e.solver->step();
  const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
  e.samples.push_back(ns / (double(steps) * e.solver->params().substeps * double(e.solver->lattice().size())));
  e.contacts = 0;
  for (const auto& c : e.solver->colliders()) e.contacts += e.solver->contactWrench(c.first).contacts;
}

Collider sphere(const Eigen::Vector3d& centre, double radius) {
  Collider c;
  c.shape.type = ColliderType::Sphere;
  c.shape.radius = radius;
  c.pose.translation() = centre;
  return c;
}

Collider box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = half;
  c.pose.translation() = centre;
  return c;
}

/// A cylinder whose axis (its frame's z) is turned by `turn`.
Collider cylinder(const Eigen::Vector3d& centre, const Eigen::AngleAxisd& turn, double radius, double halfLength) {
  Collider c;
  c.shape.type = ColliderType::Cylinder;
  c.shape.radius = radius;
  c.shape.halfLength = halfLength;
  c.pose.translation() = centre;
  c.pose.linear() = turn.toRotationMatrix();
  return c;
}

/// A closed box mesh of half extents `half` about the origin (a link's mesh collision shape).
std::shared_ptr<const TriMesh> boxMesh(const Eigen::Vector3d& half) {
  auto m = std::make_shared<TriMesh>();
  for (int k = 0; k < 8; ++k)
    m->vertices.emplace_back((k & 1 ? 1 : -1) * half.x(), (k & 2 ? 1 : -1) * half.y(), (k & 4 ? 1 : -1) * half.z());
  // two counter-clockwise triangles per face, seen from outside
  m->triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                  {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  return m;
}

/// A capsule whose axis (its frame's z) is turned by `turn`.
Collider capsule(const Eigen::Vector3d& centre, const Eigen::AngleAxisd& turn, double radius, double halfLength) {
  Collider c;
  c.shape.type = ColliderType::Capsule;
  c.shape.radius = radius;
  c.shape.halfLength = halfLength;
  c.pose.translation() = centre;
  c.pose.linear() = turn.toRotationMatrix();
  return c;
}

/// The 8 primitives (the ground, two boxes, three spheres and two capsules), each touching the
/// bunny (bounds lo..hi, middle mid, the particles' spheres `touch` out from them). Prints nothing.
void addPrimitives(Solver& s, const Collider& ground, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                   const Eigen::Vector3d& mid, double touch) {
  s.setCollider("ground", ground);
  const Eigen::Vector3d half(0.03, 0.01, 0.03);
  s.setCollider("left", box(Eigen::Vector3d(mid.x(), lo.y() - touch - half.y(), mid.z()), half));
  s.setCollider("right", box(Eigen::Vector3d(mid.x(), hi.y() + touch + half.y(), mid.z()), half));
  const double R = 0.02;
  s.setCollider("front", sphere(Eigen::Vector3d(lo.x() - touch - R, mid.y(), mid.z()), R));
  s.setCollider("back", sphere(Eigen::Vector3d(hi.x() + touch + R, mid.y(), mid.z()), R));
  s.setCollider("top", sphere(Eigen::Vector3d(mid.x(), mid.y(), hi.z() + touch + R), R));
  s.setCollider("rod_y", capsule(Eigen::Vector3d(mid.x(), mid.y(), hi.z() + touch + 0.01), Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitX()), 0.01, 0.1));  // along y
  s.setCollider("rod_x", capsule(Eigen::Vector3d(mid.x(), lo.y() - touch - 0.01, lo.z() + 0.03), Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()), 0.01, 0.1));  // along x
}

/// The ground and a rigid bunny of half the size beside the soft one, touching it; prints the mesh
/// collider's line (its triangles, its distance field's nodes and build time).
void addMeshCollider(Solver& s, const TriMesh& mesh, const Collider& ground, const Eigen::Vector3d& hi,
                     const Eigen::Vector3d& mid) {
  TriMesh small = mesh;
  for (auto& v : small.vertices) v *= 0.5;
  Collider rigid;
  rigid.shape.type = ColliderType::Mesh;
  rigid.shape.mesh = std::make_shared<const TriMesh>(small);
  const auto t0 = std::chrono::steady_clock::now();
  rigid.shape.distanceField = std::make_shared<const MeshDistanceField>(small);
  const double ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  std::printf("mesh collider: %zu triangles, distance field %d x %d x %d nodes built in %.0f ms\n",
              small.triangles.size(), rigid.shape.distanceField->dims().x(), rigid.shape.distanceField->dims().y(),
              rigid.shape.distanceField->dims().z(), ms);
  // its centre on the soft bunny's +x side at mid height: the warm-up pushes the soft one aside
  rigid.pose.translation() = Eigen::Vector3d(hi.x(), mid.y(), mid.z()) - 0.5 * (small.boundsMin() + small.boundsMax());
  s.setCollider("ground", ground);
  s.setCollider("rigid_bunny", rigid);
}

/// The robot's 22 far links, spread along an arm that reaches toward the bunny (bounds up to hi)
/// from the +x, +y side, ending 5 cm or more short of its bounds. Prints nothing.
void addFarLinks(Solver& s, const Eigen::Vector3d& hi) {
  const auto meshLink = boxMesh(Eigen::Vector3d(0.03, 0.02, 0.05));
  for (int k = 0; k < 22; ++k) {
    // along the arm, from 0.8 m away to 5 cm from the bunny's bounds, turning as it goes
    const double t = k / 21.0;
    const double reach = 0.05 + 0.75 * (1.0 - t);
    const Eigen::Vector3d centre = hi + Eigen::Vector3d(reach + 0.06, reach + 0.06, 0.1 * t);
    const Eigen::AngleAxisd turn(0.4 * k, Eigen::Vector3d(1, 2, 3).normalized());
    Collider c;
    switch (k % 4) {
      case 0: c = cylinder(centre, turn, 0.04, 0.06); break;
      case 1: c = box(centre, Eigen::Vector3d(0.03, 0.04, 0.05)); c.pose.linear() = turn.toRotationMatrix(); break;
      case 2: c = sphere(centre, 0.05); break;
      default:
        c.shape.type = ColliderType::Mesh;
        c.shape.mesh = meshLink;
        c.pose.translation() = centre;
        c.pose.linear() = turn.toRotationMatrix();
    }
    s.setCollider("robot/link" + std::to_string(k) + "/0", c);
  }
}

/// Prints the table of the entries' figures (ns per particle-step, x none, contacts, ms per step
/// for `particles` particles), then the far links' own cost.
void resultTable(const std::vector<Entry>& entries, const Args& args, int steps, const SolverParams& p,
                 std::size_t particles) {
  std::printf("\nsingle thread, %d rounds of %d steps after %d steps of warm-up; x none: median of the ratios within\n"
              "a round; contacts: particles touching a collider in the last sub-step\n", args.rounds, steps, 3 * steps);
  std::printf("%16s %12s %10s %10s %10s\n", "colliders", "ns/p-step", "x none", "contacts", "ms/step");
  for (const Entry& e : entries) {
    std::vector<double> ratio;
    for (std::size_t i = 0; i < e.samples.size(); ++i) ratio.push_back(e.samples[i] / entries[0].samples[i]);
    const double ns = median(e.samples);
    std::printf("%16s %12.1f %10.3f %10zu %10.2f\n", e.name.c_str(), ns, median(ratio), e.contacts,
                ns * p.substeps * double(particles) * 1e-6);
  }
  // The far links' own cost: the robot against its two fingers alone, and against the ground
  // alone (no robot), each the median of the ratios within a round.
  const auto versus = [&](const Entry& a, const Entry& b) {
    std::vector<double> ratio;
    for (std::size_t i = 0; i < a.samples.size(); ++i) ratio.push_back(a.samples[i] / b.samples[i]);
    return median(ratio);
  };
  std::printf("\n24-link robot (22 links far) / 2 fingers: %.3f\n", versus(entries[5], entries[4]));
  std::printf("24-link robot / ground (no robot):       %.3f\n", versus(entries[5], entries[1]));
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  TriMesh mesh = loadMesh(args.mesh, 0.1);
  for (auto& v : mesh.vertices) v = Eigen::Vector3d(v.x(), -v.z(), v.y());  // Y-up file, Z-up here
  const Voxelization vox = nearestResolution(mesh, args.particles).voxels;
  const int w = regionHalfWidthForRadius(0.048, vox.spacing);
  auto lattice = std::make_shared<const Lattice>(vox, 1000.0, w);
  const SolverParams p = test::physicalParams(14e3, 0.0, w, 1.0 / 60.0, 4);
  std::printf("mesh %s: %zu particles, spacing %.4g m, w = %d, %d sub-steps of %.4g s\n", args.mesh.c_str(),
              lattice->size(), vox.spacing, w, p.substeps, p.substepLength());

  // The bunny's extent and the contact radius, to place colliders that touch it.
  const Eigen::Vector3d lo = lattice->restMin(), hi = lattice->restMax(), mid = 0.5 * (lo + hi);
  const double r = 0.5 * vox.spacing, touch = r - 0.25 * vox.spacing;  // a quarter cell into the spheres
  Collider ground;
  ground.pose.translation() = Eigen::Vector3d(0, 0, lo.z() - touch);

  std::vector<Entry> entries(6);
  entries[0].name = "none (pinned)";
  entries[1].name = "ground";
  entries[2].name = "8 primitives";
  entries[3].name = "ground + mesh";
  entries[4].name = "2 fingers";
  entries[5].name = "24-link robot";
  for (Entry& e : entries) e.solver = std::make_unique<Solver>(lattice, p);
  entries[0].solver->pinBox(Eigen::Vector3d::Constant(-1e9), Eigen::Vector3d(1e9, 1e9, lo.z() + 0.5 * vox.spacing), true);
  entries[1].solver->setCollider("ground", ground);
  addPrimitives(*entries[2].solver, ground, lo, hi, mid, touch);
  addMeshCollider(*entries[3].solver, mesh, ground, hi, mid);
  // A robot: two box fingers gripping the bunny's sides (with the ground), then the same with
  // 22 more links spread along an arm that reaches toward it from the +x, +y side and stops
  // 5 cm or more short of its bounds.
  for (int k : {4, 5}) {
    Solver& s = *entries[k].solver;
    s.setCollider("ground", ground);
    const Eigen::Vector3d half(0.04, 0.01, 0.04);
    s.setCollider("robot/finger_left/0", box(Eigen::Vector3d(mid.x(), lo.y() - touch - half.y(), mid.z()), half));
    s.setCollider("robot/finger_right/0", box(Eigen::Vector3d(mid.x(), hi.y() + touch + half.y(), mid.z()), half));
  }
  addFarLinks(*entries[5].solver, hi);
  const int steps = stepsPerRun(lattice->size());
  for (int i = 0; i < 3; ++i)
    for (Entry& e : entries) run(e, steps);  // warm-up: the bunny settles against its colliders
  for (Entry& e : entries) e.samples.clear();
  for (int round = 0; round < args.rounds; ++round)
    for (Entry& e : entries) run(e, steps);

  resultTable(entries, args, steps, p, lattice->size());
  return 0;
}
