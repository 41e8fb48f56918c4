// Several objects in one World: the same steps as a bare Solver for one object, momentum kept by
// the contact between objects, and scenes compared with statics: a stack whose contacts carry
// the weight above them, two objects squeezed by a collider, a bin of objects, a gripper lifting
// two stacked objects by friction, a bar folded onto itself, a pile of soft objects that stays at
// rest; run-time changes and refusals.
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
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <random>
#include <set>
#include <string>
#include <vector>

using namespace deformable_flsm;
using namespace deformable_flsm::world_scenes;

namespace {

/// The particle pairs of objects a and b (a's particle, b's) closer than `reach` times the sum of
/// their contact radii.
std::size_t pairsWithin(const World& world, const std::string& a, const std::string& b, double reach) {
  const Solver& A = *world.object(a);
  const Solver& B = *world.object(b);
  const double R = reach * (A.contactRadius() + B.contactRadius());
  std::size_t count = 0;
  for (const auto& x : A.positions())
    for (const auto& y : B.positions()) count += (x - y).squaredNorm() < R * R ? 1 : 0;
  return count;
}

}  // namespace

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

// --- a stack ---------------------------------------------------------------------------------

// The stack with `integrator` at `substeps` sub-steps of each 1/60 s step.
static void stackOfThree(Integrator integrator, int substeps) {
  World world(kStep, substeps);
  world.setCollider("ground", ground(0.0));
  const double s = 0.01;
  // face to face: each block's bottom spheres touch the top spheres of the one below
  auto bottom = boxAt(6, 6, 2, s, Eigen::Vector3d(0, 0, 0));
  auto middle = boxAt(4, 4, 2, s, Eigen::Vector3d(0.01, 0.01, 0.02));
  auto top = boxAt(4, 2, 2, s, Eigen::Vector3d(0.01, 0.02, 0.04));
  // firm and well damped, so that the stack's slow vertical bounce settles within the test
  const auto params = [&](const Lattice& lattice) {
    SolverParams p = paramsFor(lattice, 1.0, 2.0);
    p.integrator = integrator;
    p.substeps = substeps;
    return p;
  };
  world.addObject("bottom", bottom, params(*bottom));
  world.addObject("middle", middle, params(*middle));
  world.addObject("top", top, params(*top));
  const int steps = stepsFor(4.0), last = stepsFor(1.0);
  ContactWrench bm, mt, g;  // averaged over the last second
  double overlap = 0.0;
  for (int i = 0; i < steps; ++i) {
    world.step();
    overlap = std::max(overlap, deepestOverlap(world));
    if (i < steps - last) continue;
    bm.force += world.objectWrench("bottom", "middle").force / last;
    mt.force += world.objectWrench("middle", "top").force / last;
    g.force += world.contactWrench("ground").force / last;
  }
  const double Wt = top->totalMass() * kG, Wm = middle->totalMass() * kG, Wb = bottom->totalMass() * kG;
  std::printf("stack (%s, %d sub-steps): middle->top %.4f N (weight %.4f), bottom->middle %.4f N (weight above %.4f), "
              "ground %.4f N (all %.4f); deepest overlap %.3g r, max speed %.3g m/s\n",
              integrator == Integrator::Implicit ? "implicit" : "explicit", substeps, mt.force.z(), Wt, bm.force.z(), Wt + Wm, -g.force.z(), Wt + Wm + Wb, overlap, maxSpeed(world));
  EXPECT_NEAR(mt.force.z(), Wt, 0.02 * Wt);
  EXPECT_NEAR(bm.force.z(), Wt + Wm, 0.02 * (Wt + Wm));
  EXPECT_NEAR(-g.force.z(), Wt + Wm + Wb, 0.02 * (Wt + Wm + Wb));
  EXPECT_NEAR(world.objectWrench("top", "middle").force.z(), -mt.force.z(), 0.1 * Wt) << "equal and opposite";
  EXPECT_LT(overlap, 0.1) << "no two spheres of different objects overlap by a tenth of a radius";
  EXPECT_LT(maxSpeed(world), 1e-3) << "the stack is at rest";
}

TEST(WorldScene, AStackOfThreeCarriesTheWeightAboveEachContact) { stackOfThree(Integrator::Explicit, kSubsteps); }

// The same at one implicit sub-step: the three objects' systems and the contact springs between
// them in one solve (ImplicitCoupling).
TEST(WorldScene, AStackOfThreeCarriesTheWeightAboveEachContactWithTheImplicitStep) {
  stackOfThree(Integrator::Implicit, 1);
}

// --- squeezed by a collider ------------------------------------------------------------------

TEST(WorldScene, TwoBlocksSqueezedByAColliderDoNotPassThroughAndRecover) {
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  // a wall at x = 0, the blocks side by side, a pusher at their right face
  world.setCollider("wall", box(Eigen::Vector3d(-0.05, 0.02, 0.05), Eigen::Vector3d(0.05, 0.1, 0.1)));
  auto a = boxAt(4, 4, 3, 0.01, Eigen::Vector3d(0.0, 0.0, 0.0));
  auto b = boxAt(4, 4, 3, 0.01, Eigen::Vector3d(0.04, 0.0, 0.0));
  Solver& A = world.addObject("a", a, paramsFor(*a, 1.0, 2.0));
  Solver& B = world.addObject("b", b, paramsFor(*b, 1.0, 2.0));
  const Collider pusher = box(Eigen::Vector3d(0.13, 0.02, 0.05), Eigen::Vector3d(0.05, 0.1, 0.1));
  world.setCollider("pusher", pusher);
  for (int i = 0; i < stepsFor(1.0); ++i) world.step();
  const double restA = A.shapeError(), restB = B.shapeError();
  // push 2 cm (a quarter of the two blocks' width) in 1 s, hold, then back away
  const Eigen::Vector3d in(-0.02, 0.0, 0.0);
  world.moveCollider("pusher", world.object("a") ? pusher.pose : pusher.pose, in, Eigen::Vector3d::Zero());
  double overlap = 0.0, squeezed = 0.0, push = 0.0;
  for (int i = 0; i < stepsFor(1.0); ++i) {
    world.step();
    overlap = std::max(overlap, deepestOverlap(world));
  }
  Eigen::Isometry3d held = pusher.pose;
  held.translation() += in;
  world.moveCollider("pusher", held, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(0.5); ++i) {
    world.step();
    overlap = std::max(overlap, deepestOverlap(world));
  }
  squeezed = std::min(A.shapeError(), B.shapeError());
  push = world.contactWrench("pusher").force.x();
  const double between = world.objectWrench("a", "b").force.x();
  world.moveCollider("pusher", pusher.pose, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(2.0); ++i) world.step();
  std::printf("squeeze: pusher %.3f N, a on b %.3f N; shape error at rest %.3g/%.3g m, squeezed %.3g m, "
              "released %.3g/%.3g m; deepest overlap %.3g r\n",
              push, between, restA, restB, squeezed, A.shapeError(), B.shapeError(), overlap);
  EXPECT_GT(push, 0.1) << "the pusher presses the blocks against the wall";
  // statics along x: the wall holds what the pusher pushes, through both blocks (the ground's
  // friction takes a share)
  EXPECT_GT(between, 0.5 * push);
  EXPECT_GT(squeezed, 10.0 * std::max(restA, restB)) << "the squeeze deforms both";
  EXPECT_LT(overlap, 0.1) << "neither passes through the other";
  EXPECT_LT(A.shapeError(), 2.0 * restA + 1e-5) << "released, a recovers its shape";
  EXPECT_LT(B.shapeError(), 2.0 * restB + 1e-5) << "released, b recovers its shape";
}

// --- a bin -----------------------------------------------------------------------------------

TEST(WorldScene, TwentyObjectsDroppedIntoABinComeToRestInside) {
  World world(kStep, kSubsteps);
  // a 14 x 14 cm bin 10 cm deep: a floor and four walls (thicker than a particle can be pushed
  // into: a box pushes out through its nearest face)
  const double inner = 0.07, depth = 0.1, wall = 0.05;
  const std::vector<std::pair<std::string, Collider>> colliders = binColliders(inner, depth, wall);
  for (const auto& c : colliders) world.setCollider(c.first, c.second);
  // five layers of four 3 x 3 x 3 cm blocks, each layer shifted, every block spinning so that
  // they tumble onto each other
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (int n = 0; n < 20; ++n) {
    const int layer = n / 4, corner = n % 4;
    const double shift = (layer % 2 == 0 ? -0.01 : 0.01);
    const Eigen::Vector3d lo((corner % 2 == 0 ? -0.045 : 0.005) + shift, (corner / 2 == 0 ? -0.045 : 0.005) - shift,
                             0.01 + 0.045 * layer);
    auto lattice = boxAt(3, 3, 3, 0.01, lo);
    Solver& s = world.addObject("block" + std::to_string(n), lattice, paramsFor(*lattice, 1.0, 2.0));
    const Eigen::Vector3d centre = lo + Eigen::Vector3d::Constant(0.015);
    const Eigen::Vector3d spin = 5.0 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    std::vector<Eigen::Vector3d> v(lattice->size());
    for (std::size_t i = 0; i < v.size(); ++i) v[i] = spin.cross(s.positions()[i] - centre);
    s.setVelocities(v);
  }
  double overlap = 0.0;
  for (int i = 0; i < stepsFor(4.0); ++i) {
    world.step();
    if (i % 6 == 0) overlap = std::max(overlap, deepestOverlap(world));
  }
  overlap = std::max(overlap, deepestOverlap(world));
  // how far the deepest sphere reaches into a wall or the floor (r = 5 mm)
  const double r = 0.005;
  double intoWalls = -r, highest = 0.0;
  for (const std::string& name : world.objectNames())
    for (const auto& x : world.object(name)->positions()) {
      intoWalls = std::max({intoWalls, std::abs(x.x()) + r - inner, std::abs(x.y()) + r - inner, r - x.z()});
      highest = std::max(highest, x.z());
    }
  std::printf("bin: 20 blocks, max speed %.3g m/s, deepest overlap %.3g r, deepest into a wall %.3g r, "
              "top of the pile %.3f m\n",
              maxSpeed(world), overlap, intoWalls / r, highest);
  EXPECT_TRUE(allFinite(world));
  EXPECT_LT(intoWalls, 0.1 * r) << "nothing escapes the bin or sinks into its walls";
  EXPECT_LT(highest, depth) << "the pile settles below the rim";
  EXPECT_LT(overlap, 0.1) << "no two blocks interpenetrate";
  EXPECT_LT(maxSpeed(world), 0.02) << "the pile comes to rest";
}

// --- a gripper lifting two objects -----------------------------------------------------------

namespace {

/// Two blocks side by side between two fingers, the left finger with friction, the right one
/// smooth: squeezed, then lifted 3 cm. Returns how far the right block (held by the smooth
/// finger and its neighbour only) rose.
double liftTwoBlocks(double objectFriction, double* leftRise) {
  ObjectContactParams contact;
  contact.staticFriction = contact.kineticFriction = objectFriction;
  World world(kStep, kSubsteps, contact);
  world.setCollider("ground", ground(0.0));
  auto a = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0.0, 0.0, 0.0));
  auto b = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0.03, 0.0, 0.0));
  Solver& A = world.addObject("a", a, paramsFor(*a, 1.0, 2.0));
  Solver& B = world.addObject("b", b, paramsFor(*b, 1.0, 2.0));
  const Eigen::Vector3d half(0.01, 0.03, 0.03);
  Collider left = box(Eigen::Vector3d(-0.01, 0.015, 0.025), half, 1.0);
  Collider right = box(Eigen::Vector3d(0.07, 0.015, 0.025), half, 0.0);
  world.setCollider("left", left);
  world.setCollider("right", right);
  for (int i = 0; i < stepsFor(0.5); ++i) world.step();
  const double a0 = centreOfMass(A).z(), b0 = centreOfMass(B).z();
  // squeeze 3 mm each in 0.3 s, then lift at 10 cm/s for 0.3 s, then hold
  const Eigen::Vector3d squeeze(0.01, 0.0, 0.0), up(0.0, 0.0, 0.1);
  world.moveCollider("left", left.pose, squeeze, Eigen::Vector3d::Zero());
  world.moveCollider("right", right.pose, -squeeze, Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(0.3); ++i) world.step();
  left.pose.translation() += 0.3 * squeeze;
  right.pose.translation() -= 0.3 * squeeze;
  world.moveCollider("left", left.pose, up, Eigen::Vector3d::Zero());
  world.moveCollider("right", right.pose, up, Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(0.3); ++i) world.step();
  left.pose.translation() += 0.3 * up;
  right.pose.translation() += 0.3 * up;
  world.moveCollider("left", left.pose, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  world.moveCollider("right", right.pose, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  for (int i = 0; i < stepsFor(0.5); ++i) world.step();
  *leftRise = centreOfMass(A).z() - a0;
  return centreOfMass(B).z() - b0;
}

}  // namespace

TEST(WorldScene, AGripperLiftsTwoObjectsThroughTheFrictionBetweenThem) {
  double aRise = 0.0, aRiseSmooth = 0.0;
  const double bRise = liftTwoBlocks(0.8, &aRise);
  const double bRiseSmooth = liftTwoBlocks(0.0, &aRiseSmooth);
  std::printf("gripper lifts 3 cm: with friction between the blocks a rises %.4f m, b %.4f m; "
              "without, a %.4f m, b %.4f m\n",
              aRise, bRise, aRiseSmooth, bRiseSmooth);
  EXPECT_NEAR(aRise, 0.03, 0.006) << "the block on the rough finger rises with the gripper";
  EXPECT_NEAR(bRise, 0.03, 0.006) << "the block on the smooth finger is carried by its neighbour";
  EXPECT_LT(bRiseSmooth, 0.01) << "without friction between them it is left behind";
}

// --- self-contact ----------------------------------------------------------------------------

namespace {

/// The deepest overlap of two spheres of one object farther apart than `exclusion` cells in
/// the rest lattice, as a fraction of the radius (brute force).
double deepestSelfOverlap(const Solver& s, int exclusion) {
  const auto& x = s.positions();
  const auto& cells = s.lattice().cells();
  const double r = s.contactRadius();
  double deepest = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i)
    for (std::size_t j = i + 1; j < x.size(); ++j)
      if ((cells[i] - cells[j]).cwiseAbs().maxCoeff() > exclusion)
        deepest = std::max(deepest, (2.0 * r - (x[i] - x[j]).norm()) / r);
  return deepest;
}

/// A 20 x 2 x 2 bar whose left half is pinned, its right end pulled by a spring drag up, over
/// the pinned half and down through it (no gravity). Returns the deepest self-overlap over the
/// fold.
double foldBar(bool selfContact) {
  ObjectContactParams contact;
  contact.selfContact = selfContact;
  World world(kStep, kSubsteps, contact);
  auto bar = boxAt(20, 2, 2, 0.01, Eigen::Vector3d(0, 0, 0));
  SolverParams p = paramsFor(*bar, 1.0, 2.0);
  p.gravity.setZero();
  Solver& s = world.addObject("bar", bar, p);
  s.pinBox(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0.1, 1, 1), true);
  std::vector<std::uint32_t> end;
  for (std::uint32_t i = 0; i < bar->size(); ++i)
    if (bar->cells()[i].x() >= 18) end.push_back(i);
  const Eigen::Vector3d start(0.19, 0.01, 0.01);
  // a soft spring: a near-hard one crushes the thin bar between its end and the pinned half
  s.grab("end", end, start, 0.05 * s.springLimit("end", end).stiffness);
  // a half circle about the fold from x = 0.19 to x = 0.03, then down through the pinned half
  const Eigen::Vector3d centre(0.11, 0.01, 0.01);
  const int arc = stepsFor(1.0), down = stepsFor(0.5), hold = stepsFor(0.5);
  double deepest = 0.0;
  for (int i = 1; i <= arc + down + hold; ++i) {
    Eigen::Vector3d target;
    if (i <= arc) {
      const double phi = M_PI * i / arc;
      target = centre + 0.08 * Eigen::Vector3d(std::cos(phi), 0.0, std::sin(phi));
    } else {
      target = Eigen::Vector3d(0.03, 0.01, 0.01 - 0.04 * std::min(1.0, double(i - arc) / down));
    }
    s.moveDrag("end", target);
    world.step();
    deepest = std::max(deepest, deepestSelfOverlap(s, contact.selfExclusion));
  }
  return deepest;
}

}  // namespace

TEST(WorldScene, ABarFoldedOntoItselfDoesNotPassThroughWithSelfContact) {
  const double with = foldBar(true), without = foldBar(false);
  std::printf("folded bar: deepest self-overlap %.3g r with self-contact, %.3g r without\n", with, without);
  EXPECT_LT(with, 0.1) << "self-contact keeps the end out of the bar";
  EXPECT_GT(without, 1.0) << "without it the end passes through the bar";
}

// The contact pass keeps its list of candidate pairs while the particles stay near where it was
// built: a block resting apart for a second, then thrown fast at a resting stack, must still be
// met by the stack's particles (the list built again as it moves), not pass into them.
TEST(World, ABlockThrownFastAtARestingStackDoesNotPassIntoIt) {
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  auto a = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0));
  auto b = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0.03));
  auto c = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0.1, 0.0, 0.015));
  world.addObject("a", a, paramsFor(*a, 1.0, 2.0));
  const Solver& B = world.addObject("b", b, paramsFor(*b, 1.0, 2.0));
  SolverParams pc = paramsFor(*c, 1.0, 2.0);
  pc.gravity.setZero();  // c hangs beside the stack until thrown
  Solver& C = world.addObject("c", c, pc);
  for (int i = 0; i < stepsFor(1.0); ++i) world.step();
  ASSERT_LT(deepestOverlap(world), 0.1);
  const double b0 = centreOfMass(B).x();
  // 3 m/s towards the stack: 6 mm (1.2 r) per sub-step
  C.setVelocities(std::vector<Eigen::Vector3d>(c->size(), Eigen::Vector3d(-3.0, 0.0, 0.0)));
  double overlap = 0.0;
  for (int i = 0; i < stepsFor(0.3); ++i) {
    world.step();
    overlap = std::max(overlap, deepestOverlap(world));
  }
  const double pushed = b0 - centreOfMass(B).x();
  std::printf("block thrown at 3 m/s at a stack: deepest overlap %.3g r, the top block pushed %.3g m\n", overlap,
              pushed);
  EXPECT_TRUE(allFinite(world));
  EXPECT_LT(overlap, 0.1) << "the thrown block is met by the stack";
  EXPECT_GT(pushed, 0.01) << "it hit the stack";
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

// --- a pile at rest ---------------------------------------------------------------------------

// A pile at rest must stay at rest: a contact solve that leaves each sub-step's impulses short of
// convergence differently every time, or friction that flips between its static and kinetic
// bounds within the passes, shakes the pile forever (a few particles at centimetres per second
// in the node's bin scene), though it never explodes.

static void softBin(Integrator integrator) {
  const double dt = 1.0 / 60.0;
  const int substeps = integrator == Integrator::Implicit ? 1 : 11;
  World world(dt, substeps);
  double r = 1.0;
  const auto colliders = fillSoftBin(world, integrator, r);
  for (long i = 0; i < std::lround(10.0 / dt); ++i) world.step();
  // at rest: no particle moves a hundredth of its radius in a step (far below what an eye
  // sees on an object of a few cm, and the contacts' own tolerance of penetration) over 2 s.
  // Measured as the motion over each step, not the velocity at its end: a particle of a thin
  // corner (in four regions, alpha 1) may tremble from sub-step to sub-step where it stands.
  const double bound = 0.01 * r / dt;
  double fastest = 0.0;
  const std::size_t builds = world.contactListBuilds();
  std::vector<std::vector<Eigen::Vector3d>> before;
  for (const std::string& name : world.objectNames()) before.push_back(world.object(name)->positions());
  for (long i = 0; i < std::lround(2.0 / dt); ++i) {
    world.step();
    std::size_t o = 0;
    for (const std::string& name : world.objectNames()) {
      const auto& x = world.object(name)->positions();
      for (std::size_t k = 0; k < x.size(); ++k) fastest = std::max(fastest, (x[k] - before[o][k]).norm() / dt);
      before[o++] = x;
    }
  }
  const double overlap = deepestOverlap(world);
  // each pair's contacts are particle pairs that touch, each counted once: within 1.2 (r1 + r2),
  // for a contact that ends the passes pushing while its particles part (a light particle a
  // cube's corner, moved on by its other contacts after its own last update: one at 1.16 in the
  // implicit bin)
  std::size_t counted = 0, touching = 0, worst = 0;
  for (const ObjectPairWrench& w : world.objectWrenches()) {
    if (w.from > w.on) continue;  // each pair once
    const std::size_t near = pairsWithin(world, w.from, w.on, 1.2);
    counted += w.wrench.contacts;
    touching += near;
    if (w.wrench.contacts > near) worst = std::max(worst, w.wrench.contacts - near);
  }
  // and each collider's: particles within 1.1 r of its surface, each counted once
  std::size_t onColliders = 0, nearColliders = 0, worstCollider = 0;
  for (const auto& c : colliders) {
    std::size_t near = 0;
    for (const std::string& name : world.objectNames()) {
      const Solver& s = *world.object(name);
      Eigen::Vector3d normal;
      for (const Eigen::Vector3d& x : s.positions())
        near += colliderDistance(c.second.shape, c.second.pose, x, normal) < 1.1 * s.contactRadius() ? 1 : 0;
    }
    const std::size_t counted = world.contactWrench(c.first).contacts;
    onColliders += counted;
    nearColliders += near;
    if (counted > near) worstCollider = std::max(worstCollider, counted - near);
  }
  std::printf("bin of 20 soft objects (%s, %d sub-steps): from 10 to 12 s the most a particle moved in a step %.3g m/s (bound %.3g m/s), deepest "
              "overlap %.3g r, contact list built %zu times; %zu contacts between objects (%zu particle pairs within 1.2 (r1 + r2)), %zu "
              "with the box (%zu particles within 1.1 r)\n",
              integrator == Integrator::Implicit ? "implicit" : "explicit", substeps, fastest, bound, overlap,
              world.contactListBuilds() - builds, counted, touching, onColliders, nearColliders);
  EXPECT_TRUE(allFinite(world));
  EXPECT_LT(fastest, bound) << "the pile stays at rest";
  EXPECT_LT(overlap, 0.1) << "no two objects interpenetrate";
  EXPECT_GT(counted, 0u);
  EXPECT_EQ(worst, 0u) << "a pair counts more contacts than it has touching particle pairs";
  EXPECT_GT(onColliders, 0u);
  EXPECT_EQ(worstCollider, 0u) << "a collider counts more contacts than particles near it";
}

TEST(WorldScene, TwentySoftObjectsInABinGoToRestAndStayThere) { softBin(Integrator::Explicit); }

// The same at one implicit sub-step: the objects' systems and the springs between touching
// particles in one solve.
TEST(WorldScene, TwentySoftObjectsInABinGoToRestAndStayThereWithTheImplicitStep) { softBin(Integrator::Implicit); }

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
