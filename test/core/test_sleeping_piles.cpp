// Piles of objects asleep in a World: the node's bin of soft objects and a bin of bunnies sleep
// at rest and wake where a finger presses into them, which meets the force it meets in a pile
// that never sleeps.
#include "deformable_flsm/core/world.h"

#include "sleep_fixtures.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <random>
#include <set>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::sleep_fixtures;
using namespace deformable_flsm::world_scenes;

// The node's bin of twenty soft objects: at rest it sleeps, and its box still carries the whole
// weight (statics); a finger pressed 3 cm into one corner of the pile wakes what it stirs, meets
// the resistance it meets in a pile that never sleeps (a pile of immovable sleepers would be
// stiffer), nothing interpenetrates, and once it is withdrawn the pile sleeps again.
static double pressTheBin(bool sleeping) {
  const double dt = 1.0 / 60.0;
  World world(dt, 11);
  if (sleeping) world.setSleepParams(sleepAfter(1.0));
  double r = 1.0;
  const auto colliders = fillSoftBin(world, Integrator::Explicit, r);
  double weight = 0.0;
  for (const std::string& name : world.objectNames()) weight += world.object(name)->lattice().totalMass() * kG;
  int steps = 0;
  for (; steps < std::lround(15.0 / dt) || (sleeping && world.sleepingCount() < world.objectCount() &&
                                            steps < std::lround(25.0 / dt));
       ++steps)
    world.step();
  const std::size_t asleep = world.sleepingCount();
  if (sleeping) {
    double carried = 0.0;
    for (const auto& c : colliders) carried -= world.contactWrench(c.first).force.z();
    std::printf("bin of 20 with sleeping: %zu asleep after %.1f s, the box carries %.4f of the weight\n", asleep, steps * dt,
                carried / weight);
    EXPECT_GE(asleep, 18u) << "the pile rests";
    EXPECT_NEAR(carried, weight, 0.02 * weight) << "asleep, the pile still weighs on its box";
  }
  // a 2 cm finger pushed down at 10 cm/s onto the pile in the corner of x, y < 0, from 5 cm
  // above its top there until its lowest point is 3 cm below it
  const Eigen::Vector2d at(-0.12, -0.12);
  double topZ = 0.0;
  for (const std::string& name : world.objectNames())
    for (const Eigen::Vector3d& x : world.object(name)->positions())
      if ((x.head<2>() - at).norm() < 0.03) topZ = std::max(topZ, x.z());
  Collider finger;
  finger.shape.type = ColliderType::Sphere;
  finger.shape.radius = 0.02;
  finger.pose.translation() = Eigen::Vector3d(at.x(), at.y(), topZ + 0.07);
  world.setCollider("finger", finger);
  std::set<std::string> woke;
  double overlap = 0.0, push = 0.0;
  const int down = static_cast<int>(std::lround(0.08 / 0.1 / dt));
  for (int i = 0; i < down; ++i) {
    world.moveCollider("finger", world.object("o0")->colliders().at("finger").pose, Eigen::Vector3d(0, 0, -0.1),
                       Eigen::Vector3d::Zero());
    world.step();
    push = std::max(push, world.contactWrench("finger").force.norm());
    for (const std::string& name : world.objectNames())
      if (!world.asleep(name)) woke.insert(name);
    overlap = std::max(overlap, deepestOverlap(world));
  }
  world.removeCollider("finger");
  std::printf("finger pressed into the pile (%s): up to %.3g N (the pile weighs %.3g N), %zu objects awake in the push; "
              "deepest overlap %.3g r\n",
              sleeping ? "sleeping" : "never sleeping", push, weight, woke.size(), overlap);
  EXPECT_GT(push, 0.02 * weight) << "the finger pressed into the pile";
  EXPECT_LT(overlap, 0.1) << "nothing interpenetrates, asleep or awake";
  EXPECT_TRUE(allFinite(world));
  if (sleeping) {
    EXPECT_GE(woke.size(), 2u) << "the finger wakes what it stirs";
    for (steps = 0; steps < std::lround(20.0 / dt) && world.sleepingCount() < asleep; ++steps) world.step();
    std::printf("the pile sleeps again after %.1f s: %zu asleep\n", steps * dt, world.sleepingCount());
    EXPECT_GE(world.sleepingCount(), asleep);
  }
  return push;
}

TEST(WorldSleep, ABinAtRestSleepsAndWakesWhereAFingerPressesIt) {
  const double awake = pressTheBin(false), sleeping = pressTheBin(true);
  EXPECT_NEAR(sleeping, awake, 0.15 * awake) << "the sleeping pile resists the finger as the awake one does";
}

// Forty 5 cm bunnies of the classic material (alpha 1, 142 particles), dropped spinning into a
// bin and left to sleep, then a 2 cm finger pressed 3 cm into one corner at 2 cm/s (the scene
// of bench_world's bin, smaller). A sleeping object is woken by the objects that move against
// it, not by the jiggle of those woken around it: the press wakes about as many objects as it
// moves by more than 0.03 r in the same pile never put to sleep, and meets the same force.
struct BunnyPress {
  double push = 0.0;
  std::size_t woke = 0, moved = 0;
};
/// Forty bunnies of 5 cm dropped into a bin in four-by-four layers, each spinning (seeded).
static void dropFortyBunnies(World& world, double dt, double size) {
  const int n = 40, side = 4;
  const auto shape = meshAt(kBunnyMeshPath, true, 0.0, size, 7, Eigen::Vector3d::Zero());
  Eigen::Vector3d extent = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& x : shape->restPositions()) extent = extent.cwiseMax(x);
  const double pitch = 1.15 * size, inner = 0.5 * side * pitch + 0.01;
  for (const auto& c : binColliders(inner, 0.3, 0.05)) world.setCollider(c.first, c.second);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int i = 0; i < n; ++i) {
    const int layer = i / (side * side), k = i % (side * side);
    const double shift = layer % 2 == 0 ? 0.0 : 0.3 * pitch;
    const Eigen::Vector3d lo(-inner + 0.01 + pitch * (k % side) + 0.5 * shift, -inner + 0.01 + pitch * (k / side) + shift,
                             0.005 + 1.2 * size * layer);
    auto lattice = meshAt(kBunnyMeshPath, true, 0.0, size, 7, lo);
    SolverParams p;
    p.regionHalfWidth = lattice->regionHalfWidth();
    p.stiffness = 1.0;
    p.timeStep = dt;
    p.substeps = 8;
    p.ambientDamping = 2.0;
    Solver& s = world.addObject("o" + std::to_string(i), lattice, p);
    const Eigen::Vector3d centre = lo + 0.5 * extent, spin = 4.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    std::vector<Eigen::Vector3d> v(lattice->size());
    for (std::size_t j = 0; j < v.size(); ++j) v[j] = spin.cross(s.positions()[j] - centre);
    s.setVelocities(v);
  }
}

/// A sphere "finger" of 2 cm set on the pile a quarter of the way across; each object's positions
/// before it presses.
static std::vector<std::vector<Eigen::Vector3d>> fingerOnThePile(World& world, const std::vector<std::string>& names) {
  std::vector<std::vector<Eigen::Vector3d>> start;
  Eigen::Vector3d lo = world.object(names[0])->positions()[0], hi = lo;
  for (const std::string& name : names) {
    start.push_back(world.object(name)->positions());
    for (const Eigen::Vector3d& x : start.back()) {
      lo = lo.cwiseMin(x);
      hi = hi.cwiseMax(x);
    }
  }
  const Eigen::Vector2d at = lo.head<2>() + 0.25 * (hi - lo).head<2>();
  double top = lo.z();
  for (const auto& xs : start)
    for (const Eigen::Vector3d& x : xs)
      if ((x.head<2>() - at).norm() < 0.01) top = std::max(top, x.z());
  Collider finger;
  finger.shape.type = ColliderType::Sphere;
  finger.shape.radius = 0.02;
  finger.pose.translation() = Eigen::Vector3d(at.x(), at.y(), top + finger.shape.radius);
  world.setCollider("finger", finger);
  return start;
}

/// The objects whose mass-weighted displacement from `start` exceeds 0.03 of a contact radius.
static std::size_t movedObjects(const World& world, const std::vector<std::string>& names,
                                const std::vector<std::vector<Eigen::Vector3d>>& start) {
  std::size_t moved = 0;
  for (std::size_t o = 0; o < names.size(); ++o) {
    const Solver& s = *world.object(names[o]);
    const auto& m = s.lattice().masses();
    double d = 0.0, mass = 0.0;
    for (std::size_t i = 0; i < m.size(); ++i) {
      d += m[i] * (s.positions()[i] - start[o][i]).squaredNorm();
      mass += m[i];
    }
    if (std::sqrt(d / mass) > 0.03 * s.contactRadius()) ++moved;
  }
  return moved;
}

static BunnyPress pressTheBunnies(bool sleeping) {
  const double dt = 1.0 / 30.0, size = 0.05;
  World world(dt, 8);
  if (sleeping) world.setSleepParams(sleepAfter(1.0));
  dropFortyBunnies(world, dt, size);
  for (int i = 0; i < 300; ++i) world.step();
  if (sleeping) {
    std::printf("bin of 40 bunnies with sleeping: %zu asleep after 10 s\n", world.sleepingCount());
    EXPECT_GE(world.sleepingCount(), 36u) << "the pile rests";
  }
  const auto names = world.objectNames();
  const std::vector<std::vector<Eigen::Vector3d>> start = fingerOnThePile(world, names);
  BunnyPress press;
  std::set<std::string> woke;
  double overlap = 0.0;
  for (int i = 0; i < 45; ++i) {
    world.moveCollider("finger", world.object(names[0])->colliders().at("finger").pose, Eigen::Vector3d(0, 0, -0.02),
                       Eigen::Vector3d::Zero());
    world.step();
    press.push = std::max(press.push, world.contactWrench("finger").force.norm());
    for (const std::string& name : names)
      if (!world.asleep(name)) woke.insert(name);
    overlap = std::max(overlap, deepestOverlap(world));
  }
  press.woke = woke.size();
  press.moved = movedObjects(world, names, start);
  std::printf("finger pressed into 40 bunnies (%s): up to %.3g N, %zu objects awake in the push, %zu moved farther than "
              "0.03 r; deepest overlap %.3g r\n",
              sleeping ? "sleeping" : "never sleeping", press.push, press.woke, press.moved, overlap);
  // the squeeze under the finger: 0.25-0.32 r over variants of the passes (order, tolerance), a
  // third of a radius at most; objects passing through each other would be 2 r
  EXPECT_LT(overlap, 0.35) << "nothing interpenetrates";
  EXPECT_TRUE(allFinite(world));
  return press;
}

TEST(WorldSleep, AFingerPressedIntoAPileOfBunniesWakesWhatItMoves) {
  const BunnyPress awake = pressTheBunnies(false), sleeping = pressTheBunnies(true);
  EXPECT_NEAR(sleeping.push, awake.push, 0.15 * awake.push) << "the sleeping pile resists the finger as the awake one does";
  EXPECT_GE(sleeping.woke, 2u) << "the finger wakes what it stirs";
  EXPECT_LE(sleeping.woke, awake.moved + awake.moved / 4) << "it wakes what the press moves, not the whole pile";
}
