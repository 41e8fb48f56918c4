// Scenes of several objects in one World compared with statics: a stack whose contacts carry the
// weight above them, two objects squeezed by a collider, a bin of objects, a gripper lifting two
// objects side by side by friction, a bar folded onto itself, a block thrown at a stack, and a
// pile of soft objects that stays at rest.
#include "deformable_flsm/core/world.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/object_contact.h"
#include "fixtures.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <utility>
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
