// Contact under abuse: colliders set into or around the object push it out without throwing
// it, pinned objects buried in giant colliders and flooded with drags stay bounded, and the
// bunny squeezed, dragged through a sphere, dropped and pressed flat recovers its shape.
#include "deformable_flsm/core/contact.h"

#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/section.h"
#include "deformable_flsm/core/solver.h"
#include "contact_fixtures.h"
#include "fixtures.h"
#include "support/params.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::contact_fixtures;

TEST(Contact, ColliderSetIntoTheObjectPushesItOutWithoutThrowingIt) {
  // A wall set (or moved, or the object reset) through a weightless, undamped block at rest:
  // half of the block is inside it. The wall is at rest and does no work, so the energy the
  // block can have afterwards is what pushing its particles out stores in shape matching's
  // springs: moved d_i out against k_i = alpha m_i / h^2 (v += alpha (g - x) / h), at most
  // E = sum_i alpha m_i d_i^2 / (2 h^2). Handing each particle the velocity d_i / h that ends
  // it on the surface in one sub-step gives 1 / alpha times that as kinetic energy instead, and
  // where colliders overlap it grew without bound (the soak's blown-up states).
  auto lattice = std::make_shared<const Lattice>(test::makeBox(8, 8, 8, 0.01), 1000.0, 2);
  // the node's default material and sub-steps: alpha 0.34
  SolverParams p = test::physicalParams(3e4, 0.0, lattice->regionHalfWidth(), 1.0 / 60.0, 11);
  p.gravity.setZero();
  p.damping = 0.0;
  p.ambientDamping = 0.0;
  Solver s(lattice, p);
  Collider wall;  // its solid is the side below a plane through the centre, tilted 45 degrees
  wall.pose = Eigen::Translation3d(centreOfMass(s)) * Eigen::AngleAxisd(M_PI / 4, Eigen::Vector3d::UnitY());
  wall.staticFriction = wall.kineticFriction = 0.0;
  const double h = p.substepLength();
  double stored = 0.0;
  for (std::size_t i = 0; i < s.positions().size(); ++i) {
    Eigen::Vector3d n;
    const double d = colliderDistance(wall.shape, wall.pose, s.positions()[i], n) - s.contactRadius();
    if (d < 0.0) stored += s.alpha() * lattice->masses()[i] * d * d / (2.0 * h * h);
  }
  ASSERT_GT(stored, 0.0);
  s.setCollider("wall", wall);
  double worst = 0.0;
  for (int i = 0; i < stepsFor(2.0, s); ++i) {
    s.step();
    ASSERT_TRUE(allFinite(s));
    worst = std::max(worst, s.kineticEnergy());
  }
  std::printf("[ set in  ] alpha %.3f: kinetic energy at most %.3g J; the push-out stores at most %.3g J\n",
              s.alpha(), worst, stored);
  EXPECT_LT(worst, stored);
  double deepest = 0.0;
  for (const auto& x : s.positions()) {
    Eigen::Vector3d n;
    deepest = std::max(deepest, s.contactRadius() - colliderDistance(wall.shape, wall.pose, x, n));
  }
  EXPECT_LT(deepest, 1e-9) << "pushed out all the same";
}

TEST(Contact, AColliderSetAroundTheObjectPushesItOutAtABoundedPace) {
  // A sphere of 1e9 m set around a block (a size a client may send: finite and positive): every
  // particle is deep inside. Moved out at most its contact radius r per sub-step, a particle is
  // after n sub-steps at most n r from where it was by projection, and at most as much again by
  // the velocity shape matching's spring-back gives it from that displacement; thrown to the
  // surface at once it would be 1e9 m away, and shape matching pulling it back over one sub-step
  // would blow the state up.
  auto lattice = std::make_shared<const Lattice>(test::makeBox(4, 4, 4, 0.01), 1000.0, 1);
  SolverParams p = sceneParams(*lattice);
  p.gravity.setZero();
  Solver s(lattice, p);
  Collider giant;
  giant.shape.type = ColliderType::Sphere;
  giant.shape.radius = 1e9;
  giant.pose.translation() = centreOfMass(s);
  s.setCollider("giant", giant);
  const int steps = stepsFor(0.5, s);
  for (int i = 0; i < steps; ++i) s.step();
  ASSERT_TRUE(allFinite(s));
  double farthest = 0.0;
  for (std::size_t i = 0; i < s.positions().size(); ++i)
    farthest = std::max(farthest, (s.positions()[i] - lattice->restPositions()[i]).norm());
  const double pace = steps * p.substeps * s.contactRadius();
  std::printf("[ giant   ] after %d sub-steps the farthest particle moved %.3g m (bound %.3g m)\n",
              steps * p.substeps, farthest, 2.0 * pace);
  EXPECT_LE(farthest, 2.0 * pace);
}

TEST(Contact, AHalfPinnedObjectInsideAGiantSphereAndBelowAPlaneStaysBounded) {
  // The soak's blown-up states: half the bunny pinned, a stiff material at the cap on alpha, a
  // sphere of 1e9 m set around it (its centre inside the object), a tilted plane through it, the
  // gravity reconfigured upwards, friction, ambient damping. The pinned half keeps the free half
  // near the sphere's centre, where the depth changes direction within a particle's path: a
  // response of "no deeper than at the start" alone throws a particle passing the centre on
  // along its motion, and the speeds grow geometrically (see contactVelocityChange()). The
  // object cannot leave the sphere, so the push-out keeps stretching it at its bounded pace: the
  // farthest particle is at most twice n r from rest after n sub-steps (as a free object's, see
  // AColliderSetAroundTheObjectPushesItOutAtABoundedPace), and the speeds must not grow faster
  // than that displacement does (linearly: the last third's at most twice the second's).
  const BunnyScene scene = bunnyScene();
  SolverParams p = sceneParams(*scene.lattice);
  p.youngsModulus = 1e7;
  p.substeps = 11;
  p.damping = 12.4;
  p.ambientDamping = 2.07;
  p.gravity = Eigen::Vector3d(0, 0, 3.81);
  Solver s(scene.lattice, p);
  ASSERT_TRUE(s.stiffnessSaturated());
  const Eigen::Vector3d c = centreOfMass(s);
  ASSERT_GT(s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(c.x(), 1.0, 1.0), true), 0u);
  Collider giant;
  giant.shape.type = ColliderType::Sphere;
  giant.shape.radius = 1e9;
  giant.pose.translation() = c + Eigen::Vector3d(0.01, 0.02, 0.005);
  giant.staticFriction = giant.kineticFriction = 0.5;
  s.setCollider("giant", giant);
  Collider plane;  // the solid below a plane through the centre, tilted
  plane.pose = Eigen::Translation3d(c) * Eigen::AngleAxisd(0.4, Eigen::Vector3d::UnitX());
  plane.staticFriction = plane.kineticFriction = 0.5;
  s.setCollider("plane", plane);
  const int steps = 300;
  double second = 0.0, last = 0.0;
  for (int i = 0; i < steps; ++i) {
    s.step();
    ASSERT_TRUE(allFinite(s)) << "step " << i;
    if (i >= 2 * steps / 3)
      last = std::max(last, maxSpeed(s));
    else if (i >= steps / 3)
      second = std::max(second, maxSpeed(s));
  }
  const double pace = steps * p.substeps * s.contactRadius();
  std::printf("[ flood   ] %zu of %zu pinned, alpha %.2f: farthest particle %.3g m from rest (bound %.3g m), "
              "top speed %.3g m/s then %.3g m/s\n", s.pinnedCount(), s.positions().size(), s.alpha(),
              s.maxDisplacement(), 2.0 * pace, second, last);
  EXPECT_LE(s.maxDisplacement(), 2.0 * pace);
  EXPECT_LE(last, 2.0 * second);
}

namespace {

/// The node's default object: the bunny at its particle budget of 2500 (2472 particles, w = 1
/// across the ears' section), so that E 1e7 Pa saturates alpha at the explicit step's cap.
struct NodeBunny {
  std::shared_ptr<const Lattice> lattice;
  SolverParams params;
};

NodeBunny nodeBunny() {
  NodeBunny b;
  const ResolutionChoice c = finestResolutionWithin(zUpBunny(), 2500);
  const int w = regionHalfWidthForSection(measureSectionThickness(c.voxels).thinnest, 5);
  b.lattice = std::make_shared<const Lattice>(c.voxels, 1000.0, w);
  b.params = test::physicalParams(1e7, 0.0, w, 1.0 / 60.0, 11);
  return b;
}

/// Uniform in [-1, 1] from the generator's raw output (the same sequence with any library).
double uniform(std::mt19937& rng) { return 2.0 * static_cast<double>(rng()) / 4294967295.0 - 1.0; }

struct FloodFigures {
  double topSpeed = 0.0;  // m/s, over the run
  double farthest = 0.0;  // m, the farthest particle from rest at the end
  double stretch = 0.0;   // m, the largest shapeError() (RMS distance from the best rigid fit)
  int blownUpAt = -1;     // the step the guard's threshold (1e12 m or m/s) was passed
};

/// A scene of the soak's kind, drawn from a seed.
struct FloodScene {
  unsigned seed = 1;
  bool pins = true;              // the part of the object on one side of its centre pinned
  bool giant = true;             // a collider of 1e9 m around the object
  ColliderType giantType = ColliderType::Sphere;
  int planes = 0;                // tilted planes through the object's centre, 0 to 2
  double youngsModulus = 1e7;    // Pa
  double damping = 10.0, ambientDamping = 0.5;  // 1/s
  double gravityZ = -9.81;       // m/s^2
};

/// The soak's scene in the core: the object with the ground below, a collider of 1e9 m centred
/// within 0.1 m of the object's centre (every particle buried), planes, part of it pinned, and
/// every 7 steps a drag of 1 or 7 particles (hard, or a spring of 50 N/m) to a target within
/// reach of the centre of mass, released every 11 steps.
FloodFigures flood(const NodeBunny& b, const FloodScene& scene, int steps) {
  std::mt19937 rng(scene.seed);
  SolverParams p = b.params;
  p.youngsModulus = scene.youngsModulus;
  p.damping = scene.damping;
  p.ambientDamping = scene.ambientDamping;
  p.gravity = Eigen::Vector3d(0, 0, scene.gravityZ);
  Solver s(b.lattice, p);
  s.setCollider("ground", groundBelow(s, 0.02));
  const Eigen::Vector3d c = centreOfMass(s);
  if (scene.pins)
    s.pinBox(Eigen::Vector3d::Constant(-10.0), Eigen::Vector3d(c.x() + 0.02 * uniform(rng), 10.0, 10.0), true);
  if (scene.giant) {
    Collider giant;
    giant.shape.type = scene.giantType;
    giant.shape.radius = 1e9;
    giant.shape.halfLength = 0.05;
    giant.pose.translation() = c + 0.1 * Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
    giant.staticFriction = 0.5;
    giant.kineticFriction = 0.3;
    s.setCollider("giant", giant);
  }
  for (int k = 0; k < scene.planes; ++k) {
    Collider plane;
    const Eigen::Vector3d axis = Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng)).normalized();
    plane.pose = Eigen::Translation3d(c) * Eigen::AngleAxisd(M_PI * uniform(rng), axis);
    plane.staticFriction = plane.kineticFriction = 0.5;
    s.setCollider("plane" + std::to_string(k), plane);
  }
  FloodFigures f;
  for (int i = 0; i < steps; ++i) {
    if (i % 7 == 0) {
      const Eigen::Vector3d com = centreOfMass(s);
      const Eigen::Vector3d point = com + 0.12 * Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
      const std::vector<std::uint32_t> particles =
          rng() % 2 != 0 ? s.nearestParticles(point, 7)
                         : std::vector<std::uint32_t>{static_cast<std::uint32_t>(rng() % s.positions().size())};
      const Eigen::Vector3d target = com + 0.12 * Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
      const double stiffness = rng() % 3 == 0 ? 50.0 : 0.0;
      try {
        s.grab("d", particles, target, stiffness);
      } catch (const std::invalid_argument&) {  // a spring over the stability limit: refused
      }
    }
    if (i % 11 == 0) s.release("d");
    s.step();
    const double v = maxSpeed(s);
    f.topSpeed = std::max(f.topSpeed, v);
    if (!allFinite(s) || !(v < 1e12) || !(s.maxDisplacement() < 1e12)) {
      f.blownUpAt = i;
      break;
    }
    if (i % 20 == 0) f.stretch = std::max(f.stretch, s.shapeError());
  }
  f.farthest = s.maxDisplacement();
  return f;
}

/// The diagonal of the object's rest bounding box (m).
double objectSize(const Solver& s) {
  Eigen::Vector3d lo = s.positions()[0], hi = lo;
  for (const auto& x : s.positions()) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  return (hi - lo).norm();
}

}  // namespace

TEST(Contact, DragsOnAPinnedObjectBuriedInAGiantColliderStayBounded) {
  // The soak's remaining blown-up states: the node's bunny, E 1e7 Pa (alpha at its cap, above 1),
  // most of it pinned, buried in a sphere or capsule of 1e9 m, and drags grabbed and released.
  // Near the collider's centre the outward normal turns within a sub-step's path, and stopping
  // a buried particle's "approach" there (the contact velocity response) is a one-sided filter on
  // its velocity that, with shape matching's overshoot at alpha > 1, pumped a drag's yank up a
  // little every few sub-steps until the state passed 1e12. Bound: shape matching changes a
  // particle's velocity by alpha (g - x) / h per sub-step, g - x at most the object's extent
  // D, and the dampings take it out again over a few sub-steps: the speeds stay below
  // alpha 2 D / h. D: pins hold one side and the hard drags' targets are within 0.21 m (0.7 L)
  // of the centre of mass, so a particle pulled by them stays within about L of where its
  // regions' shape puts it, and with the push-out's r per particle within D = L + 2 L of its
  // goal; the stretch (shapeError(), the RMS distance from the best rigid fit) stays below
  // that same D. Which drags a seed draws decides how far below: the stretch of these scenes
  // spreads from under L to above 2 L with any change of the contact response (friction on
  // the ground included), so the bound is the extent itself, not a figure of one run. Pushed
  // out without bound (the free side away from the pins at r per sub-step) the stretch grows
  // with the steps, some fifty times L in 600 steps.
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const NodeBunny b = nodeBunny();
  const Solver probe(b.lattice, b.params);
  ASSERT_TRUE(probe.stiffnessSaturated());
  ASSERT_GT(probe.alpha(), 1.0);
  const double L = objectSize(probe);
  const double speedBound = probe.alpha() * 2.0 * 3.0 * L / b.params.substepLength();
  const struct {
    unsigned seed;
    ColliderType type;
  } cases[] = {{1, ColliderType::Sphere}, {4, ColliderType::Sphere}, {2, ColliderType::Capsule}, {4, ColliderType::Capsule}};
  for (const auto& c : cases) {
    FloodScene scene;
    scene.seed = c.seed;
    scene.giantType = c.type;
    const FloodFigures f = flood(b, scene, 600);
    std::printf("[ buried  ] seed %u, %s: top speed %.3g m/s (bound %.3g), stretch %.3g m (bound %.3g), farthest "
                "particle %.3g m%s\n", c.seed, toString(c.type), f.topSpeed, speedBound, f.stretch, 3.0 * L, f.farthest,
                f.blownUpAt >= 0 ? (", BLOWN UP at step " + std::to_string(f.blownUpAt)).c_str() : "");
    EXPECT_EQ(f.blownUpAt, -1) << "seed " << c.seed;
    EXPECT_LT(f.topSpeed, speedBound) << "seed " << c.seed;
    EXPECT_LT(f.stretch, 3.0 * L) << "seed " << c.seed;
  }
}

TEST(Contact, RandomFloodScenesStayBoundedForTwoThousandSteps) {
  // Scenes of the soak's kind drawn at random: pins on part of the object or none, a 1e9 m sphere
  // or capsule around it or none, 0 to 2 planes through it, E 1e7 Pa (alpha at the cap) or
  // 3e4 Pa, the soak's ranges of damping and gravity, drags grabbed and released, 2000 steps.
  // The bounds of the test above: the stretch below 3 L, the speeds below alpha 2 (3 L) / h,
  // never the guard's 1e12 m or m/s. A buried object that nothing holds leaves the collider as
  // a body (at most r per sub-step), so its distance from rest is not bounded; its shape is.
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const NodeBunny b = nodeBunny();
  const Solver probe(b.lattice, b.params);
  const double L = objectSize(probe);
  std::mt19937 draw(2026);
  const int scenes = 8;
  for (int k = 0; k < scenes; ++k) {
    FloodScene scene;
    scene.seed = draw();
    scene.pins = draw() % 2 == 0;
    scene.giant = draw() % 4 != 0;
    scene.giantType = draw() % 2 == 0 ? ColliderType::Sphere : ColliderType::Capsule;
    scene.planes = static_cast<int>(draw() % 3);
    scene.youngsModulus = draw() % 3 == 0 ? 3e4 : 1e7;
    scene.damping = 15.0 + 15.0 * uniform(draw);
    scene.ambientDamping = 1.5 + 1.5 * uniform(draw);
    scene.gravityZ = -7.5 + 12.5 * uniform(draw);
    SolverParams p = b.params;
    p.youngsModulus = scene.youngsModulus;
    const Solver material(b.lattice, p);
    const FloodFigures f = flood(b, scene, 2000);
    const double speedBound = material.alpha() * 2.0 * 3.0 * L / p.substepLength();
    std::printf("[ flood   ] scene %d: pins %d, giant %s, %d plane(s), E %.3g Pa, alpha %.2f: top speed %.3g m/s "
                "(bound %.3g), stretch %.3g m (bound %.3g), farthest particle %.3g m%s\n",
                k, scene.pins ? 1 : 0, scene.giant ? toString(scene.giantType) : "none", scene.planes,
                scene.youngsModulus, material.alpha(), f.topSpeed, speedBound, f.stretch, 3.0 * L, f.farthest,
                f.blownUpAt >= 0 ? (", BLOWN UP at step " + std::to_string(f.blownUpAt)).c_str() : "");
    EXPECT_EQ(f.blownUpAt, -1) << "scene " << k;
    EXPECT_LT(f.topSpeed, speedBound) << "scene " << k;
    EXPECT_LT(f.stretch, 3.0 * L) << "scene " << k;
  }
}

namespace {

/// Lets the object go (colliders and drags removed), runs `seconds` without gravity and returns
/// shapeError / object size.
double recoveryError(Solver& s, double seconds) {
  s.removeAllColliders();
  s.releaseAll();
  SolverParams p = s.params();
  p.gravity.setZero();
  s.setParams(p);
  for (int i = 0; i < stepsFor(seconds, s); ++i) s.step();
  return s.shapeError() / s.lattice().objectSize();
}

/// Squeezed to 2 cm between two boxes.
void abuseSqueezed(const BunnyScene& scene, double recovered) {
  Solver s(scene.lattice, sceneParams(*scene.lattice));
  s.setCollider("ground", groundBelow(s, 0.0));
  const Eigen::Vector3d c = centreOfMass(s);
  const Eigen::Vector3d half(0.2, 0.02, 0.2);
  s.setCollider("left", world_scenes::box(Eigen::Vector3d(c.x(), c.y() - 0.12, c.z()), half, 0.5));
  s.setCollider("right", world_scenes::box(Eigen::Vector3d(c.x(), c.y() + 0.12, c.z()), half, 0.5));
  setVelocity(s, "left", Eigen::Vector3d(0, 0.09, 0));
  setVelocity(s, "right", Eigen::Vector3d(0, -0.09, 0));
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();  // faces 2 cm apart
  setVelocity(s, "left", Eigen::Vector3d::Zero());
  setVelocity(s, "right", Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();
  // squeezed material may flow out past the boxes' edges, never into them
  double deepest = 0.0;
  for (const auto& x : s.positions())
    for (const char* id : {"left", "right"}) {
      Eigen::Vector3d n;
      const Collider& box = s.colliders().at(id);
      deepest = std::max(deepest, s.contactRadius() - colliderDistance(box.shape, box.pose, x, n));
    }
  EXPECT_LT(deepest, 1e-9) << "no particle sphere inside a box";
  ASSERT_TRUE(allFinite(s));
  const double error = recoveryError(s, 4.0);
  std::printf("[ abuse   ] squeezed to 2 cm: shape error after 4 s %.3f %% of the size\n", 100 * error);
  EXPECT_LT(error, recovered);
  EXPECT_TRUE(allFinite(s));
}

/// Dragged through a sphere, weightless.
void abuseDraggedThroughASphere(const BunnyScene& scene, double recovered) {
  SolverParams p = sceneParams(*scene.lattice);
  p.gravity.setZero();
  Solver s(scene.lattice, p);
  const Eigen::Vector3d c = centreOfMass(s);
  Collider ball;
  ball.shape.type = ColliderType::Sphere;
  ball.shape.radius = 0.03;
  ball.pose.translation() = c + Eigen::Vector3d(0.15, 0, 0);
  s.setCollider("ball", ball);
  const auto grabbed = s.nearestParticles(c, 20);
  s.grab("hand", grabbed, c, 0.0);
  for (int i = 1; i <= stepsFor(2.0, s); ++i) {
    s.moveDrag("hand", c + Eigen::Vector3d(0.3 * i / stepsFor(2.0, s), 0, 0));
    s.step();
  }
  ASSERT_TRUE(allFinite(s));
  const double error = recoveryError(s, 4.0);
  std::printf("[ abuse   ] dragged through a sphere: shape error after 4 s %.3f %% of the size\n", 100 * error);
  EXPECT_LT(error, recovered);
}

/// Dropped from 2 m.
void abuseDropped(const BunnyScene& scene, double recovered) {
  Solver s(scene.lattice, sceneParams(*scene.lattice));
  const Collider ground = groundBelow(s, 2.0);
  s.setCollider("ground", ground);
  double deepest = 0.0, worstShape = 0.0;
  for (int i = 0; i < stepsFor(2.0, s); ++i) {
    s.step();
    deepest = std::max(deepest, ground.pose.translation().z() + s.contactRadius() - lowestZ(s));
    worstShape = std::max(worstShape, s.shapeError() / s.lattice().objectSize());
  }
  ASSERT_TRUE(allFinite(s));
  for (int i = 0; i < stepsFor(4.0, s); ++i) s.step();
  // against the same bunny set down gently: what resting on the ground under its weight costs
  Solver gentle(scene.lattice, sceneParams(*scene.lattice));
  gentle.setCollider("ground", groundBelow(gentle, 0.0));
  for (int i = 0; i < stepsFor(4.0, gentle); ++i) gentle.step();
  const double onGround = s.shapeError() / s.lattice().objectSize();
  const double reference = gentle.shapeError() / gentle.lattice().objectSize();
  // On the ground the sag depends on the side the bunny landed on (upright when set down
  // gently, often on its side after the drop), so recovery is judged as in the other scenes:
  // let go (no collider, no gravity), it returns to its rest shape.
  const double error = recoveryError(s, 4.0);
  std::printf("[ abuse   ] dropped from 2 m: worst shape error %.2f %%, 4 s later on the ground %.3f %% (set down "
              "gently: %.3f %%), let go 4 s %.3f %%; deepest sphere %.2g m\n", 100 * worstShape,
              100 * onGround, 100 * reference, 100 * error, deepest);
  EXPECT_LT(deepest, 1e-9);
  EXPECT_LT(error, recovered);
}

/// Pressed flat by a box to 3 cm above the ground.
void abusePressedFlat(const BunnyScene& scene, double recovered) {
  Solver s(scene.lattice, sceneParams(*scene.lattice));
  const Collider ground = groundBelow(s, 0.0);
  s.setCollider("ground", ground);
  const Eigen::Vector3d c = centreOfMass(s);
  const double top = lowestZ(s) + (scene.lattice->restMax() - scene.lattice->restMin()).z() + 0.01;
  const Eigen::Vector3d half(0.2, 0.2, 0.02);
  s.setCollider("press", world_scenes::box(Eigen::Vector3d(c.x(), c.y(), top + half.z() + 0.01), half, 0.5));
  const double travel = top + 0.01 - (ground.pose.translation().z() + 0.03);
  setVelocity(s, "press", Eigen::Vector3d(0, 0, -travel));
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();
  setVelocity(s, "press", Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();
  double highest = -1.0;
  for (const auto& x : s.positions()) highest = std::max(highest, x.z() + s.contactRadius());
  ASSERT_TRUE(allFinite(s));
  const double error = recoveryError(s, 4.0);
  std::printf("[ abuse   ] pressed flat (highest sphere %.1f mm above the ground): shape error after 4 s "
              "%.3f %%\n", 1e3 * (highest - ground.pose.translation().z()), 100 * error);
  EXPECT_LT(highest - ground.pose.translation().z(), 0.03 + 1e-9);
  EXPECT_LT(error, recovered);
}

}  // namespace

TEST(ContactScene, AbuseLeavesTheBunnyFiniteAndItRecoversItsShape) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const BunnyScene scene = bunnyScene();
  const double recovered = 0.01;  // shapeError below 1 % of the size, as the stress scenarios ask
  abuseSqueezed(scene, recovered);
  abuseDraggedThroughASphere(scene, recovered);
  abuseDropped(scene, recovered);
  abusePressedFlat(scene, recovered);
}
