/// @file contact_fixtures.h
/// What the contact tests share (test_contact, test_contact_abuse, test_contact_scenes): the
/// bunny of the scenes and their solver parameters, measures of a solver's state, a ground
/// below it.
#pragma once

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>

namespace deformable_flsm {
namespace contact_fixtures {

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;
constexpr double kG = 9.81;

/// The bunny file's ~2-unit bunny at 0.1 (about 20 cm), turned from Y-up to Z-up.
inline TriMesh zUpBunny() {
  TriMesh mesh = loadMesh(kBunnyPath, 0.1);
  for (auto& v : mesh.vertices) v = Eigen::Vector3d(v.x(), -v.z(), v.y());
  return mesh;
}

/// Lattice cells along the bunny's longest axis in the scenes: about 1300 particles.
constexpr int kBunnyResolution = 16;

struct BunnyScene {
  TriMesh mesh;
  std::shared_ptr<const Lattice> lattice;
};

/// Regions of two cells (w = 2).
constexpr int kRegionHalfWidth = 2;

inline BunnyScene bunnyScene() {
  BunnyScene scene;
  scene.mesh = zUpBunny();
  VoxelizeOptions options;
  options.resolution = kBunnyResolution;
  scene.lattice = std::make_shared<const Lattice>(voxelize(scene.mesh, options), 1000.0, kRegionHalfWidth);
  return scene;
}

/// 60 Hz in 8 sub-steps, classic FastLSM with alpha = `alpha` (firm: the squeeze of a grasp
/// must carry the weight), the default damping. (The package's default E = 14 kPa at this
/// resolution is a jelly that two fingers squeezing 1.5 cm hold with only 2 N each.)
inline SolverParams sceneParams(const Lattice& lattice, double alpha = 1.0) {
  SolverParams p;
  p.regionHalfWidth = lattice.regionHalfWidth();
  p.stiffness = alpha;
  p.timeStep = 1.0 / 60.0;
  p.substeps = 8;
  return p;
}

inline Eigen::Vector3d centreOfMass(const Solver& s) {
  const auto& m = s.lattice().masses();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < m.size(); ++i) c += m[i] * s.positions()[i];
  return c / s.lattice().totalMass();
}

inline double maxSpeed(const Solver& s) {
  double v = 0.0;
  for (const auto& vi : s.velocities()) v = std::max(v, vi.norm());
  return v;
}

inline bool allFinite(const Solver& s) {
  for (std::size_t i = 0; i < s.positions().size(); ++i)
    if (!s.positions()[i].allFinite() || !s.velocities()[i].allFinite()) return false;
  return true;
}

inline double lowestZ(const Solver& s) {
  double z = s.positions()[0].z();
  for (const auto& x : s.positions()) z = std::min(z, x.z());
  return z;
}

/// A ground plane whose surface is `gap` below the lowest particle sphere.
inline Collider groundBelow(const Solver& s, double gap) {
  Collider ground;
  ground.pose.translation() = Eigen::Vector3d(0, 0, lowestZ(s) - s.contactRadius() - gap);
  return ground;
}

inline void setVelocity(Solver& s, const std::string& id, const Eigen::Vector3d& v) {
  ASSERT_TRUE(s.moveCollider(id, s.colliders().at(id).pose, v, Eigen::Vector3d::Zero()));
}

inline int stepsFor(double seconds, const Solver& s) {
  return static_cast<int>(std::lround(seconds / s.params().timeStep));
}

}  // namespace contact_fixtures
}  // namespace deformable_flsm
