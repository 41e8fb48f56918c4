// Contact scenes whose figures are printed with the test output: a bunny dropped on the
// ground, a block on an incline, a grasp by two fingers, a sphere pressed into the bunny and an
// indenter moved into it in one command.
#include "deformable_flsm/core/contact.h"

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/mesh.h"
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
#include <string>
#include <utility>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::contact_fixtures;

TEST(ContactScene, BunnyDroppedOnTheGroundComesToRest) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const BunnyScene scene = bunnyScene();
  Solver s(scene.lattice, sceneParams(*scene.lattice));
  const Collider ground = groundBelow(s, 0.10);
  s.setCollider("ground", ground);
  const double zg = ground.pose.translation().z(), r = s.contactRadius();
  const double W = scene.lattice->totalMass() * kG;
  // at rest: the kinetic energy, averaged over half a second, stays below 0.1 % of the energy of
  // the fall (a thin ear, one cell across, keeps trembling long after the body has settled)
  const double dropEnergy = W * 0.10, kRestEnergy = 1e-3;
  double deepest = 0.0, lastMoving = 0.0;
  std::vector<double> energy(static_cast<std::size_t>(stepsFor(0.5, s)), 0.0);
  const int steps = stepsFor(8.0, s);
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  const int averaged = 30;
  for (int i = 0; i < steps; ++i) {
    s.step();
    ASSERT_TRUE(allFinite(s));
    deepest = std::max(deepest, zg + r - lowestZ(s));
    // the mean over the last half second: an ear tip chattering on the ground makes spikes
    energy[static_cast<std::size_t>(i) % energy.size()] = s.kineticEnergy();
    double mean = 0.0;
    for (double e : energy) mean += e / static_cast<double>(energy.size());
    if (mean > kRestEnergy * dropEnergy) lastMoving = s.time();
    if (i >= steps - averaged) force += s.contactWrench("ground").force / averaged;
  }
  const Embedding embedding(*scene.lattice, scene.mesh.vertices);
  TriMesh deformed = scene.mesh;
  embedding.deform(s.positions(), s.regionRotations(), deformed.vertices);
  double vertexDepth = 0.0;
  for (const auto& v : deformed.vertices) vertexDepth = std::max(vertexDepth, zg - v.z());
  const double volumeChange = test::signedVolume(deformed) / test::signedVolume(scene.mesh) - 1.0;
  std::vector<Eigen::Vector3d> projected = deformed.vertices;
  const std::size_t moved = projectOutOfColliders(projected, s.colliders(), 0.0);
  double projectedDepth = 0.0;
  for (const auto& v : projected) projectedDepth = std::max(projectedDepth, zg - v.z());
  const double spacing = scene.lattice->spacing();
  std::printf("[ drop    ] bunny %zu particles (spacing %.1f mm), 10 cm onto the ground: at rest (kinetic "
              "energy over 0.5 s < 0.1 %% of m g h) after %.2f s; deepest particle sphere %.2g m; render vertices %.2f mm (%.0f %% of the "
              "spacing) below the ground, %zu moved out by projectOutOfColliders (then %.2g m); volume change "
              "%+.2f %%; ground force %.4f N vs weight %.4f N (%+.2f %%)\n",
              scene.lattice->size(), 1e3 * spacing, lastMoving, deepest, 1e3 * vertexDepth,
              100 * vertexDepth / spacing, moved, projectedDepth, 100 * volumeChange, -force.z(), W,
              100 * (-force.z() / W - 1));
  EXPECT_LT(lastMoving, 7.5) << "the bunny settles within the run";
  EXPECT_LT(deepest, 1e-9) << "no particle sphere ends a sub-step inside the ground";
  EXPECT_LT(vertexDepth, 0.1 * spacing) << "render vertices stay on the ground (without projection)";
  EXPECT_LT(projectedDepth, 1e-12);
  EXPECT_LT(std::abs(volumeChange), 0.05);  // shape matching keeps volume only as shape
  EXPECT_NEAR(-force.z(), W, 0.02 * W) << "at rest the ground carries the weight";
  EXPECT_LT(force.head<2>().norm(), 0.02 * W);
}

namespace {

/// A 10 x 5 x 3 cm block settles on a horizontal plane through the origin, which then tilts
/// slowly (0.1 rad/s, about y) to theta: downhill is the plane's +x. Returns the block's downhill
/// displacement along the plane over `settle` seconds after the tilt, and its downhill
/// acceleration over the following `measure` seconds.
struct InclineResult {
  double displacement;
  double acceleration;
};

InclineResult slideOnIncline(double theta, double mus, double muk, double settle, double measure) {
  auto lattice = std::make_shared<const Lattice>(test::makeBox(10, 5, 3, 0.01), 1000.0, 2);
  // alpha = 1 makes the block ring at every sub-step, and a ringing block creeps down a slope
  // it would stand on (each chattering contact slips a little): a softer block stands still.
  SolverParams p = sceneParams(*lattice, 0.3);
  p.ambientDamping = 0.0;  // air drag would slow the slide
  Solver s(lattice, p);
  Collider plane;  // the lattice's cells fill [0, 0.1] x [0, 0.05] x [0, 0.03]: on the plane
  plane.staticFriction = mus;
  plane.kineticFriction = muk;
  s.setCollider("incline", plane);
  for (int i = 0; i < stepsFor(0.5, s); ++i) s.step();
  const int tilting = std::max(1, stepsFor(theta / 0.1, s));
  const Eigen::Vector3d omega(0, theta / (tilting * p.timeStep), 0);
  s.moveCollider("incline", Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), omega);
  for (int i = 0; i < tilting; ++i) s.step();
  const Eigen::Isometry3d tilted(Eigen::AngleAxisd(theta, Eigen::Vector3d::UnitY()));
  const Eigen::Isometry3d& reached = s.colliders().at("incline").pose;
  EXPECT_LT((reached.linear() - tilted.linear()).cwiseAbs().maxCoeff(), 1e-9) << "the tilt reached theta";
  EXPECT_LT(reached.translation().norm(), 1e-12);
  s.moveCollider("incline", tilted, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  const Eigen::Vector3d downhill = tilted.linear().col(0);
  const double along0 = centreOfMass(s).dot(downhill);
  auto velocity = [&] { return s.linearMomentum().dot(downhill) / lattice->totalMass(); };
  for (int i = 0; i < stepsFor(settle, s); ++i) s.step();
  const double displacement = centreOfMass(s).dot(downhill) - along0;
  const double v1 = velocity(), t1 = s.time();
  for (int i = 0; i < stepsFor(measure, s); ++i) s.step();
  return {displacement, (velocity() - v1) / (s.time() - t1)};
}

}  // namespace

TEST(ContactScene, BlockOnAnInclineSticksBelowTheFrictionAngleAndSlidesAbove) {
  const double mus = 0.6;
  // Coulomb with mu_k = mu_s: the block holds up to the friction angle.
  for (double ratio : {0.5, 0.9}) {
    const double theta = std::atan(ratio * mus);
    const InclineResult held = slideOnIncline(theta, mus, mus, 2.0, 1.0);
    std::printf("[ incline ] mu_s = mu_k = %.1f, theta %.1f deg (tan = %.1f mu_s): moved %.3f mm in 2 s, "
                "acceleration %.4f m/s^2\n", mus, theta * 180 / M_PI, ratio, 1e3 * held.displacement, held.acceleration);
    EXPECT_LT(std::abs(held.displacement), 1e-3) << "the block sticks at tan(theta) = " << ratio << " mu_s";
    EXPECT_LT(std::abs(held.acceleration), 0.01);
  }
  // Above it the block slides with g (sin - mu_k cos).
  for (auto [muk, tanTheta] : {std::pair<double, double>{mus, 1.1 * mus}, {0.5, 1.2 * mus}, {0.5, 1.0}}) {
    const double theta = std::atan(tanTheta);
    const double expected = kG * (std::sin(theta) - muk * std::cos(theta));
    const InclineResult slide = slideOnIncline(theta, mus, muk, 0.5, 1.0);
    std::printf("[ incline ] mu_s %.1f, mu_k %.1f, theta %.1f deg: acceleration %.4f m/s^2, g (sin - mu_k cos) = "
                "%.4f (%+.2f %%)\n", mus, muk, theta * 180 / M_PI, slide.acceleration, expected,
                100 * (slide.acceleration / expected - 1));
    EXPECT_NEAR(slide.acceleration, expected, 0.05 * expected) << "theta " << theta;
  }
}

namespace {

struct GraspResult {
  double lift;          // rise of the bunny's centre of mass (m)
  double slip;          // its fall relative to the fingers over the hold (m)
  double carried;       // the fingers' vertical force over the last second of the hold / weight
  bool finite;
};

/// The bunny settles on the ground, two box fingers close on it along y (1.5 cm into it on each
/// side), lift it 10 cm in 2 s and hold it 5 s.
GraspResult grasp(const BunnyScene& scene, double mu) {
  Solver s(scene.lattice, sceneParams(*scene.lattice));
  s.setCollider("ground", groundBelow(s, 0.0));
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();
  const Eigen::Vector3d c = centreOfMass(s);
  const double r = s.contactRadius();
  // the width along y of the bunny in a 8 x 8 cm window (x, z) around its centre of mass
  double yLo = 1.0, yHi = -1.0;
  for (const auto& x : s.positions())
    if (std::abs(x.x() - c.x()) < 0.04 && std::abs(x.z() - c.z()) < 0.04) {
      yLo = std::min(yLo, x.y() - r);
      yHi = std::max(yHi, x.y() + r);
    }
  const Eigen::Vector3d half(0.04, 0.01, 0.04);
  const double gap = 0.01, squeeze = 0.015;
  s.setCollider("left", world_scenes::box(Eigen::Vector3d(c.x(), yLo - gap - half.y(), c.z()), half, mu));
  s.setCollider("right", world_scenes::box(Eigen::Vector3d(c.x(), yHi + gap + half.y(), c.z()), half, mu));
  const double closeTime = 0.5;
  const double speed = (gap + squeeze) / closeTime;
  setVelocity(s, "left", Eigen::Vector3d(0, speed, 0));
  setVelocity(s, "right", Eigen::Vector3d(0, -speed, 0));
  for (int i = 0; i < stepsFor(closeTime, s); ++i) s.step();
  setVelocity(s, "left", Eigen::Vector3d(0, 0, 0.05));
  setVelocity(s, "right", Eigen::Vector3d(0, 0, 0.05));
  for (int i = 0; i < stepsFor(2.0, s); ++i) s.step();
  setVelocity(s, "left", Eigen::Vector3d::Zero());
  setVelocity(s, "right", Eigen::Vector3d::Zero());
  const double fingerZ = s.colliders().at("left").pose.translation().z();
  const double relative0 = centreOfMass(s).z() - fingerZ;
  double carried = 0.0;
  const int hold = stepsFor(5.0, s), last = stepsFor(1.0, s);
  for (int i = 0; i < hold; ++i) {
    s.step();
    if (i >= hold - last)
      carried += (s.contactWrench("left").force.z() + s.contactWrench("right").force.z()) / last;
  }
  GraspResult out;
  out.lift = centreOfMass(s).z() - c.z();
  out.slip = relative0 - (centreOfMass(s).z() - fingerZ);
  out.carried = -carried / (scene.lattice->totalMass() * kG);
  out.finite = allFinite(s);
  return out;
}

}  // namespace

TEST(ContactScene, TwoFingersLiftTheBunnyWithFrictionAndLoseItWithout) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const BunnyScene scene = bunnyScene();
  const GraspResult held = grasp(scene, 1.0);
  std::printf("[ grasp   ] mu 1: lifted %.1f mm, slip %.2f mm over the 5 s hold, fingers carry %.2f %% of the "
              "weight\n", 1e3 * held.lift, 1e3 * held.slip, 100 * held.carried);
  EXPECT_TRUE(held.finite);
  // the fingers rose 10 cm; hanging, the bunny stretches below where it sat squeezed on the ground
  EXPECT_GT(held.lift, 0.08);
  EXPECT_LT(std::abs(held.slip), 0.005);
  EXPECT_NEAR(held.carried, 1.0, 0.05);
  const GraspResult lost = grasp(scene, 0.05);
  std::printf("[ grasp   ] mu 0.05: lifted %.1f mm, fingers carry %.2f %% of the weight\n", 1e3 * lost.lift,
              100 * lost.carried);
  EXPECT_TRUE(lost.finite);
  EXPECT_LT(lost.lift, 0.02) << "without friction the bunny slips out";
}

TEST(ContactScene, SpherePressedIntoTheBunnyMeetsAGrowingReaction) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const BunnyScene scene = bunnyScene();
  Solver s(scene.lattice, sceneParams(*scene.lattice));
  s.setCollider("ground", groundBelow(s, 0.0));
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();
  const Eigen::Vector3d c = centreOfMass(s);
  const double r = s.contactRadius(), R = 0.03;
  double top = -1.0;
  for (const auto& x : s.positions())
    if ((x - c).head<2>().norm() < 0.02) top = std::max(top, x.z() + r);
  Collider ball;
  ball.shape.type = ColliderType::Sphere;
  ball.shape.radius = R;
  ball.pose.translation() = Eigen::Vector3d(c.x(), c.y(), top + R);
  s.setCollider("ball", ball);
  double previous = 0.0;
  for (double depth : {0.01, 0.02, 0.03}) {
    // down by 1 cm in 0.25 s, then held 1 s
    setVelocity(s, "ball", Eigen::Vector3d(0, 0, -0.04));
    for (int i = 0; i < stepsFor(0.25, s); ++i) s.step();
    setVelocity(s, "ball", Eigen::Vector3d::Zero());
    const int hold = stepsFor(1.0, s), last = stepsFor(0.25, s);
    double force = 0.0;
    for (int i = 0; i < hold; ++i) {
      s.step();
      if (i >= hold - last) force += s.contactWrench("ball").force.z() / last;
    }
    EXPECT_NEAR(s.colliders().at("ball").pose.translation().z(), top + R - depth, 1e-9);
    std::printf("[ indent  ] sphere r %.0f mm pressed %.0f mm into the bunny: reaction %.3f N\n", 1e3 * R,
                1e3 * depth, force);
    EXPECT_GT(force, previous) << "deeper, harder";
    previous = force;
    EXPECT_TRUE(allFinite(s));
  }
}

namespace {

/// The indenter scene below, with the explicit step (11 sub-steps, as the node's default) or the
/// implicit one (one sub-step of 1/60 s: 3 steps are 3 sub-steps, not 33). Returns the sphere's
/// reaction at rest (N) for the free and the pinned bunny at each depth, in that order, in
/// `reactions` (an out-parameter: gtest's ASSERT returns void).
void indenterMovedInOneCommand(bool implicit, std::vector<double>& reactions) {
  reactions.clear();
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const ResolutionChoice choice = finestResolutionWithin(zUpBunny(), 2000);
  const int w = regionHalfWidthForSection(measureSectionThickness(choice.voxels).thinnest, 5);
  auto lattice = std::make_shared<const Lattice>(choice.voxels, 1000.0, w);
  const SolverParams p = implicit ? test::physicalParams(3e4, 0.0, w, 1.0 / 60.0, 1, Integrator::Implicit)
                                  : test::physicalParams(3e4, 0.0, w, 1.0 / 60.0, 11);
  for (bool pinned : {false, true}) {
    Solver s(lattice, p);
    s.setCollider("ground", groundBelow(s, 0.02));
    for (int i = 0; i < stepsFor(5.0, s); ++i) s.step();
    if (pinned) {
      const double z = lowestZ(s) + 0.03;
      ASSERT_GT(s.pinBox(Eigen::Vector3d::Constant(-10.0), Eigen::Vector3d(10.0, 10.0, z), true), 0u);
    }
    const Eigen::Vector3d c = centreOfMass(s);
    const double r = s.contactRadius(), R = 0.02;
    double top = -1.0;
    for (const auto& x : s.positions())
      if ((x - c).head<2>().norm() < 0.02) top = std::max(top, x.z() + r);
    Collider ball;
    ball.shape.type = ColliderType::Sphere;
    ball.shape.radius = R;
    ball.staticFriction = 0.6;
    ball.kineticFriction = 0.5;
    ball.pose.translation() = Eigen::Vector3d(c.x(), c.y(), top + R);
    s.setCollider("ball", ball);
    // the deepest particle centre inside the sphere (m; 0 when none is)
    const auto deepest = [&] {
      const Collider& now = s.colliders().at("ball");
      double d = 0.0;
      Eigen::Vector3d n;
      for (const auto& x : s.positions()) d = std::max(d, -colliderDistance(now.shape, now.pose, x, n));
      return d;
    };
    const int second = stepsFor(1.0, s);
    for (double depth : {0.01, 0.03}) {
      Eigen::Isometry3d pose = ball.pose;
      pose.translation().z() -= depth;
      ASSERT_TRUE(s.moveCollider("ball", pose, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()));
      const double buried = deepest();
      for (int i = 0; i < 3; ++i) s.step();
      const double left = deepest();
      // the first step after which every particle stayed slower than r per second for a second
      int still = 0, rest = -1;
      for (int i = 3; i < stepsFor(30.0, s) && rest < 0; ++i) {
        s.step();
        ASSERT_TRUE(allFinite(s));
        still = maxSpeed(s) < r / 1.0 ? still + 1 : 0;
        if (still >= second) rest = i + 1;
      }
      std::printf("[ indent  ] %s %s bunny, sphere r %.0f mm moved to %.0f mm into it in one command (contact radius "
                  "%.1f mm): deepest particle centre %.1f mm inside it, %.2g mm after 3 steps; at rest after %.2f s, "
                  "reaction %.3f N\n", implicit ? "implicit," : "explicit,", pinned ? "pinned" : "free", 1e3 * R, 1e3 * depth, 1e3 * r, 1e3 * buried,
                  1e3 * left, rest * p.timeStep, s.contactWrench("ball").force.z());
      EXPECT_GT(buried, 0.0) << "the move buried particle spheres deeper than r";
      EXPECT_LE(left, 0.0) << "pushed out within 3 steps" << (pinned ? " (pinned)" : "") << (implicit ? " (implicit)" : "");
      EXPECT_GT(rest, 0) << "the bunny comes to rest under the indenter" << (pinned ? " (pinned)" : "") << (implicit ? " (implicit)" : "");
      EXPECT_GT(s.contactWrench("ball").force.z(), 0.0) << "and pushes it up";
      reactions.push_back(s.contactWrench("ball").force.z());
    }
  }
}

}  // namespace

TEST(ContactScene, IndenterMovedIntoTheBunnyInOneCommandPushesItOutAndItRests) {
  // The node's default object and material (config/flsm.yaml at contact.test's particle budget)
  // on the ground, free or with its bottom 3 cm pinned; a sphere set touching its back is then
  // moved down in one command (a pose, no velocity) by 1 cm, then by 2 cm more, each time
  // farther than the contact radius r: particle centres start the next sub-step inside the
  // sphere (their spheres deeper than r). They must be pushed out: at r per sub-step a few
  // sub-steps suffice, so after 3 steps (33 sub-steps) no particle centre is inside the sphere.
  // And the object must settle under the indenter: within 30 s every particle slower than r per
  // second for a whole second (the indentation moved centimetres in a fraction of a second;
  // what is left is far below a particle's size per second), and the object pushes the sphere
  // up. A buried particle that got no velocity response was pulled back in by shape matching as
  // fast as the push-out moved it out; one of a pinned object pushed no farther than r beyond
  // its goal stayed inside: the pins do not keep this object in the sphere, most of it is out.
  // The same at one implicit sub-step of 1/60 s: contact is inside the solve, and a buried
  // particle is pushed out by position there (3 steps are 3 sub-steps instead of 33). At rest
  // the same material under the same indenter carries the same reaction: within 10 % of the
  // explicit step's, whose alpha is uncapped at 11 sub-steps (both are the modulus asked).
  std::vector<double> explicitReactions, implicitReactions;
  indenterMovedInOneCommand(false, explicitReactions);
  indenterMovedInOneCommand(true, implicitReactions);
  ASSERT_EQ(implicitReactions.size(), explicitReactions.size());
  for (std::size_t i = 0; i < explicitReactions.size(); ++i)
    EXPECT_NEAR(implicitReactions[i] / explicitReactions[i], 1.0, 0.10) << "case " << i;
}
