// Friction with static above kinetic (mu_k < mu_s): the transition between them in the contact
// response (frictionTaken() in contact.h), and soft objects touching each other on a floor with
// the colliders' default friction, which must come to rest.
#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/voxelizer.h"
#include "deformable_flsm/core/world.h"
#include "support/params.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

using namespace deformable_flsm;

// --- the kernel ------------------------------------------------------------------------------

TEST(FrictionTaken, SticksUpToStaticThenReachesKineticContinuously) {
  const double mus = 0.6, muk = 0.5, N = 0.1;
  // static friction: all of a slip up to mu_s N is stopped
  EXPECT_DOUBLE_EQ(frictionTaken(0.0, N, mus, muk), 0.0);
  EXPECT_DOUBLE_EQ(frictionTaken(0.05, N, mus, muk), 0.05);
  EXPECT_DOUBLE_EQ(frictionTaken(mus * N, N, mus, muk), mus * N);
  // Coulomb's kinetic friction once the slip exceeds the breakaway by the normal change N
  EXPECT_DOUBLE_EQ(frictionTaken((1.0 + mus) * N, N, mus, muk), muk * N);
  EXPECT_DOUBLE_EQ(frictionTaken(2.0, N, mus, muk), muk * N);
  // between: the slip left after friction is continuous (no jump at the breakaway) and never
  // decreases as the slip to stop grows, so a contact at the edge of its cone has no two
  // answers to alternate between
  double lastLeft = 0.0;
  for (int i = 0; i <= 2000; ++i) {
    const double needed = 0.2 * N * i / 100.0;
    const double taken = frictionTaken(needed, N, mus, muk);
    const double left = needed - taken;
    EXPECT_GE(taken, std::min(needed, muk * N) - 1e-15) << "never less than kinetic friction";
    EXPECT_LE(taken, std::min(needed, mus * N) + 1e-15) << "never more than static friction";
    EXPECT_GE(left, lastLeft - 1e-15) << "slip left decreases at " << needed;
    // the step 2e-4 in `needed` moves the slip left by at most (1 + mu_s - mu_k) times that
    EXPECT_LE(left - lastLeft, (1.0 + mus - muk) * 0.002 * N + 1e-15) << "jump at " << needed;
    lastLeft = left;
  }
  // mu_s = mu_k: Coulomb's law without a transition
  EXPECT_DOUBLE_EQ(frictionTaken(0.5, N, 0.6, 0.6), 0.06);
}

TEST(FrictionTaken, TheContactResponseUsesIt) {
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ(), still = Eigen::Vector3d::Zero();
  const double h = 0.01;
  // 1 mm deep from outside: normal change 0.1 m/s; a slip of 0.065 m/s is just past the
  // breakaway 0.06: friction takes 0.06 - 0.1 (0.065 - 0.06) = 0.0595 (Coulomb's step would
  // take only mu_k 0.1 = 0.05, leaving 0.015 instead of 0.0055)
  const Eigen::Vector3d dv =
      contactVelocityChange(-0.001, 0.0, n, Eigen::Vector3d(0.065, 0.0, -0.2), still, h, 0.6, 0.5);
  EXPECT_NEAR(dv.x(), -0.0595, 1e-12);
  EXPECT_NEAR(dv.z(), 0.1, 1e-12);
}

// --- soft objects on a floor -------------------------------------------------------------------

namespace {

/// An object placed as the node places one of ~objects (runtime buildWorld()): the mesh loaded
/// at `scale`, turned by roll `roll` about X, moved by the pose (x, y, z, yaw about Z), then
/// voxelized at `resolution` cells along its longest axis.
std::shared_ptr<const Lattice> placed(const std::string& path, double scale, double roll, int resolution,
                                      const Eigen::Vector3d& at, double yaw) {
  TriMesh mesh = loadMesh(path, scale);
  const Eigen::Isometry3d pose = Eigen::Translation3d(at) * Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                                 Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX());
  for (Eigen::Vector3d& v : mesh.vertices) v = pose * v;
  VoxelizeOptions options;
  options.resolution = resolution;
  return std::make_shared<const Lattice>(voxelize(mesh, options), 1000.0, 1);
}

}  // namespace

// The node's bin scene (config/bin.yaml), its objects placed as the node places them (bunnies 9 cm
// long, cubes 8 cm, soft rubber of 30 kPa, 60 Hz in 11 sub-steps, object contact on), its box's
// floor and walls at the colliders' default friction (static 0.6, kinetic 0.5). The pile presses
// particles of objects that touch each other aslant onto the floor at the edge of their friction
// cones; with Coulomb's step from static to kinetic friction such a pair's common velocity
// flipped every sub-step (centimetres per second, positions still) and the pile never rested.
TEST(FrictionScene, ABinOfSoftObjectsComesToRestWithKineticBelowStatic) {
  const double dt = 1.0 / 60.0;
  const int substeps = 11;
  World world(dt, substeps);
  Collider box;  // the colliders' default friction
  box.shape.type = ColliderType::Box;
  ASSERT_LT(box.kineticFriction, box.staticFriction);
  auto wall = [&](const Eigen::Vector3d& centre, const Eigen::Vector3d& size) {
    Collider c = box;
    c.shape.halfExtents = size / 2;
    c.pose.translation() = centre;
    return c;
  };
  world.setCollider("floor", wall({0, 0, -0.025}, {0.5, 0.5, 0.05}));
  world.setCollider("wall_east", wall({0.225, 0, 0.175}, {0.05, 0.5, 0.35}));
  world.setCollider("wall_west", wall({-0.225, 0, 0.175}, {0.05, 0.5, 0.35}));
  world.setCollider("wall_north", wall({0, 0.225, 0.175}, {0.4, 0.05, 0.35}));
  world.setCollider("wall_south", wall({0, -0.225, 0.175}, {0.4, 0.05, 0.35}));
  const std::string cube = "/usr/share/glmark2/models/cube.3ds";
  // bunnies at the even places, cubes at the odd: three layers of a 3 x 3 grid 12 cm apart,
  // each object turned about the vertical
  const double yaw[20] = {-0.785, -0.14, 0.506, -0.419, 0.227,  -0.698, -0.052, 0.593, -0.332, 0.314,
                          -0.611, 0.035, 0.681, -0.244, 0.401, -0.524, 0.122,  0.768, -0.157, 0.489};
  double r = 1.0;
  for (int n = 0; n < 20; ++n) {
    const Eigen::Vector3d at(-0.12 + 0.12 * (n % 3), -0.12 + 0.12 * ((n % 9) / 3), 0.06 + 0.12 * (n / 9));
    auto lattice = n % 2 == 0 ? placed(kBunnyMeshPath, 0.045, 1.5708, 6, at, yaw[n])
                              : placed(cube, 0.04, 0.0, 5, at, yaw[n]);
    SolverParams p = test::physicalParams(30000.0, 0.0, 1, dt, substeps);
    p.ambientDamping = 1.0;
    Solver& s = world.addObject("o" + std::to_string(n), lattice, p);
    r = std::min(r, s.contactRadius());
  }
  for (long i = 0; i < std::lround(14.0 / dt); ++i) world.step();
  // at rest: no particle moves a hundredth of its radius in a step over 2 s (the bound of the
  // bin's own rest test in test_world_scenes.cpp: far below what an eye sees on objects of a few cm,
  // and below the contacts' tolerance of penetration); the cycle ran at ten times it
  const double bound = 0.01 * r / dt;
  double fastest = 0.0;
  for (long i = 0; i < std::lround(2.0 / dt); ++i) {
    world.step();
    for (const std::string& name : world.objectNames())
      for (const auto& v : world.object(name)->velocities()) {
        ASSERT_TRUE(v.allFinite());
        fastest = std::max(fastest, v.norm());
      }
  }
  std::printf("[ bin     ] 20 soft objects, friction 0.6 / 0.5: from 14 to 16 s the fastest particle %.3g m/s "
              "(bound %.3g m/s)\n",
              fastest, bound);
  EXPECT_LT(fastest, bound) << "the objects touching on the floor come to rest";
}
