// Several objects in one World: the same steps as bare Solvers for one object and for objects
// apart, momentum kept by the contact between objects, the contact pass's counts and times,
// run-time changes and refusals, thread-count independence and steps that allocate nothing.
#include "deformable_flsm/core/world.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/object_contact.h"
#include "allocation_counter.h"
#include "fixtures.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <cstdlib>
#include <new>
#include <cstdio>
#include <ctime>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::world_scenes;

// --- one object ------------------------------------------------------------------------------

TEST(World, OneObjectStepsExactlyAsTheBareSolver) {
  auto lattice = boxAt(5, 4, 3, 0.01, Eigen::Vector3d(0, 0, 0.02));
  Solver bare(lattice, paramsFor(*lattice));
  World world(kStep, kSubsteps);
  Solver& object = world.addObject("block", lattice, paramsFor(*lattice));
  const Collider floor = ground(0.0);
  const Collider pusher = box(Eigen::Vector3d(0.08, 0.02, 0.02), Eigen::Vector3d(0.02, 0.05, 0.05));
  bare.setCollider("ground", floor);
  bare.setCollider("pusher", pusher);
  world.setCollider("ground", floor);
  world.setCollider("pusher", pusher);
  const Eigen::Vector3d towards(-0.05, 0, 0);
  bare.moveCollider("pusher", pusher.pose, towards, Eigen::Vector3d::Zero());
  world.moveCollider("pusher", pusher.pose, towards, Eigen::Vector3d::Zero());
  bare.grab("corner", {0, 1}, Eigen::Vector3d(0.0, 0.0, 0.06), 0.0);
  object.grab("corner", {0, 1}, Eigen::Vector3d(0.0, 0.0, 0.06), 0.0);
  std::size_t touched = 0;
  for (int i = 0; i < 60; ++i) {
    bare.step();
    world.step();
    touched += world.contactWrench("ground").contacts + world.contactWrench("pusher").contacts;
  }
  for (std::size_t i = 0; i < lattice->size(); ++i) {
    ASSERT_EQ(bare.positions()[i], object.positions()[i]) << "particle " << i;
    ASSERT_EQ(bare.velocities()[i], object.velocities()[i]) << "particle " << i;
  }
  EXPECT_EQ(bare.contactWrench("pusher").force, world.contactWrench("pusher").force);
  EXPECT_EQ(bare.contactWrench("ground").force, world.contactWrench("ground").force);
  EXPECT_GT(touched, 0u) << "the scene touches its colliders";
  EXPECT_EQ(world.time(), bare.time());
}

// Objects that do not touch each other step exactly as bare solvers, although their region sums
// sweep one set of slice buffers (the World's) that the others have just filled: lattices of
// different sizes and region widths, one object on two threads, one dragged, all falling onto
// the ground. The set stays shared when an object's summers are rebuilt (a new thread count).
TEST(World, ObjectsApartStepExactlyAsBareSolvers) {
  const std::vector<std::shared_ptr<const Lattice>> lattices = {
      boxAt(5, 4, 3, 0.01, Eigen::Vector3d(0, 0, 0.02), 1), boxAt(9, 7, 6, 0.01, Eigen::Vector3d(0.2, 0, 0.03), 2),
      boxAt(4, 4, 8, 0.01, Eigen::Vector3d(-0.2, 0, 0.01), 3)};
  const auto params = [&](std::size_t o) {
    SolverParams p = paramsFor(*lattices[o]);
    p.threads = o == 1 ? 2 : 1;
    return p;
  };
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  std::vector<std::unique_ptr<Solver>> bare;
  std::vector<Solver*> objects;
  for (std::size_t o = 0; o < lattices.size(); ++o) {
    bare.push_back(std::make_unique<Solver>(lattices[o], params(o)));
    bare.back()->setCollider("ground", ground(0.0));
    objects.push_back(&world.addObject("object" + std::to_string(o), lattices[o], params(o)));
  }
  const auto shared = objects[0]->regionScratch();
  ASSERT_NE(shared, nullptr);
  for (std::size_t o = 0; o < lattices.size(); ++o) {
    EXPECT_EQ(objects[o]->regionScratch(), shared) << "object " << o;
    EXPECT_NE(bare[o]->regionScratch(), shared) << "bare solver " << o;
  }
  const Eigen::Vector3d target = lattices[1]->restPositions()[0] + Eigen::Vector3d(0.0, 0.02, 0.05);
  bare[1]->grab("corner", {0, 1}, target, 0.0);
  objects[1]->grab("corner", {0, 1}, target, 0.0);
  for (int i = 0; i < 40; ++i) {
    if (i == 20) {  // object 2 on two threads from now on: its summers are made again
      SolverParams p = params(2);
      p.threads = 2;
      bare[2]->setParams(p);
      objects[2]->setParams(p);
      ASSERT_EQ(objects[2]->regionScratch(), shared);
    }
    for (auto& s : bare) s->step();
    world.step();
  }
  EXPECT_TRUE(world.objectWrenches().empty()) << "the objects stay apart";
  for (std::size_t o = 0; o < lattices.size(); ++o)
    for (std::size_t i = 0; i < lattices[o]->size(); ++i) {
      ASSERT_EQ(bare[o]->positions()[i], objects[o]->positions()[i]) << "object " << o << ", particle " << i;
      ASSERT_EQ(bare[o]->velocities()[i], objects[o]->velocities()[i]) << "object " << o << ", particle " << i;
    }
}

// --- momentum --------------------------------------------------------------------------------

namespace {

struct Momenta {
  Eigen::Vector3d P = Eigen::Vector3d::Zero(), L = Eigen::Vector3d::Zero();
  double scaleP = 0.0, scaleL = 0.0;  // sum m |v|, sum m |x| |v|: the yardsticks of round-off
};

Momenta momenta(const World& world) {
  Momenta m;
  for (const std::string& name : world.objectNames()) {
    const Solver& s = *world.object(name);
    m.P += s.linearMomentum();
    m.L += s.angularMomentum();
    for (std::size_t i = 0; i < s.positions().size(); ++i) {
      const double mi = s.lattice().masses()[i];
      m.scaleP += mi * s.velocities()[i].norm();
      m.scaleL += mi * s.positions()[i].norm() * s.velocities()[i].norm();
    }
  }
  return m;
}

/// Two free blocks thrown at each other off-centre and spinning (no gravity, no colliders).
void throwTwoBlocks(World& world, Integrator integrator = Integrator::Explicit) {
  auto a = boxAt(4, 3, 3, 0.01, Eigen::Vector3d(-0.06, 0.0, 0.0));
  auto b = boxAt(3, 4, 3, 0.01, Eigen::Vector3d(0.02, 0.012, 0.008));
  SolverParams pa = paramsFor(*a, 0.3, 0.5, integrator), pb = paramsFor(*b, 0.3, 0.5, integrator);
  pa.gravity.setZero();
  pb.gravity.setZero();
  Solver& A = world.addObject("a", a, pa);
  Solver& B = world.addObject("b", b, pb);
  test::deformAndSpin(A, Eigen::Vector3d(0.0, 0.0, 2.0), 1);
  test::deformAndSpin(B, Eigen::Vector3d(1.0, 0.0, -1.0), 2);
  std::vector<Eigen::Vector3d> va = A.velocities(), vb = B.velocities();
  for (auto& v : va) v += Eigen::Vector3d(0.6, 0.0, 0.0);
  for (auto& v : vb) v += Eigen::Vector3d(-0.6, 0.0, 0.0);
  A.setVelocities(va);
  B.setVelocities(vb);
}

}  // namespace

static void frictionlessCollision(Integrator integrator) {
  ObjectContactParams contact;
  contact.staticFriction = contact.kineticFriction = 0.0;
  World world(kStep, substepsOf(integrator), contact);
  throwTwoBlocks(world, integrator);
  const Momenta before = momenta(world);
  std::size_t touched = 0;
  for (int i = 0; i < 30; ++i) {
    world.step();
    touched += world.objectWrenches().size();
  }
  const Momenta after = momenta(world);
  EXPECT_GT(touched, 0u) << "the blocks collide";
  std::printf("frictionless collision: |dP| %.3g of sum m|v| %.3g, |dL| %.3g of sum m|x||v| %.3g\n",
              (after.P - before.P).norm(), before.scaleP, (after.L - before.L).norm(), before.scaleL);
  // round-off: a few ulps per particle update, over 240 sub-steps of some hundred particles
  // (friction, below, breaks angular momentum by 1e-2 of the yardstick)
  EXPECT_LT((after.P - before.P).norm(), 1e-10 * before.scaleP);
  EXPECT_LT((after.L - before.L).norm(), 1e-10 * before.scaleL);
}

TEST(World, FrictionlessCollisionConservesLinearAndAngularMomentum) { frictionlessCollision(Integrator::Explicit); }

// In one implicit solve: the contact springs act along the line between their particles at the
// start of the sub-step, equal and opposite, and each free object's rigid modes are corrected to
// what the external forces and the springs' impulses give (correctRigidModes()).
TEST(World, FrictionlessCollisionConservesLinearAndAngularMomentumInOneImplicitSolve) {
  frictionlessCollision(Integrator::Implicit);
}

TEST(World, CollisionWithFrictionConservesLinearMomentum) {
  World world(kStep, kSubsteps);
  throwTwoBlocks(world);
  const Momenta before = momenta(world);
  for (int i = 0; i < 30; ++i) world.step();
  const Momenta after = momenta(world);
  EXPECT_LT((after.P - before.P).norm(), 1e-10 * before.scaleP);
  // Friction between particle centres 2r apart is a couple the spinless particles cannot take:
  // bounded by 2 r times the friction impulse, itself at most mu_s times the normal impulse,
  // which cannot exceed the momentum the blocks bring (sum m |v|).
  const double r = 0.005;
  std::printf("collision with friction: |dL| %.3g, bound 2 r mu sum m|v| = %.3g\n", (after.L - before.L).norm(),
              2.0 * r * 0.6 * 2.0 * before.scaleP);
  EXPECT_LT((after.L - before.L).norm(), 2.0 * r * 0.6 * 2.0 * before.scaleP);
}

// The benchmarks' figure of Gauss-Seidel passes: counted in the sub-steps that have contacts
// only, at least one pass and at most ObjectContactParams::iterations each.
TEST(World, ContactPassesAreCountedInTheSubstepsWithContacts) {
  for (int iterations : {1, 16}) {
    ObjectContactParams contact;
    contact.iterations = iterations;
    World world(kStep, kSubsteps, contact);
    throwTwoBlocks(world);
    world.step();
    EXPECT_EQ(world.contactPasses().substeps, 0u) << "the blocks start apart";
    World::ContactPasses before = world.contactPasses();
    std::size_t touching = 0;
    for (int i = 0; i < 30; ++i) {
      world.step();
      touching += world.objectWrenches().empty() ? 0 : 1;
    }
    const World::ContactPasses during = world.contactPasses().since(before);
    ASSERT_GT(touching, 0u) << "the blocks collide";
    ASSERT_GT(during.substeps, 0u);
    EXPECT_LE(during.substeps, 30u * kSubsteps);
    EXPECT_GE(during.passes, during.substeps);
    EXPECT_LE(during.passes, during.substeps * static_cast<std::size_t>(iterations));
    if (iterations == 1) {
      EXPECT_EQ(during.perSubstep(), 1.0);
    }
  }
}

TEST(World, ContactTimesSplitTheContactPassWhenTimed) {
  const auto cpu = [] {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
  };
  for (bool timed : {false, true}) {
    World world(kStep, kSubsteps);
    world.setContactTiming(timed);
    throwTwoBlocks(world);
    const double t0 = cpu();
    std::size_t touching = 0;
    for (int i = 0; i < 30; ++i) {
      world.step();
      touching += world.objectWrenches().empty() ? 0 : 1;
    }
    const double stepped = cpu() - t0;
    ASSERT_GT(touching, 0u) << "the blocks collide";
    const World::ContactTimes t = world.contactTimes();
    if (!timed) {
      EXPECT_EQ(t.list + t.pairs + t.passes + t.rest, 0.0) << "nothing timed unless asked";
      continue;
    }
    // each part was spent (the blocks fly, touch and part), and all of them within the steps
    EXPECT_GT(t.list, 0.0);
    EXPECT_GT(t.pairs, 0.0);
    EXPECT_GT(t.passes, 0.0);
    EXPECT_GT(t.rest, 0.0);
    EXPECT_LE(t.list + t.pairs + t.passes + t.rest, stepped);
    const World::ContactTimes none = world.contactTimes().since(t);
    EXPECT_EQ(none.list + none.pairs + none.passes + none.rest, 0.0);
  }
}

// --- run-time changes and refusals -----------------------------------------------------------

TEST(World, ObjectsAreAddedAndRemovedAtRunTime) {
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  auto a = boxAt(3, 3, 2, 0.01, Eigen::Vector3d(0, 0, 0));
  auto b = boxAt(3, 3, 2, 0.01, Eigen::Vector3d(0, 0, 0.02));
  world.addObject("a", a, paramsFor(*a));
  world.addObject("b", b, paramsFor(*b));
  for (int i = 0; i < 30; ++i) world.step();
  EXPECT_GT(world.objectWrench("a", "b").force.z(), 0.0);
  // a third one dropped on top later, given the ground set before it came
  auto c = boxAt(3, 3, 2, 0.01, Eigen::Vector3d(0, 0, 0.06));
  world.addObject("c", c, paramsFor(*c));
  EXPECT_EQ(world.objectCount(), 3u);
  EXPECT_EQ(world.object("c")->colliders().count("ground"), 1u);
  for (int i = 0; i < 60; ++i) world.step();
  EXPECT_GT(world.objectWrench("b", "c").force.z(), 0.0) << "c landed on b";
  // take the middle one out: c falls onto a
  EXPECT_TRUE(world.removeObject("b"));
  EXPECT_FALSE(world.removeObject("b"));
  EXPECT_EQ(world.object("b"), nullptr);
  EXPECT_EQ(world.objectNames(), (std::vector<std::string>{"a", "c"}));
  for (const ObjectPairWrench& w : world.objectWrenches()) EXPECT_TRUE(w.from != "b" && w.on != "b");
  for (int i = 0; i < 60; ++i) world.step();
  EXPECT_GT(world.objectWrench("a", "c").force.z(), 0.0) << "c fell onto a";
  EXPECT_LT(deepestOverlap(world), 0.1);
}

TEST(World, RefusesDuplicatesOverlapsAndOtherTimeSteps) {
  World world(kStep, kSubsteps);
  auto a = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0));
  world.addObject("a", a, paramsFor(*a));
  EXPECT_THROW(world.addObject("a", boxAt(2, 2, 2, 0.01, Eigen::Vector3d(1, 0, 0)), paramsFor(*a)), std::invalid_argument);
  EXPECT_THROW(world.addObject("", boxAt(2, 2, 2, 0.01, Eigen::Vector3d(1, 0, 0)), paramsFor(*a)), std::invalid_argument);
  try {
    world.addObject("inside", boxAt(2, 2, 2, 0.01, Eigen::Vector3d(0.015, 0.015, 0.015)), paramsFor(*a));
    ADD_FAILURE() << "an object starting inside another is refused";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("'inside'"), std::string::npos) << what;
    EXPECT_NE(what.find("'a'"), std::string::npos) << what;
  }
  SolverParams other = paramsFor(*a);
  other.substeps = kSubsteps + 1;
  EXPECT_THROW(world.addObject("b", boxAt(2, 2, 2, 0.01, Eigen::Vector3d(1, 0, 0)), other), std::invalid_argument);
  // touching face to face is not overlapping
  EXPECT_NO_THROW(world.addObject("beside", boxAt(2, 2, 2, 0.01, Eigen::Vector3d(0.03, 0, 0)), paramsFor(*a)));
  EXPECT_EQ(world.objectNames(), (std::vector<std::string>{"a", "beside"}));
  EXPECT_THROW(World(0.0, 4), std::invalid_argument);
  EXPECT_THROW(World(kStep, 0), std::invalid_argument);
  ObjectContactParams bad;
  bad.kineticFriction = bad.staticFriction + 0.1;
  EXPECT_THROW(World(kStep, kSubsteps, bad), std::invalid_argument);
  // an object set to another time step stops the world's step, naming it
  world.object("a")->setParams(other);
  EXPECT_THROW(world.step(), std::logic_error);
}

static void threadCountIndependent(Integrator integrator) {
  auto run = [integrator](int threads) {
    World world(kStep, substepsOf(integrator));
    world.setCollider("ground", ground(0.0));
    std::vector<std::shared_ptr<const Lattice>> lattices = {boxAt(8, 8, 4, 0.01, Eigen::Vector3d(0, 0, 0)),
                                                            boxAt(4, 4, 4, 0.01, Eigen::Vector3d(0.02, 0.02, 0.045))};
    for (std::size_t o = 0; o < lattices.size(); ++o) {
      SolverParams p = paramsFor(*lattices[o], 0.3, 0.5, integrator);
      p.threads = threads;
      world.addObject("o" + std::to_string(o), lattices[o], p);
    }
    for (int i = 0; i < 60; ++i) world.step();
    std::vector<Eigen::Vector3d> x;
    for (const std::string& name : world.objectNames())
      x.insert(x.end(), world.object(name)->positions().begin(), world.object(name)->positions().end());
    x.push_back(world.objectWrench("o0", "o1").force);
    return x;
  };
  const auto one = run(1), two = run(2);
  ASSERT_EQ(one.size(), two.size());
  EXPECT_NE(one.back(), Eigen::Vector3d::Zero()) << "the objects touch";
  for (std::size_t i = 0; i < one.size(); ++i) ASSERT_EQ(one[i], two[i]) << i;
}

TEST(World, ResultsDoNotDependOnTheThreadCount) { threadCountIndependent(Integrator::Explicit); }

TEST(World, ImplicitResultsDoNotDependOnTheThreadCount) { threadCountIndependent(Integrator::Implicit); }

static void stepWithoutAllocating(Integrator integrator) {
  // a stack on the ground pushed by a kinematic box, with self-contact: every path of the pass
  // (with the implicit step, of the coupled solve too)
  ObjectContactParams contact;
  contact.selfContact = true;
  World world(kStep, substepsOf(integrator), contact);
  world.setCollider("ground", ground(0.0));
  auto a = boxAt(4, 4, 2, 0.01, Eigen::Vector3d(0, 0, 0));
  auto b = boxAt(3, 3, 2, 0.01, Eigen::Vector3d(0.005, 0.005, 0.02));
  world.addObject("a", a, paramsFor(*a, 0.3, 0.5, integrator));
  world.addObject("b", b, paramsFor(*b, 0.3, 0.5, integrator));
  const Collider pusher = box(Eigen::Vector3d(0.07, 0.02, 0.02), Eigen::Vector3d(0.02, 0.05, 0.05));
  world.setCollider("pusher", pusher);
  world.moveCollider("pusher", pusher.pose, Eigen::Vector3d(-0.01, 0, 0), Eigen::Vector3d::Zero());
  for (int i = 0; i < 60; ++i) world.step();
  ASSERT_FALSE(world.objectWrenches().empty());
  const long before = gAllocations.load();
  for (int i = 0; i < 20; ++i) world.step();
  EXPECT_EQ(gAllocations.load() - before, 0);
  EXPECT_FALSE(world.objectWrenches().empty());
}

TEST(World, StepDoesNotAllocateOnceItsBuffersHaveGrown) { stepWithoutAllocating(Integrator::Explicit); }

TEST(World, ImplicitStepDoesNotAllocateOnceItsBuffersHaveGrown) { stepWithoutAllocating(Integrator::Implicit); }

// ImplicitScheme::Bdf2 steps one object alone: in a world of one it steps exactly as the bare
// solver, and an object that could touch it (object contact on) is refused with a reason.
TEST(World, Bdf2StepsOneObjectAsTheBareSolverAndRefusesObjectsThatTouchIt) {
  auto lattice = boxAt(5, 4, 3, 0.01, Eigen::Vector3d(0, 0, 0.02));
  SolverParams p = paramsFor(*lattice);
  p.integrator = Integrator::Implicit;
  p.implicitScheme = ImplicitScheme::Bdf2;
  Solver bare(lattice, p);
  World world(kStep, kSubsteps);
  Solver& object = world.addObject("block", lattice, p);
  bare.setCollider("ground", ground(0.0));
  world.setCollider("ground", ground(0.0));
  for (int i = 0; i < 30; ++i) {
    bare.step();
    world.step();
  }
  for (std::size_t i = 0; i < lattice->size(); ++i) ASSERT_EQ(bare.positions()[i], object.positions()[i]);
  EXPECT_EQ(world.time(), bare.time());
  auto other = boxAt(5, 4, 3, 0.01, Eigen::Vector3d(0.1, 0, 0.02));
  SolverParams q = paramsFor(*other);
  q.integrator = Integrator::Implicit;
  try {
    world.addObject("neighbour", other, q);
    FAIL() << "an object beside a bdf2 one is refused";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("bdf2"), std::string::npos) << e.what();
  }
  EXPECT_EQ(world.objectCount(), 1u);
}
