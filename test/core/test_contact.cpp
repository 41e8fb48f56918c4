// Contact of the deformable object with rigid colliders: the response kernel against Coulomb's
// law and the solver's contact pass (no penetration, wrenches, recorded contacts, mesh and
// cylinder colliders, kinematic colliders, pins, a turntable, threads).
#include "deformable_flsm/core/contact.h"

#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/solver.h"
#include "contact_fixtures.h"
#include "fixtures.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::contact_fixtures;

// --- the kernel ------------------------------------------------------------------------------

TEST(ContactVelocityChange, EndsOnTheSurfaceAndSticksWithinTheFrictionCone) {
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ();
  const double h = 0.01;
  // 1 mm deep, tangential slip 0.05 m/s: the normal change is 0.1 m/s, mu_s 0.6 holds 0.06
  const Eigen::Vector3d v(0.05, 0.0, -0.2);
  Eigen::Vector3d dv = contactVelocityChange(-0.001, 0.0, n, v, Eigen::Vector3d::Zero(), h, 0.6, 0.5);
  EXPECT_NEAR(dv.z(), 0.1, 1e-15) << "the normal change ends the sub-step on the surface";
  EXPECT_NEAR((v + dv).x(), 0.0, 1e-15) << "static friction stops the slip";
  // slip 0.2 m/s exceeds 0.06: kinetic friction takes mu_k * 0.1 = 0.05 off it
  dv = contactVelocityChange(-0.001, 0.0, n, Eigen::Vector3d(0.2, 0, -0.2), Eigen::Vector3d::Zero(), h, 0.6, 0.5);
  EXPECT_NEAR(dv.x(), -0.05, 1e-15);
  EXPECT_NEAR(dv.z(), 0.1, 1e-15);
  // relative to a moving collider: a particle moving with the surface keeps its velocity
  const Eigen::Vector3d belt(0.3, 0.1, 0.0);
  dv = contactVelocityChange(-0.001, 0.0, n, belt, belt, h, 0.6, 0.5);
  EXPECT_TRUE(dv.isApprox(Eigen::Vector3d(0, 0, 0.1), 1e-14));
  // frictionless: the tangential velocity stays
  dv = contactVelocityChange(-0.001, 0.0, n, Eigen::Vector3d(0.01, 0, 0), Eigen::Vector3d::Zero(), h, 0.0, 0.0);
  EXPECT_TRUE(dv.isApprox(Eigen::Vector3d(0, 0, 0.1), 1e-14));
}

TEST(ContactVelocityChange, PenetrationFromBeforeTheSubStepBecomesNoVelocity) {
  const Eigen::Vector3d n = Eigen::Vector3d::UnitZ(), still = Eigen::Vector3d::Zero();
  const double h = 0.01;
  // 2 cm inside since before the sub-step (a collider set or moved onto the particle) and no
  // deeper at its end: the collider at rest does no work on it (the old response gave it the
  // 2 m/s that ends the sub-step on the surface)
  EXPECT_TRUE(contactVelocityChange(-0.02, -0.02, n, still, still, h, 0.6, 0.5).isZero(0.0));
  // on its way out (2 cm to 1.5 cm deep): left alone too
  const Eigen::Vector3d out(0.3, 0.0, 0.5);
  EXPECT_TRUE(contactVelocityChange(-0.015, -0.02, n, out, still, h, 0.6, 0.5).isZero(0.0));
  // 5 mm deeper over the sub-step: only those 5 mm are undone (0.5 m/s), and friction acts on
  // that normal change: slip 1 m/s > mu_s 0.5 m/s * 0.6, kinetic mu_k 0.5 takes 0.25 m/s off it
  Eigen::Vector3d dv = contactVelocityChange(-0.025, -0.02, n, Eigen::Vector3d(1.0, 0.0, -0.5), still, h, 0.6, 0.5);
  EXPECT_NEAR(dv.z(), 0.5, 1e-12) << "ends as deep as it started";
  EXPECT_NEAR(dv.x(), -0.25, 1e-12);
  // a particle that came from outside (start 1 mm above) ends on the surface as before
  dv = contactVelocityChange(-0.001, 0.001, n, Eigen::Vector3d(0.0, 0.0, -0.2), still, h, 0.6, 0.5);
  EXPECT_NEAR(dv.z(), 0.1, 1e-12);
}

TEST(ContactVelocityChange, PassingACurvedColliderCentreThrowsNothing) {
  // Deep inside a sphere of radius R, a particle crosses its centre: from 1 cm on one side to
  // 5 mm on the other along u. Its depth is 5 mm less at the end, but it moved away from the end
  // normal's surface point along u = n, not into it: a collider at rest gives it nothing (the
  // "no deeper" measure alone would add (1 cm - 5 mm) / h = 0.5 m/s along its motion, every
  // sub-step it passes the centre).
  const Eigen::Vector3d u = Eigen::Vector3d(1.0, 2.0, -0.5).normalized(), still = Eigen::Vector3d::Zero();
  const double h = 0.01, R = 1e9, r = 0.005;
  const Eigen::Vector3d v = (0.01 + 0.005) / h * u;
  EXPECT_TRUE(contactVelocityChange(0.005 - R - r, 0.01 - R - r, u, v, still, h, 0.6, 0.5).isZero(0.0));
  // moving into the end normal's surface (back towards the centre) it is stopped along n only
  const Eigen::Vector3d in = -0.3 * u + 0.1 * u.unitOrthogonal();
  const Eigen::Vector3d dv = contactVelocityChange(0.005 - R - r, 0.008 - R - r, u, in, still, h, 0.0, 0.0);
  EXPECT_NEAR(dv.dot(u), 0.3, 1e-12) << "the approach is stopped, no more";
  EXPECT_NEAR((dv - dv.dot(u) * u).norm(), 0.0, 1e-12);
}

// --- the contact pass ------------------------------------------------------------------------

TEST(Contact, BlockRestsOnTheGroundAndItsWeightIsTheNormalForce) {
  auto lattice = std::make_shared<const Lattice>(test::makeBox(6, 4, 3, 0.01), 1000.0, 1);
  Solver s(lattice, sceneParams(*lattice, 0.3));
  const Collider ground = groundBelow(s, 0.02);
  s.setCollider("ground", ground);
  const double zg = ground.pose.translation().z();
  double deepest = 0.0;
  const int steps = stepsFor(5.0, s), last = stepsFor(1.0, s);
  ContactWrench w;  // averaged over the last second
  for (int i = 0; i < steps; ++i) {
    s.step();
    deepest = std::max(deepest, zg + s.contactRadius() - lowestZ(s));
    if (i < steps - last) continue;
    w.force += s.contactWrench("ground").force / last;
    w.torque += s.contactWrench("ground").torque / last;
    w.contacts = s.contactWrench("ground").contacts;
  }
  EXPECT_LT(deepest, 1e-12) << "no sphere ends a sub-step inside the ground";
  EXPECT_LT(maxSpeed(s), 1e-3);
  const double W = lattice->totalMass() * kG;
  EXPECT_NEAR(w.force.z(), -W, 2e-3 * W) << "the block presses on the ground with its weight";
  EXPECT_NEAR(w.force.head<2>().norm(), 0.0, 2e-3 * W);
  EXPECT_EQ(w.contacts, 24u) << "the bottom layer of 6 x 4 particles touches";
  // torque about the ground's origin: the weight acts at the centre of mass
  const Eigen::Vector3d c = centreOfMass(s) - ground.pose.translation();
  const Eigen::Vector3d expected = Eigen::Vector3d(c.x(), c.y(), 0.0).cross(Eigen::Vector3d(0, 0, -W));
  EXPECT_TRUE(w.torque.isApprox(expected, 1e-2)) << w.torque.transpose() << " vs " << expected.transpose();
  EXPECT_EQ(s.contactWrench("nothing").contacts, 0u);
  // reset keeps the colliders
  s.reset();
  EXPECT_EQ(s.colliders().size(), 1u);
}

// Recorded contacts (a tactile image's data): every particle that pushed on the ground, where it
// touched and with what force; they add up to the ground's wrench to rounding, with both steps,
// and say where the weight rests: the bottom layer, on the ground's surface.
TEST(Contact, RecordedContactsAddUpToTheWrenchWithBothIntegrators) {
  for (const Integrator integrator : {Integrator::Explicit, Integrator::Implicit}) {
    auto lattice = std::make_shared<const Lattice>(test::makeBox(6, 4, 3, 0.01), 1000.0, 1);
    SolverParams p = sceneParams(*lattice, 0.3);
    p.integrator = integrator;
    Solver s(lattice, p);
    s.recordContacts("ground", true);  // before the collider: kept by its id
    const Collider ground = groundBelow(s, 0.0);
    s.setCollider("ground", ground);
    s.setCollider("unrecorded", world_scenes::box(Eigen::Vector3d(1, 0, 0), Eigen::Vector3d::Constant(0.1), 0.5));
    for (int i = 0; i < stepsFor(2.0, s); ++i) s.step();
    const std::vector<ParticleContact>& record = s.recordedContacts("ground");
    ASSERT_EQ(record.size(), 24u) << "the bottom layer of 6 x 4 particles";
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (const ParticleContact& c : record) {
      sum += c.force;
      EXPECT_NEAR(c.point.z(), ground.pose.translation().z(), 1e-6) << "particle " << c.particle;
      EXPECT_NEAR(lattice->restPositions()[c.particle].z(), lowestZ(s), 0.5 * lattice->spacing());
    }
    const Eigen::Vector3d w = s.contactWrench("ground").force;
    EXPECT_LT((sum - w).norm(), 1e-12 * w.norm()) << sum.transpose() << " vs " << w.transpose();
    EXPECT_NEAR(-w.z(), lattice->totalMass() * kG, 0.02 * lattice->totalMass() * kG);
    EXPECT_TRUE(s.recordedContacts("unrecorded").empty());
    s.recordContacts("ground", false);
    s.step();
    EXPECT_TRUE(s.recordedContacts("ground").empty());
  }
}

// A block pushed into the corner of the ground and a wall (gravity tilted towards the wall):
// each collider counts the particles of the face resting on it, the edge row on both, each once,
// whichever of the two the implicit solve holds it on and the contact pass meets first.
TEST(Contact, ABlockInACornerCountsEachTouchingParticleOncePerCollider) {
  // the colliders are met in the order of their names: the wall before the ground, then after it
  for (const char* name : {"a_wall", "wall"}) {
    for (const bool implicit : {false, true}) {
      auto lattice = std::make_shared<const Lattice>(test::makeBox(4, 4, 4, 0.01), 1000.0, 1);
      SolverParams p = sceneParams(*lattice, 0.3);
      p.gravity = Eigen::Vector3d(-4.0, 0.0, -kG);
      p.ambientDamping = 2.0;  // settles within the 4 s
      if (implicit) {
        p.integrator = Integrator::Implicit;
        p.substeps = 1;
        p.youngsModulus = 1e5;
      }
      Solver s(lattice, p);
      // frictionless: the wall takes all of the sideways load, every particle of the side presses
      Collider ground = groundBelow(s, 0.0);
      ground.staticFriction = ground.kineticFriction = 0.0;
      s.setCollider("ground", ground);
      double lowestX = s.positions()[0].x();
      for (const Eigen::Vector3d& x : s.positions()) lowestX = std::min(lowestX, x.x());
      Collider wall;  // a half-space whose normal is +x, touching the block's -x face
      wall.pose.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitY()).toRotationMatrix();
      wall.pose.translation() = Eigen::Vector3d(lowestX - s.contactRadius(), 0, 0);
      wall.staticFriction = wall.kineticFriction = 0.0;
      s.setCollider(name, wall);
      for (int i = 0; i < 240; ++i) s.step();
      EXPECT_LT(maxSpeed(s), 1e-3) << (implicit ? "implicit" : "explicit");
      EXPECT_EQ(s.contactWrench("ground").contacts, 16u) << (implicit ? "implicit" : "explicit") << ": the 4 x 4 bottom";
      EXPECT_EQ(s.contactWrench(name).contacts, 16u) << (implicit ? "implicit" : "explicit") << ": the 4 x 4 side";
    }
  }
}

TEST(Contact, BlockRestsOnAMeshTable) {
  // the same block on a table given as a triangle mesh (a 20 x 20 x 5 cm box whose top is z = 0)
  auto lattice = std::make_shared<const Lattice>(test::makeBox(6, 4, 3, 0.01), 1000.0, 1);
  Solver s(lattice, sceneParams(*lattice, 0.3));
  Collider table;
  table.shape.type = ColliderType::Mesh;
  table.shape.mesh = std::make_shared<const TriMesh>(
      test::boxMesh(Eigen::Vector3d(-0.07, -0.08, -0.05), Eigen::Vector3d(0.13, 0.12, 0.0)));
  table.pose.translation() = Eigen::Vector3d(0, 0, -0.01);
  s.setCollider("table", table);
  ASSERT_TRUE(s.colliders().at("table").shape.distanceField) << "setCollider builds the field";
  const int steps = stepsFor(4.0, s), last = stepsFor(1.0, s);
  double deepest = 0.0, fz = 0.0;
  for (int i = 0; i < steps; ++i) {
    s.step();
    deepest = std::max(deepest, -0.01 + s.contactRadius() - lowestZ(s));
    if (i >= steps - last) fz += s.contactWrench("table").force.z() / last;
  }
  // the top face is far from the table's edges: the field is exact there
  EXPECT_LT(deepest, 1e-9);
  const double W = lattice->totalMass() * kG;
  EXPECT_NEAR(fz, -W, 2e-3 * W);
  EXPECT_EQ(s.contactWrench("table").contacts, 24u);
}

TEST(Contact, BlockRestsLevelOnACylinderPost) {
  // the same block on the flat end of an upright cylinder (radius 8 cm, top face z = -0.01): a
  // flat end carries the weight evenly on the whole bottom layer, where a capsule's round end
  // would carry it on a few particles and tip the block
  auto lattice = std::make_shared<const Lattice>(test::makeBox(6, 4, 3, 0.01), 1000.0, 1);
  Solver s(lattice, sceneParams(*lattice, 0.3));
  Collider post;
  post.shape.type = ColliderType::Cylinder;
  post.shape.radius = 0.08;
  post.shape.halfLength = 0.05;
  post.pose.translation() = Eigen::Vector3d(0.03, 0.02, -0.06);
  s.setCollider("post", post);
  const int steps = stepsFor(4.0, s), last = stepsFor(1.0, s);
  double deepest = 0.0, fz = 0.0;
  for (int i = 0; i < steps; ++i) {
    s.step();
    deepest = std::max(deepest, -0.01 + s.contactRadius() - lowestZ(s));
    if (i >= steps - last) fz += s.contactWrench("post").force.z() / last;
  }
  EXPECT_LT(deepest, 1e-12) << "no sphere ends a sub-step inside the end face";
  const double W = lattice->totalMass() * kG;
  EXPECT_NEAR(fz, -W, 2e-3 * W) << "the post carries the block's weight";
  EXPECT_EQ(s.contactWrench("post").contacts, 24u) << "the whole bottom layer touches the flat end";
  const Eigen::AngleAxisd tilt(s.rigidFrame().linear());
  EXPECT_LT(tilt.angle(), 1e-3) << "the block stays level";
}

TEST(Contact, PinnedParticlesAreNotMovedByContact) {
  auto lattice = std::make_shared<const Lattice>(test::makeBox(4, 4, 4, 0.01), 1000.0, 1);
  SolverParams p = sceneParams(*lattice);
  p.gravity.setZero();
  Solver s(lattice, p);
  s.setPinned(0, true);  // a corner at (0.005, 0.005, 0.005)
  // a ball that swallows the pinned corner
  Collider ball;
  ball.shape.type = ColliderType::Sphere;
  ball.shape.radius = 0.012;
  ball.pose.translation() = Eigen::Vector3d::Zero();
  s.setCollider("ball", ball);
  for (int i = 0; i < 10; ++i) s.step();
  EXPECT_EQ(s.positions()[0], lattice->restPositions()[0]);
  EXPECT_TRUE(allFinite(s));
}

TEST(Contact, KinematicColliderPushesAndFollowsItsVelocity) {
  auto lattice = std::make_shared<const Lattice>(test::makeBox(4, 4, 4, 0.01), 1000.0, 1);
  SolverParams p = sceneParams(*lattice);
  p.gravity.setZero();
  p.ambientDamping = 0.0;
  Solver s(lattice, p);
  // a wall coming from -x at 0.5 m/s, frictionless
  Collider wall = world_scenes::box(Eigen::Vector3d(-0.05, 0.02, 0.02), Eigen::Vector3d(0.04, 0.1, 0.1), 0.0);
  wall.linearVelocity = Eigen::Vector3d(0.5, 0, 0);
  s.setCollider("wall", wall);
  EXPECT_THROW(s.moveCollider("wall", Eigen::Isometry3d(Eigen::Translation3d(std::nan(""), 0, 0)),
                              Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()),
               std::invalid_argument);
  EXPECT_FALSE(s.moveCollider("none", Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()));
  const int steps = stepsFor(0.5, s);
  for (int i = 0; i < steps; ++i) s.step();
  // the wall went 0.25 m; its face is at x = -0.01 + 0.25 = 0.24 and pushes the block ahead of it
  EXPECT_NEAR(s.colliders().at("wall").pose.translation().x(), -0.05 + 0.5 * steps * p.timeStep, 1e-12);
  const double face = s.colliders().at("wall").pose.translation().x() + 0.04;
  double back = 1.0;
  for (const auto& x : s.positions()) back = std::min(back, x.x());
  EXPECT_GE(back - s.contactRadius(), face - 1e-12) << "nothing behind the wall's face";
  EXPECT_GT(centreOfMass(s).x(), 0.2) << "the block was pushed along";
  EXPECT_NEAR(s.linearMomentum().y(), 0.0, 1e-9);
}

TEST(Contact, TurntableCarriesTheBlockByFriction) {
  // a ground spinning about its normal at 1 rad/s under a block centred on the axis: friction on
  // the velocity relative to the surface (omega x r) turns the block with it
  auto lattice = std::make_shared<const Lattice>(test::makeBox(6, 4, 3, 0.01), 1000.0, 1);
  Solver s(lattice, sceneParams(*lattice, 0.3));
  Collider table;
  table.pose.translation() = Eigen::Vector3d(0.03, 0.02, 0.0);  // under the block's centre
  s.setCollider("table", table);
  for (int i = 0; i < stepsFor(0.5, s); ++i) s.step();
  const Eigen::Matrix3d before = s.rigidFrame().linear();
  s.moveCollider("table", s.colliders().at("table").pose, Eigen::Vector3d::Zero(), Eigen::Vector3d(0, 0, 1.0));
  for (int i = 0; i < stepsFor(1.0, s); ++i) s.step();
  const Eigen::AngleAxisd turned(s.rigidFrame().linear() * before.transpose());
  EXPECT_NEAR(turned.angle(), 1.0, 0.02) << "the block turned with the table";
  EXPECT_NEAR(std::abs(turned.axis().z()), 1.0, 1e-3);
  EXPECT_NEAR((centreOfMass(s) - table.pose.translation()).head<2>().norm(), 0.0, 1e-3) << "about its axis";
}

TEST(Contact, WrenchesDoNotDependOnTheThreadCount) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const BunnyScene scene = bunnyScene();
  SolverParams p1 = sceneParams(*scene.lattice);
  SolverParams p2 = p1;
  p2.threads = 2;
  Solver one(scene.lattice, p1), two(scene.lattice, p2);
  for (Solver* s : {&one, &two}) {
    s->setCollider("ground", groundBelow(*s, 0.01));
    Collider ball;
    ball.shape.type = ColliderType::Sphere;
    ball.shape.radius = 0.04;
    ball.pose.translation() = centreOfMass(*s) + Eigen::Vector3d(0.02, 0, 0.15);
    ball.linearVelocity = Eigen::Vector3d(0, 0, -0.3);
    s->setCollider("ball", ball);
  }
  for (int i = 0; i < 30; ++i) {
    one.step();
    two.step();
  }
  for (const char* id : {"ground", "ball"}) {
    EXPECT_EQ(one.contactWrench(id).force, two.contactWrench(id).force) << id;
    EXPECT_EQ(one.contactWrench(id).torque, two.contactWrench(id).torque) << id;
    EXPECT_EQ(one.contactWrench(id).contacts, two.contactWrench(id).contacts) << id;
  }
  EXPECT_GT(one.contactWrench("ball").contacts, 0u) << "the ball reached the bunny";
  EXPECT_EQ(one.positions(), two.positions());
}
