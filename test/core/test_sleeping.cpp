// Sleeping objects: the rule of the sleeping unit alone (when an object falls asleep, what wakes
// it), then sleeping in a World: stacks and piles that sleep carrying their weight and wake where
// they are pushed, and steps that allocate nothing with objects asleep.
#include "deformable_flsm/core/sleeping.h"

#include "deformable_flsm/core/world.h"
#include "allocation_counter.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <random>
#include <set>
#include <string>
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

namespace {

SleepParams sleepAfter(double hold) {
  SleepParams s;
  s.fraction = 2e-5;  // the node's rest (LoopSettings::restFraction)
  s.hold = hold;
  return s;
}

}  // namespace

// The stack of three at rest sleeps; asleep, it is not stepped (nothing moves by a bit) and its
// contacts keep carrying the weight above each within 2 %, the statics a stepped stack
// converges to. A block thrown at the top one wakes it (an object that moved struck it), the top
// block is pushed as far as without sleeping, and nothing interpenetrates.
/// Three firm blocks stacked face to face on the ground (at z = 0) of `world`, as the stack of
/// WorldScene, and a fourth block, `name`, of 2 x 2 x 2 cells with its lower corner at `other`.
struct BlockStack {
  std::shared_ptr<const Lattice> bottom, middle, top, other;
};
static BlockStack stackWithABlock(World& world, const std::string& name, const Eigen::Vector3d& other,
                                  bool weightlessOther = false) {
  world.setCollider("ground", ground(0.0));
  const double s = 0.01;
  BlockStack b{boxAt(6, 6, 2, s, Eigen::Vector3d(0, 0, 0)), boxAt(4, 4, 2, s, Eigen::Vector3d(0.01, 0.01, 0.02)),
               boxAt(4, 2, 2, s, Eigen::Vector3d(0.01, 0.02, 0.04)), boxAt(2, 2, 2, s, other)};
  world.addObject("bottom", b.bottom, paramsFor(*b.bottom, 1.0, 2.0));
  world.addObject("middle", b.middle, paramsFor(*b.middle, 1.0, 2.0));
  world.addObject("top", b.top, paramsFor(*b.top, 1.0, 2.0));
  SolverParams po = paramsFor(*b.other, 1.0, 2.0);
  if (weightlessOther) po.gravity.setZero();
  world.addObject(name, b.other, po);
  return b;
}

static double strikeTheStack(bool sleeping) {
  World world(kStep, kSubsteps);
  if (sleeping) world.setSleepParams(sleepAfter(0.5));
  // the thrown block waits beside the stack, weightless, until thrown
  const BlockStack b = stackWithABlock(world, "thrown", Eigen::Vector3d(0.15, 0.02, 0.04), true);
  const auto &bottom = b.bottom, &middle = b.middle, &top = b.top, &thrown = b.other;
  const Solver& T = *world.object("top");
  Solver& C = *world.object("thrown");
  for (int i = 0; i < stepsFor(4.0) || (sleeping && world.sleepingCount() < 4 && i < stepsFor(20.0)); ++i) world.step();
  if (sleeping) {
    EXPECT_EQ(world.sleepingCount(), 4u) << "the stack and the waiting block rest";
    const auto before = T.positions();
    const int last = stepsFor(1.0);
    ContactWrench bm, mt, g;
    for (int i = 0; i < last; ++i) {
      world.step();
      bm.force += world.objectWrench("bottom", "middle").force / last;
      mt.force += world.objectWrench("middle", "top").force / last;
      g.force += world.contactWrench("ground").force / last;
    }
    EXPECT_EQ(T.positions(), before) << "a sleeping object is not stepped";
    const double Wt = top->totalMass() * kG, Wm = middle->totalMass() * kG, Wb = bottom->totalMass() * kG;
    std::printf("sleeping stack: middle->top %.4f N (weight %.4f), bottom->middle %.4f N (weight above %.4f), ground "
                "%.4f N (all %.4f)\n",
                mt.force.z(), Wt, bm.force.z(), Wt + Wm, -g.force.z(), Wt + Wm + Wb);
    EXPECT_NEAR(mt.force.z(), Wt, 0.02 * Wt);
    EXPECT_NEAR(bm.force.z(), Wt + Wm, 0.02 * (Wt + Wm));
    EXPECT_NEAR(-g.force.z(), Wt + Wm + Wb, 0.02 * (Wt + Wm + Wb));
  } else {
    for (int i = 0; i < stepsFor(1.0); ++i) world.step();
  }
  // thrown at the top block at 1 m/s: it wakes when its velocities are set
  const double t0 = centreOfMass(T).x();
  C.setVelocities(std::vector<Eigen::Vector3d>(thrown->size(), Eigen::Vector3d(-1.0, 0.0, 0.0)));
  double overlap = 0.0;
  bool topWoke = false;
  for (int i = 0; i < stepsFor(0.5); ++i) {
    world.step();
    overlap = std::max(overlap, deepestOverlap(world));
    topWoke = topWoke || !world.asleep("top");
  }
  const double pushed = t0 - centreOfMass(T).x();
  std::printf("block thrown at 1 m/s at the top of the stack (%s): top pushed %.4g m, deepest overlap %.3g r\n",
              sleeping ? "sleeping" : "never sleeping", pushed, overlap);
  EXPECT_TRUE(allFinite(world));
  EXPECT_LT(overlap, 0.1) << "the thrown block does not pass into the top one";
  if (sleeping) {
    EXPECT_TRUE(topWoke) << "the struck block woke";
  }
  return pushed;
}

TEST(WorldSleep, ASleepingStackCarriesItsWeightAndWakesWhenStruck) {
  const double awake = strikeTheStack(false), sleeping = strikeTheStack(true);
  EXPECT_GT(awake, 0.005) << "the top block is pushed";
  EXPECT_NEAR(sleeping, awake, 0.1 * awake) << "woken, it is pushed as far as one that never slept";
}

// Until an object rests, sleeping changes nothing: two blocks thrown at each other over a block
// on the ground step to the bit as without it.
TEST(WorldSleep, ObjectsThatDoNotRestStepExactlyAsWithoutSleeping) {
  std::vector<std::vector<Eigen::Vector3d>> runs[2];
  for (int sleeping = 0; sleeping < 2; ++sleeping) {
    World world(kStep, kSubsteps);
    if (sleeping) world.setSleepParams(sleepAfter(1.0));
    world.setCollider("ground", ground(0.0));
    auto a = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0.05));
    auto b = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0.06, 0.005, 0.05));
    Solver& A = world.addObject("a", a, paramsFor(*a));
    Solver& B = world.addObject("b", b, paramsFor(*b));
    A.setVelocities(std::vector<Eigen::Vector3d>(a->size(), Eigen::Vector3d(0.5, 0.0, 0.0)));
    B.setVelocities(std::vector<Eigen::Vector3d>(b->size(), Eigen::Vector3d(-0.5, 0.0, 0.0)));
    for (int i = 0; i < stepsFor(0.8); ++i) world.step();
    runs[sleeping] = {A.positions(), B.positions()};
    EXPECT_EQ(world.sleepingCount(), 0u);
  }
  EXPECT_EQ(runs[0], runs[1]);
}

// What wakes a sleeping block resting on the ground, and what does not: a block of 3 x 3 x 3
// cells on the ground, a box "far" parked 2 m away, each case from the block asleep.
class SleepingBlock : public ::testing::Test {
 protected:
  SleepingBlock() : world(kStep, kSubsteps), a(boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0))) {
    world.setSleepParams(sleepAfter(0.5));
    world.setCollider("ground", ground(0.0));
    world.setCollider("far", box(Eigen::Vector3d(2, 0, 0.1), Eigen::Vector3d(0.05, 0.05, 0.05)));
    A = &world.addObject("a", a, paramsFor(*a, 1.0, 2.0));
  }
  /// Steps until the block sleeps (20 s at most); whether it does.
  bool settle() {
    for (int i = 0; i < stepsFor(20.0) && !world.asleep("a"); ++i) world.step();
    return world.asleep("a");
  }
  /// "far" back 2 m away, still.
  void park() {
    world.moveCollider("far", Eigen::Isometry3d(Eigen::Translation3d(2, 0, 0.1)), Eigen::Vector3d::Zero(),
                       Eigen::Vector3d::Zero());
  }

  World world;
  std::shared_ptr<const Lattice> a;
  Solver* A = nullptr;
};

TEST_F(SleepingBlock, WakesForADragOrAParameterNotForAColliderFarAway) {
  ASSERT_TRUE(settle());
  const ContactWrench held = world.contactWrench("ground");
  EXPECT_NEAR(-held.force.z(), a->totalMass() * kG, 0.02 * a->totalMass() * kG) << "asleep, it still weighs on the ground";
  // a collider moved and moving far away: still asleep
  world.moveCollider("far", Eigen::Isometry3d(Eigen::Translation3d(2, 0.5, 0.1)), Eigen::Vector3d(0, 0.1, 0),
                     Eigen::Vector3d::Zero());
  world.step();
  EXPECT_TRUE(world.asleep("a")) << "a collider far away";
  world.moveCollider("far", Eigen::Isometry3d(Eigen::Translation3d(2, 0.5, 0.1)), Eigen::Vector3d::Zero(),
                     Eigen::Vector3d::Zero());
  // a drag: awake while it holds
  A->grab("hand", {0}, A->positions()[0], 0.0);
  world.step();
  EXPECT_FALSE(world.asleep("a")) << "a drag";
  A->release("hand");
  ASSERT_TRUE(settle());
  // a parameter: gravity turned sideways
  SolverParams p = A->params();
  p.gravity = Eigen::Vector3d(3.0, 0.0, -9.81);
  A->setParams(p);
  world.step();
  EXPECT_FALSE(world.asleep("a")) << "a parameter changed";
}

TEST_F(SleepingBlock, WakesForAColliderSetOnItMovingAtItOrTakenAway) {
  ASSERT_TRUE(settle());
  // a collider put beside it, and one moving towards it
  world.moveCollider("far", Eigen::Isometry3d(Eigen::Translation3d(0.015, 0.015, 0.045)), Eigen::Vector3d::Zero(),
                     Eigen::Vector3d::Zero());
  world.step();
  EXPECT_FALSE(world.asleep("a")) << "a collider set down on it";
  park();
  ASSERT_TRUE(settle());
  // 5 cm a step, its face 5 cm away: it arrives at the end of the step, and wakes it before
  world.moveCollider("far", Eigen::Isometry3d(Eigen::Translation3d(0.13, 0.015, 0.015)),
                     Eigen::Vector3d(-3.0, 0, 0), Eigen::Vector3d::Zero());
  EXPECT_TRUE(world.asleep("a"));
  world.step();
  world.moveCollider("far", world.object("a")->colliders().at("far").pose, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  EXPECT_FALSE(world.asleep("a")) << "a collider moving at it";
  park();
  ASSERT_TRUE(settle());
  // the ground taken away: it falls
  const double z0 = centreOfMass(*A).z();
  EXPECT_TRUE(world.removeCollider("ground"));
  for (int i = 0; i < 10; ++i) world.step();
  EXPECT_FALSE(world.asleep("a"));
  EXPECT_LT(centreOfMass(*A).z(), z0 - 0.01) << "without the ground it falls";
}

TEST_F(SleepingBlock, WakesWhenItsStatePinsOrContactParametersAreSet) {
  const auto wokeBy = [&](const char* what, const std::function<void()>& change) {
    ASSERT_TRUE(settle()) << "before " << what;
    change();
    world.step();
    EXPECT_FALSE(world.asleep("a")) << what;
  };
  wokeBy("positions", [&]() { A->setPositions(A->positions()); });
  wokeBy("velocities", [&]() { A->setVelocities(std::vector<Eigen::Vector3d>(a->size(), Eigen::Vector3d::Zero())); });
  wokeBy("a pin", [&]() { A->setPinned(0, true); });
  wokeBy("a reset", [&]() { A->reset(); });
  wokeBy("the contact parameters", [&]() { world.setContactParams(world.contactParams()); });
}

TEST_F(SleepingBlock, AsleepItIsNotSteppedAndANewObjectANaNOrSwitchingOffWakesIt) {
  // asleep, it is not stepped: its particles stay, its clock still runs
  ASSERT_TRUE(settle());
  const double t0 = A->time();
  const auto still = A->positions();
  world.step();
  EXPECT_TRUE(world.asleep("a"));
  EXPECT_EQ(A->positions(), still);
  EXPECT_NEAR(A->time(), t0 + kStep, 1e-12);
  // an object added beside it wakes it
  auto b = boxAt(2, 2, 2, 0.01, Eigen::Vector3d(0.5, 0, 0));
  world.addObject("b", b, paramsFor(*b, 1.0, 2.0));
  EXPECT_FALSE(world.asleep("a")) << "an object added";
  EXPECT_TRUE(world.removeObject("b"));
  // a state that is not finite never rests
  ASSERT_TRUE(settle());
  std::vector<Eigen::Vector3d> bad = A->positions();
  bad[0].x() = std::numeric_limits<double>::quiet_NaN();
  A->setPositions(bad);
  for (int i = 0; i < stepsFor(3.0); ++i) world.step();
  EXPECT_FALSE(world.asleep("a")) << "a NaN never sleeps";
  A->reset();
  // sleeping switched off wakes it
  ASSERT_TRUE(settle());
  world.setSleepParams(SleepParams());
  EXPECT_FALSE(world.asleep("a"));
  EXPECT_THROW(world.setSleepParams(SleepParams{-1.0, 1.0}), std::invalid_argument);
  EXPECT_THROW(world.setSleepParams(SleepParams{1e-5, 0.0}), std::invalid_argument);
}

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

// A block lifted slowly off a sleeping one (33 um a step, below the contact's slop, so its
// motion alone wakes nothing): the force on the sleeping block changes by the lifted one's
// weight, which wakes it, and the ground then carries its weight alone (a block left asleep
// would hold the wrench of both).
TEST(WorldSleep, ABlockLiftedSlowlyOffASleepingOneWakesIt) {
  World world(kStep, kSubsteps);
  world.setSleepParams(sleepAfter(0.5));
  world.setCollider("ground", ground(0.0));
  auto bottom = boxAt(4, 4, 2, 0.01, Eigen::Vector3d(0, 0, 0));
  auto top = boxAt(2, 2, 2, 0.01, Eigen::Vector3d(0.01, 0.01, 0.02));
  world.addObject("bottom", bottom, paramsFor(*bottom, 1.0, 2.0));
  Solver& T = world.addObject("top", top, paramsFor(*top, 1.0, 2.0));
  for (int i = 0; i < stepsFor(10.0) && world.sleepingCount() < 2; ++i) world.step();
  ASSERT_EQ(world.sleepingCount(), 2u);
  const double Wb = bottom->totalMass() * kG, Wt = top->totalMass() * kG;
  EXPECT_NEAR(-world.contactWrench("ground").force.z(), Wb + Wt, 0.02 * (Wb + Wt));
  std::vector<std::uint32_t> all(top->size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  for (const auto& x : T.positions()) target += x / static_cast<double>(all.size());
  T.grab("lift", all, target, 0.0);
  bool woke = false;
  for (int i = 0; i < stepsFor(6.0); ++i) {
    if (i < stepsFor(5.0)) target.z() += 0.002 * kStep;  // 2 mm/s for 5 s
    T.moveDrag("lift", target);
    world.step();
    woke = woke || !world.asleep("bottom");
  }
  const double ground = -world.contactWrench("ground").force.z();
  std::printf("block lifted 1 cm off a sleeping one at 2 mm/s: the lower one woke: %s; the ground carries %.4f N (its "
              "weight %.4f, both %.4f)\n",
              woke ? "yes" : "no", ground, Wb, Wb + Wt);
  EXPECT_TRUE(woke);
  EXPECT_NEAR(ground, Wb, 0.02 * Wb) << "the ground carries the lower block alone";
  EXPECT_NEAR(world.objectWrench("bottom", "top").force.norm(), 0.0, 0.02 * Wt);
}

// Three soft cubes (30 kPa) stacked at one implicit sub-step fall asleep one by one and stay
// asleep, each contact carrying the weight above it. An implicit object resting on a sleeping
// one keeps its contact springs to it in its solve (the sleeping particles held still): without
// them it fell onto the sleeper for a step (the contact under it carried a sixth of the weight
// above), was caught by the contact pass, bounced and woke the stack, over and over.
TEST(WorldSleep, AnImplicitStackFallsAsleepAndStaysAsleepCarryingItsWeight) {
  World world(kStep, 1);
  world.setSleepParams(sleepAfter(1.0));
  world.setCollider("ground", ground(0.0));
  const char* names[3] = {"bottom", "middle", "top"};
  double weight[3];
  for (int k = 0; k < 3; ++k) {
    auto lattice = boxAt(5, 5, 5, 0.016, Eigen::Vector3d(0, 0, 0.09 * k + 0.01));
    world.addObject(names[k], lattice, implicitCube(30e3));
    weight[k] = lattice->totalMass() * kG;
  }
  int allAsleep = -1, woke = 0;
  double least[2] = {1e9, 1e9};  // the least force on the lower two cubes from above, in any step
  for (int i = 0; i < stepsFor(15.0); ++i) {
    world.step();
    least[0] = std::min(least[0], world.objectWrench("middle", "bottom").force.z() * -1.0);
    least[1] = std::min(least[1], world.objectWrench("top", "middle").force.z() * -1.0);
    if (i < stepsFor(1.5)) least[0] = least[1] = 1e9;  // the drop and its bounce
    if (allAsleep < 0 && world.sleepingCount() == 3) allAsleep = i;
    if (allAsleep >= 0 && world.sleepingCount() < 3) ++woke;
  }
  const double mt = world.objectWrench("middle", "top").force.z(), bm = world.objectWrench("bottom", "middle").force.z();
  const double g = -world.contactWrench("ground").force.z();
  std::printf("implicit stack of three 30 kPa cubes: all asleep at %.2f s, steps awake after: %d; middle->top %.4f N "
              "(weight %.4f), bottom->middle %.4f N (%.4f), ground %.4f N (%.4f); least force from above after 1.5 s: "
              "%.4f N on the middle, %.4f N on the bottom\n",
              allAsleep < 0 ? -1.0 : (allAsleep + 1) * kStep, woke, mt, weight[2], bm, weight[1] + weight[2], g,
              weight[0] + weight[1] + weight[2], least[1], least[0]);
  ASSERT_GE(allAsleep, 0) << "the stack never sleeps";
  EXPECT_LT(allAsleep, stepsFor(10.0));
  EXPECT_EQ(woke, 0) << "asleep, it stays asleep";
  EXPECT_NEAR(mt, weight[2], 0.005 * weight[2]);
  EXPECT_NEAR(bm, weight[1] + weight[2], 0.005 * (weight[1] + weight[2]));
  EXPECT_NEAR(g, weight[0] + weight[1] + weight[2], 0.005 * (weight[0] + weight[1] + weight[2]));
  EXPECT_GT(least[1], 0.9 * weight[2]) << "the top never falls onto the middle as it sleeps";
  EXPECT_GT(least[0], 0.9 * (weight[1] + weight[2])) << "nor the middle onto the bottom";
}

// A sleeping stack keeps its contacts' impulses while another object, away from it, turns and
// has the contact list built again and again: woken, its contact solve starts from them, as a
// stack woken with no build in between does (one Gauss-Seidel pass per sub-step: nothing to
// correct), and holds its weight from the first step. Dropped at a build, a woken object
// started cold; in a pile of 150 a finger's press then woke 149 of them instead of 122
// (bench_world).
static void wakeTheStack(bool moving, double& passes, double& least, double& above, std::size_t& built) {
  World world(kStep, kSubsteps);
  world.setSleepParams(sleepAfter(0.5));
  const BlockStack b = stackWithABlock(world, "mover", Eigen::Vector3d(0.3, 0.0, 0.0));
  const auto &middle = b.middle, &top = b.top, &mover = b.other;
  Solver& M = *world.object("mover");
  for (int i = 0; i < stepsFor(20.0) && world.sleepingCount() < 4; ++i) world.step();
  ASSERT_EQ(world.sleepingCount(), 4u);
  // the mover turned 0.5 rad about the vertical back and forth, 30 cm from the stack, for 2 s (or
  // held where it is): its particles move within it, which builds its list again (a motion of the
  // whole object alone would not)
  std::vector<std::uint32_t> all(mover->size());
  for (std::uint32_t i = 0; i < all.size(); ++i) all[i] = i;
  const Eigen::Isometry3d home(Eigen::Translation3d(centreOfMass(M)));
  M.attach("hand", all, home, 0.0);
  const std::size_t builds = world.contactListBuilds();
  for (int i = 0; i < stepsFor(2.0); ++i) {
    const double angle = moving ? 0.5 * std::sin(M_PI * (i + 1) * kStep) : 0.0;
    M.moveDrag("hand", home * Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitZ()));
    world.step();
  }
  built = world.contactListBuilds() - builds;
  EXPECT_EQ(world.sleepingCount(), 3u) << "the stack slept through it";
  above = (middle->totalMass() + top->totalMass()) * kG;
  world.wakeAll();
  const World::ContactPasses p0 = world.contactPasses();
  world.step();
  passes = world.contactPasses().since(p0).perSubstep();
  least = -world.objectWrench("middle", "bottom").force.z();
  for (int i = 0; i < stepsFor(0.5); ++i) {
    world.step();
    least = std::min(least, -world.objectWrench("middle", "bottom").force.z());
  }
}

TEST(WorldSleep, ASleepingStackKeepsItsContactsImpulsesOverTheBuildsOfOthers) {
  double passes[2], least[2], above = 0.0;
  std::size_t built[2];
  for (int moving = 0; moving < 2; ++moving) wakeTheStack(moving != 0, passes[moving], least[moving], above, built[moving]);
  std::printf("stack woken after %zu contact list builds of a moving object: %.3g contact passes per sub-step in its "
              "first step (%.3g after %zu builds), the middle's least force on the bottom %.4f N (%.4f; the weight "
              "above %.4f)\n",
              built[1], passes[1], passes[0], built[0], least[1], least[0], above);
  EXPECT_EQ(built[0], 0u) << "the reference stack wakes with no build in between";
  EXPECT_GT(built[1], 0u) << "the list was built while the stack slept";
  EXPECT_LE(passes[1], passes[0] + 1e-9) << "woken, it starts from its contacts' impulses";
  EXPECT_GT(least[1], 0.98 * above) << "it holds its weight from the first step";
}

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
