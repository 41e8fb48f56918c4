// Sleeping objects in a World: a stack that sleeps carrying its weight, wakes when struck and
// keeps its contacts' impulses while others move, what wakes a block asleep on the ground, a
// block lifted off a sleeping one, an implicit stack that stays asleep, and objects that do not
// rest stepping exactly as without sleeping.
#include "deformable_flsm/core/world.h"

#include "sleep_fixtures.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::sleep_fixtures;
using namespace deformable_flsm::world_scenes;

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
