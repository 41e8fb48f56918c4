// Sleeping objects: the rule of the sleeping unit alone (when an object falls asleep, what wakes
// it), and steps of a World that allocate nothing with objects asleep.
#include "deformable_flsm/core/sleeping.h"

#include "deformable_flsm/core/world.h"
#include "allocation_counter.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <utility>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::world_scenes;

// --- the sleeping unit alone -----------------------------------------------------------------

namespace {

/// A block of 2 x 2 x 2 cells of 1 cm (density 1000: 8 g, its size the diagonal 2 sqrt(3) cm,
/// contact radius 5 mm) whose lower corner is `lo`, never stepped: what Sleeping sees of it is
/// what the test sets.
struct Block {
  std::shared_ptr<const Lattice> lattice;
  Solver solver;
  explicit Block(const Eigen::Vector3d& lo = Eigen::Vector3d::Zero())
      : lattice(boxAt(2, 2, 2, 0.01, lo)), solver(lattice, paramsFor(*lattice, 1.0, 2.0)) {}
  void shift(const Eigen::Vector3d& d) {
    std::vector<Eigen::Vector3d> x = solver.positions();
    for (Eigen::Vector3d& p : x) p += d;
    solver.setPositions(x);
  }
};

const double kBlockSize = 0.02 * std::sqrt(3.0), kBlockMass = 0.008, kBlockRadius = 0.005;

SleepParams restFor(double fraction, double hold) {
  SleepParams s;
  s.fraction = fraction;
  s.hold = hold;
  return s;
}

/// One step of `sleeping` over `objects` that touch nothing.
void idle(Sleeping& sleeping, const std::vector<Solver*>& objects) {
  sleeping.beforeStep(objects, {}, kStep);
  sleeping.afterStep(objects, {}, {}, {}, kStep);
}

/// Steps until every object of `objects` is asleep, at most `steps` times; how many it took.
int sleepAll(Sleeping& sleeping, const std::vector<Solver*>& objects, int steps = 1000) {
  int n = 0;
  while (sleeping.count() < objects.size() && n < steps) {
    idle(sleeping, objects);
    ++n;
  }
  return n;
}

}  // namespace

// The block as the tests take it: the figures the hand-computed expectations below start from.
TEST(Sleeping, TheTestBlockHasTheSizeMassAndRadiusComputedByHand) {
  Block b;
  EXPECT_NEAR(b.lattice->objectSize(), kBlockSize, 1e-15);
  EXPECT_NEAR(b.lattice->totalMass(), kBlockMass, 1e-15);
  EXPECT_NEAR(b.solver.contactRadius(), kBlockRadius, 1e-15);
}

// At rest, an object falls asleep after `hold` of simulated time: 0.1 s at 60 Hz is 6 steps; its
// velocities are zeroed as it does, and it sleeps through the step after.
TEST(Sleeping, AnObjectAtRestFallsAsleepAfterHold) {
  Block b;
  const std::vector<Solver*> objects{&b.solver};
  Sleeping sleeping;
  sleeping.setParams(restFor(1e-3, 0.1), objects);
  sleeping.add(b.solver);
  b.solver.setVelocities(std::vector<Eigen::Vector3d>(8, Eigen::Vector3d(0.001, 0.0, 0.0)));
  for (int i = 1; i <= 5; ++i) {
    idle(sleeping, objects);
    EXPECT_FALSE(sleeping.asleep(0)) << "after step " << i;
  }
  idle(sleeping, objects);
  EXPECT_TRUE(sleeping.asleep(0)) << "after step 6";
  EXPECT_EQ(sleeping.count(), 1u);
  for (const Eigen::Vector3d& v : b.solver.velocities()) EXPECT_EQ(v, Eigen::Vector3d::Zero());
  sleeping.beforeStep(objects, {}, kStep);
  EXPECT_EQ(sleeping.asleepThisStep(), std::vector<char>{1});
}

// Within fraction x size of where its hold began (the mass-weighted RMS: a uniform shift is its
// length) the hold goes on; beyond it the hold starts again from there. Fraction 1e-3 of
// 2 sqrt(3) cm: 34.6 um.
TEST(Sleeping, AnObjectThatMovesBeyondItsLimitHoldsAgain) {
  const double limit = 1e-3 * kBlockSize;
  for (const double shift : {0.9, 1.1}) {
    Block b;
    const std::vector<Solver*> objects{&b.solver};
    Sleeping sleeping;
    sleeping.setParams(restFor(1e-3, 0.1), objects);
    sleeping.add(b.solver);
    for (int i = 0; i < 3; ++i) idle(sleeping, objects);
    b.shift(Eigen::Vector3d(0.0, shift * limit, 0.0));
    // within the limit: asleep after the 6th step; beyond: the 4th step finds it moved and holds
    // again from there, 6 more steps, asleep after the 10th
    EXPECT_EQ(3 + sleepAll(sleeping, objects), shift < 1.0 ? 6 : 10) << "shifted by " << shift << " of the limit";
  }
}

// Sleeping off (fraction 0): nothing sleeps, nothing is kept of the colliders changed, and
// switching it off wakes every object.
TEST(Sleeping, FractionZeroNeverSleepsAndWakesEveryObject) {
  Block b;
  const std::vector<Solver*> objects{&b.solver};
  Sleeping sleeping;
  sleeping.add(b.solver);
  EXPECT_FALSE(sleeping.enabled());
  EXPECT_EQ(sleepAll(sleeping, objects, 120), 120);
  EXPECT_EQ(sleeping.count(), 0u);
  sleeping.setParams(restFor(1e-3, 0.1), objects);
  sleepAll(sleeping, objects);
  ASSERT_TRUE(sleeping.asleep(0));
  sleeping.setParams(SleepParams(), objects);
  EXPECT_FALSE(sleeping.asleep(0));
  EXPECT_THROW(sleeping.setParams(restFor(-1.0, 1.0), objects), std::invalid_argument);
  EXPECT_THROW(sleeping.setParams(restFor(1e-3, 0.0), objects), std::invalid_argument);
  EXPECT_EQ(sleeping.params().fraction, 0.0) << "refused parameters leave the old ones";
}

// Before a step, a command on a sleeping object or a change of its state wakes it, and it is
// stepped.
TEST(Sleeping, ACommandOrAChangeOfStateWakesASleepingObject) {
  Block b;
  const std::vector<Solver*> objects{&b.solver};
  Sleeping sleeping;
  sleeping.setParams(restFor(1e-3, 0.1), objects);
  sleeping.add(b.solver);
  ASSERT_EQ(sleepAll(sleeping, objects), 6);
  b.solver.grab("hand", {0}, b.solver.positions()[0], 0.0);
  sleeping.beforeStep(objects, {}, kStep);
  EXPECT_FALSE(sleeping.asleep(0)) << "a drag";
  EXPECT_EQ(sleeping.asleepThisStep(), std::vector<char>{0});
  sleeping.afterStep(objects, {}, {}, {}, kStep);
  b.solver.release("hand");
  ASSERT_EQ(sleepAll(sleeping, objects), 6);
  b.solver.setPinned(0, true);
  sleeping.beforeStep(objects, {}, kStep);
  EXPECT_FALSE(sleeping.asleep(0)) << "a pin";
}

// A collider changed near a sleeping object (within two contact radii of its particles' bounds)
// wakes it before the next step; one changed 1 m away does not. A collider moving over the step
// reaches as far as it goes in it: 1 m away at 3 m/s (5 cm a step) it wakes nothing, at 70 m/s
// (1.17 m a step) it does.
TEST(Sleeping, AColliderChangedOrMovingNearASleepingObjectWakesIt) {
  Block b;
  const std::vector<Solver*> objects{&b.solver};
  Sleeping sleeping;
  sleeping.setParams(restFor(1e-3, 0.1), objects);
  sleeping.add(b.solver);
  ASSERT_EQ(sleepAll(sleeping, objects), 6);
  Collider ball;
  ball.shape.type = ColliderType::Sphere;
  ball.shape.radius = 0.01;
  ball.pose.translation() = Eigen::Vector3d(1.0, 0.01, 0.01);
  sleeping.disturb(ball);
  sleeping.beforeStep(objects, {}, kStep);
  EXPECT_TRUE(sleeping.asleep(0)) << "a collider set 1 m away";
  sleeping.afterStep(objects, {}, {}, {}, kStep);
  // bounds [0.005, 0.015]: the ball's surface 4 mm from the block's last particle, within 1 cm
  ball.pose.translation() = Eigen::Vector3d(0.029, 0.01, 0.01);
  sleeping.disturb(ball);
  sleeping.beforeStep(objects, {}, kStep);
  EXPECT_FALSE(sleeping.asleep(0)) << "a collider set beside it";
  ASSERT_EQ(sleepAll(sleeping, objects), 6);
  ball.pose.translation() = Eigen::Vector3d(1.0, 0.01, 0.01);
  for (const double speed : {3.0, 70.0}) {
    ball.linearVelocity = Eigen::Vector3d(-speed, 0.0, 0.0);
    sleeping.beforeStep(objects, {{"ball", ball}}, kStep);
    EXPECT_EQ(sleeping.asleep(0), speed < 10.0) << "a collider 1 m away moving at it at " << speed << " m/s";
    sleeping.afterStep(objects, {}, {}, {}, kStep);
  }
}

// An awake object touching a sleeping one (a pair with contacts) wakes it when it moved farther
// than 0.05 of its contact radius in the step (the RMS of |v| T): 0.25 mm at 5 mm, 15 mm/s at
// 60 Hz; at 0.8 of that it does not, nor at 1.2 of it without a contact.
TEST(Sleeping, ATouchingObjectThatMovesFartherThanItsSlopWakesASleeper) {
  const double bound = 0.05 * kBlockRadius / kStep;
  struct Case {
    double speed;
    std::size_t contacts;
    bool wakes;
  };
  for (const Case& c : {Case{0.8 * bound, 1, false}, Case{1.2 * bound, 0, false}, Case{1.2 * bound, 1, true}}) {
    Block a, b(Eigen::Vector3d(0.0, 0.0, 0.02));
    const std::vector<Solver*> objects{&a.solver, &b.solver};
    Sleeping sleeping;
    sleeping.setParams(restFor(1e-3, 0.1), objects);
    sleeping.add(a.solver);
    sleeping.add(b.solver);
    ASSERT_EQ(sleepAll(sleeping, objects), 6);
    sleeping.wake(1, b.solver);
    sleeping.beforeStep(objects, {}, kStep);
    ASSERT_EQ(sleeping.asleepThisStep(), (std::vector<char>{1, 0}));
    b.solver.setVelocities(std::vector<Eigen::Vector3d>(8, Eigen::Vector3d(0.0, c.speed, 0.0)));
    PairImpulse touch;
    touch.a = 1;
    touch.b = 0;
    touch.contacts = c.contacts;
    sleeping.afterStep(objects, {}, {}, {touch}, kStep);
    EXPECT_EQ(sleeping.asleep(0), !c.wakes) << c.speed / bound << " of the bound, " << c.contacts << " contacts";
  }
}

// A sleeping object wakes when the other objects' force on it has changed by more than a tenth
// of its weight (8 g: 78.5 mN) since it fell asleep: 0.09 of it keeps it asleep, 0.11 wakes it.
TEST(Sleeping, AChangeOfLoadByATenthOfItsWeightWakesASleeper) {
  const double weight = kBlockMass * 9.81;
  for (const double change : {0.09, 0.11}) {
    Block a, b(Eigen::Vector3d(0.0, 0.0, 0.02));
    const std::vector<Solver*> objects{&a.solver, &b.solver};
    Sleeping sleeping;
    sleeping.setParams(restFor(1e-3, 0.1), objects);
    sleeping.add(a.solver);
    sleeping.add(b.solver);
    // b rests on a with its weight from the start: a falls asleep under it
    ObjectPairWrench onA;
    onA.from = "b";
    onA.on = "a";
    onA.wrench.force = Eigen::Vector3d(0.0, 0.0, -weight);
    const std::vector<std::pair<std::uint32_t, std::uint32_t>> bOnA{{1, 0}};
    int steps = 0;
    for (; sleeping.count() < 2 && steps < 100; ++steps) {
      sleeping.beforeStep(objects, {}, kStep);
      sleeping.afterStep(objects, {onA}, bOnA, {}, kStep);
    }
    ASSERT_EQ(steps, 6);
    onA.wrench.force.z() = -(1.0 + change) * weight;
    sleeping.beforeStep(objects, {}, kStep);
    sleeping.afterStep(objects, {onA}, bOnA, {}, kStep);
    EXPECT_EQ(sleeping.asleep(0), change < 0.1) << "the load changed by " << change << " of its weight";
    EXPECT_TRUE(sleeping.asleep(1)) << "nothing on b changed";
  }
}

// --- sleeping objects in a World ------------------------------------------------------------

// With sleeping objects: falling asleep, sleeping beside a moving collider, held wrenches and
// waking allocate nothing either, once a first such cycle has grown the buffers (with the
// implicit step, the sleeping objects' springs held in the coupled solve too).
static void sleepWithoutAllocating(Integrator integrator) {
  World world(kStep, substepsOf(integrator));
  SleepParams sleep;
  sleep.fraction = 2e-5;
  sleep.hold = 0.25;
  world.setSleepParams(sleep);
  world.setCollider("ground", ground(0.0));
  auto a = boxAt(4, 4, 2, 0.01, Eigen::Vector3d(0, 0, 0));
  auto b = boxAt(2, 2, 2, 0.01, Eigen::Vector3d(0.01, 0.01, 0.02));
  world.addObject("a", a, paramsFor(*a, 1.0, 2.0, integrator));
  world.addObject("b", b, paramsFor(*b, 1.0, 2.0, integrator));
  const Collider pusher = box(Eigen::Vector3d(0.3, 0.02, 0.02), Eigen::Vector3d(0.02, 0.05, 0.05));
  world.setCollider("pusher", pusher);
  // a cycle: asleep, the pusher passing by far away, then brought against the stack and back
  const auto cycle = [&]() {
    std::size_t most = 0;
    for (int i = 0; i < stepsFor(20.0) && world.sleepingCount() < 2; ++i) world.step();
    most = world.sleepingCount();
    world.moveCollider("pusher", pusher.pose, Eigen::Vector3d(0, 0.1, 0), Eigen::Vector3d::Zero());
    for (int i = 0; i < 10; ++i) world.step();
    world.moveCollider("pusher", Eigen::Isometry3d(Eigen::Translation3d(0.055, 0.02, 0.02)), Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::Zero());
    for (int i = 0; i < 10; ++i) world.step();
    world.moveCollider("pusher", pusher.pose, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
    return most;
  };
  ASSERT_EQ(cycle(), 2u);
  const long before = gAllocations.load();
  const std::size_t asleep = cycle();
  EXPECT_EQ(gAllocations.load() - before, 0);
  EXPECT_EQ(asleep, 2u);
}

TEST(World, StepWithSleepingObjectsDoesNotAllocate) { sleepWithoutAllocating(Integrator::Explicit); }

TEST(World, ImplicitStepWithSleepingObjectsDoesNotAllocate) { sleepWithoutAllocating(Integrator::Implicit); }
