/// @file world_scenes.h
/// The scenes and checks that the World's tests share (test_world*, test_sleeping*): blocks on the
/// ground, a bin and the node's bin of soft objects, meshes voxelized at a pose, overlaps.
#pragma once

#include "core/fixtures.h"
#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/world.h"
#include "support/params.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {
namespace world_scenes {

constexpr double kG = 9.81;
constexpr double kStep = 1.0 / 60.0;
constexpr int kSubsteps = 8;

/// A full box of nx x ny x nz cells of `spacing` whose lower corner is `lo`.
inline std::shared_ptr<const Lattice> boxAt(int nx, int ny, int nz, double spacing, const Eigen::Vector3d& lo,
                                         int w = 1) {
  Voxelization v = test::makeBox(nx, ny, nz, spacing);
  v.origin = lo;
  return std::make_shared<const Lattice>(v, 1000.0, w);
}

/// Classic FastLSM with alpha = `alpha`, 60 Hz in kSubsteps sub-steps, ambient damping
/// `ambient` (1/s); with the implicit integrator in one sub-step.
inline SolverParams paramsFor(const Lattice& lattice, double alpha = 0.3, double ambient = 0.5,
                              Integrator integrator = Integrator::Explicit) {
  SolverParams p;
  p.regionHalfWidth = lattice.regionHalfWidth();
  p.stiffness = alpha;
  p.ambientDamping = ambient;
  p.timeStep = kStep;
  p.integrator = integrator;
  p.substeps = integrator == Integrator::Implicit ? 1 : kSubsteps;
  return p;
}

inline int substepsOf(Integrator integrator) { return integrator == Integrator::Implicit ? 1 : kSubsteps; }

inline Collider ground(double z = 0.0) {
  Collider g;
  g.pose.translation() = Eigen::Vector3d(0, 0, z);
  return g;
}

inline Collider box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half, double mu = 0.6) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = half;
  c.pose.translation() = centre;
  c.staticFriction = mu;
  c.kineticFriction = mu;
  return c;
}

/// A bin's floor and four walls (boxes of thickness 2 wall) around a square of half-width
/// `inner` on z = 0, the walls `depth` high.
inline std::vector<std::pair<std::string, Collider>> binColliders(double inner, double depth, double wall) {
  return {
      {"floor", box(Eigen::Vector3d(0, 0, -wall), Eigen::Vector3d(inner + 2 * wall, inner + 2 * wall, wall))},
      {"wall_x+", box(Eigen::Vector3d(inner + wall, 0, depth / 2), Eigen::Vector3d(wall, inner + 2 * wall, depth / 2))},
      {"wall_x-", box(Eigen::Vector3d(-inner - wall, 0, depth / 2), Eigen::Vector3d(wall, inner + 2 * wall, depth / 2))},
      {"wall_y+", box(Eigen::Vector3d(0, inner + wall, depth / 2), Eigen::Vector3d(inner + 2 * wall, wall, depth / 2))},
      {"wall_y-", box(Eigen::Vector3d(0, -inner - wall, depth / 2), Eigen::Vector3d(inner + 2 * wall, wall, depth / 2))}};
}

inline int stepsFor(double seconds) { return static_cast<int>(std::lround(seconds / kStep)); }

inline Eigen::Vector3d centreOfMass(const Solver& s) {
  const auto& m = s.lattice().masses();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < m.size(); ++i) c += m[i] * s.positions()[i];
  return c / s.lattice().totalMass();
}

/// The fastest particle of any object of the world (m/s).
inline double maxSpeed(const World& world) {
  double v = 0.0;
  for (const std::string& name : world.objectNames())
    for (const auto& vi : world.object(name)->velocities()) v = std::max(v, vi.norm());
  return v;
}

/// The deepest overlap of two particle spheres of different objects, as a fraction of the
/// smaller radius (0 when none overlaps); brute force, the test's own oracle.
inline double deepestOverlap(const World& world) {
  double deepest = 0.0;
  const auto& names = world.objectNames();
  for (std::size_t a = 0; a < names.size(); ++a)
    for (std::size_t b = a + 1; b < names.size(); ++b) {
      const Solver& A = *world.object(names[a]);
      const Solver& B = *world.object(names[b]);
      const double R = A.contactRadius() + B.contactRadius();
      const double r = std::min(A.contactRadius(), B.contactRadius());
      for (const auto& x : A.positions())
        for (const auto& y : B.positions()) deepest = std::max(deepest, (R - (x - y).norm()) / r);
    }
  return deepest;
}

inline bool allFinite(const World& world) {
  for (const std::string& name : world.objectNames()) {
    const Solver& s = *world.object(name);
    for (std::size_t i = 0; i < s.positions().size(); ++i)
      if (!s.positions()[i].allFinite() || !s.velocities()[i].allFinite()) return false;
  }
  return true;
}

/// A cube of a physical material of Young's modulus E (regions of half-width 1), one implicit
/// sub-step of 1/60 s, ambient damping 1/s.
inline SolverParams implicitCube(double E) {
  SolverParams p = test::physicalParams(E, 0.0, 1, kStep, 1, Integrator::Implicit);
  p.ambientDamping = 1.0;
  return p;
}

/// Voxelized at `resolution` cells along its longest axis after turning the mesh by `yaw` about
/// Z (Z up) and scaling its longest extent to `size`, its lower corner at `lo`. Each file is read
/// once (reading the bunny takes about ten times as long as voxelizing it).
inline std::shared_ptr<const Lattice> meshAt(const std::string& path, bool yUp, double yaw, double size,
                                             int resolution, const Eigen::Vector3d& lo) {
  static std::map<std::string, TriMesh> read;
  auto it = read.find(path);
  if (it == read.end()) it = read.emplace(path, loadMesh(path, 1.0)).first;
  TriMesh mesh = it->second;
  const Eigen::Matrix3d turn = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  for (auto& v : mesh.vertices) v = turn * (yUp ? Eigen::Vector3d(v.x(), -v.z(), v.y()) : v);
  const Eigen::Vector3d mlo = mesh.boundsMin(), mhi = mesh.boundsMax();
  const double scale = size / (mhi - mlo).maxCoeff();
  for (auto& v : mesh.vertices) v = lo + (v - mlo) * scale;
  VoxelizeOptions options;
  options.resolution = resolution;
  return std::make_shared<const Lattice>(voxelize(mesh, options), 1000.0, 1);
}

/// The node's bin scene (config/bin.yaml): bunnies 9 cm long and cubes 8 cm on a side of about
/// a hundred particles, each turned about the vertical, a soft rubber (E = 30 kPa), 60 Hz in 11
/// sub-steps (the implicit step: one), dropped in three layers into a 40 x 40 cm box. Returns
/// the box's colliders and the smallest contact radius.
inline std::vector<std::pair<std::string, Collider>> fillSoftBin(World& world, Integrator integrator, double& r) {
  const double dt = world.timeStep();
  const int substeps = world.substeps();
  const double inner = 0.2, depth = 0.35, wall = 0.025;
  const std::vector<std::pair<std::string, Collider>> colliders = binColliders(inner, depth, wall);
  for (const auto& c : colliders) world.setCollider(c.first, c.second);
  const double yaw[20] = {-0.785, -0.14, 0.506, -0.419, 0.227,  -0.698, -0.052, 0.593, -0.332, 0.314,
                          -0.611, 0.035, 0.681, -0.244, 0.401, -0.524, 0.122,  0.768, -0.157, 0.489};
  r = 1.0;
  for (int n = 0; n < 20; ++n) {
    const int layer = n / 9, k = n % 9;
    const Eigen::Vector3d lo(-0.165 + 0.12 * (k % 3), -0.165 + 0.12 * (k / 3), 0.02 + 0.12 * layer);
    auto lattice = n % 2 == 0 ? meshAt(kBunnyMeshPath, true, yaw[n], 0.09, 6, lo)
                              : meshAt("/usr/share/glmark2/models/cube.3ds", false, yaw[n], 0.08, 5, lo);
    SolverParams p = test::physicalParams(30000.0, 0.0, 1, dt, substeps, integrator);
    p.ambientDamping = 1.0;
    Solver& s = world.addObject("o" + std::to_string(n), lattice, p);
    r = std::min(r, s.contactRadius());
  }
  return colliders;
}

}  // namespace world_scenes
}  // namespace deformable_flsm
