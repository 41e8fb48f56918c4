// Several objects in one World: the same steps as a bare Solver for one object, momentum kept by
// the contact between objects, and scenes compared with statics: a stack whose contacts carry
// the weight above them, two objects squeezed by a collider, a bin of objects, a gripper lifting
// two stacked objects by friction, a bar folded onto itself; run-time changes and refusals.
#include "deformable_flsm/core/world.h"

#include "deformable_flsm/core/contact.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

constexpr double kG = 9.81;
constexpr double kStep = 1.0 / 60.0;
constexpr int kSubsteps = 8;

/// A full box of nx x ny x nz cells of `spacing` whose lower corner is `lo`.
std::shared_ptr<const Lattice> boxAt(int nx, int ny, int nz, double spacing, const Eigen::Vector3d& lo,
                                     int w = 1) {
  Voxelization v = test::makeBox(nx, ny, nz, spacing);
  v.origin = lo;
  return std::make_shared<const Lattice>(v, 1000.0, w);
}

/// Classic FastLSM with alpha = `alpha`, 60 Hz in kSubsteps sub-steps, ambient damping
/// `ambient` (1/s).
SolverParams paramsFor(const Lattice& lattice, double alpha = 0.3, double ambient = 0.5) {
  SolverParams p;
  p.regionHalfWidth = lattice.regionHalfWidth();
  p.stiffness = alpha;
  p.ambientDamping = ambient;
  p.timeStep = kStep;
  p.substeps = kSubsteps;
  return p;
}

Collider ground(double z = 0.0) {
  Collider g;
  g.pose.translation() = Eigen::Vector3d(0, 0, z);
  return g;
}

Collider box(const Eigen::Vector3d& centre, const Eigen::Vector3d& half, double mu = 0.6) {
  Collider c;
  c.shape.type = ColliderType::Box;
  c.shape.halfExtents = half;
  c.pose.translation() = centre;
  c.staticFriction = mu;
  c.kineticFriction = mu;
  return c;
}

int stepsFor(double seconds) { return static_cast<int>(std::lround(seconds / kStep)); }

double maxSpeed(const World& world) {
  double v = 0.0;
  for (const std::string& name : world.objectNames())
    for (const auto& vi : world.object(name)->velocities()) v = std::max(v, vi.norm());
  return v;
}

Eigen::Vector3d centreOfMass(const Solver& s) {
  const auto& m = s.lattice().masses();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < m.size(); ++i) c += m[i] * s.positions()[i];
  return c / s.lattice().totalMass();
}

/// The deepest overlap of two particle spheres of different objects, as a fraction of the
/// smaller radius (0 when none overlaps); brute force, the test's own oracle.
double deepestOverlap(const World& world) {
  double deepest = 0.0;
  const auto& names = world.objectNames();
  for (std::size_t a = 0; a < names.size(); ++a)
    for (std::size_t b = a + 1; b < names.size(); ++b) {
      const Solver& A = *world.object(names[a]);
      const Solver& B = *world.object(names[b]);
      const double R = A.contactRadius() + B.contactRadius();
      const double r = std::min(A.contactRadius(), B.contactRadius());
      for (const auto& x : A.positions())
        for (const auto& y : B.positions()) deepest = std::max(deepest, (R - (x - y).norm()) / r);
    }
  return deepest;
}

bool allFinite(const World& world) {
  for (const std::string& name : world.objectNames()) {
    const Solver& s = *world.object(name);
    for (std::size_t i = 0; i < s.positions().size(); ++i)
      if (!s.positions()[i].allFinite() || !s.velocities()[i].allFinite()) return false;
  }
  return true;
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
void throwTwoBlocks(World& world) {
  auto a = boxAt(4, 3, 3, 0.01, Eigen::Vector3d(-0.06, 0.0, 0.0));
  auto b = boxAt(3, 4, 3, 0.01, Eigen::Vector3d(0.02, 0.012, 0.008));
  SolverParams pa = paramsFor(*a), pb = paramsFor(*b);
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

TEST(World, FrictionlessCollisionConservesLinearAndAngularMomentum) {
  ObjectContactParams contact;
  contact.staticFriction = contact.kineticFriction = 0.0;
  World world(kStep, kSubsteps, contact);
  throwTwoBlocks(world);
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

// --- a stack ---------------------------------------------------------------------------------

TEST(WorldScene, AStackOfThreeCarriesTheWeightAboveEachContact) {
  World world(kStep, kSubsteps);
  world.setCollider("ground", ground(0.0));
  const double s = 0.01;
  // face to face: each block's bottom spheres touch the top spheres of the one below
  auto bottom = boxAt(6, 6, 2, s, Eigen::Vector3d(0, 0, 0));
  auto middle = boxAt(4, 4, 2, s, Eigen::Vector3d(0.01, 0.01, 0.02));
  auto top = boxAt(4, 2, 2, s, Eigen::Vector3d(0.01, 0.02, 0.04));
  // firm and well damped, so that the stack's slow vertical bounce settles within the test
  world.addObject("bottom", bottom, paramsFor(*bottom, 1.0, 2.0));
  world.addObject("middle", middle, paramsFor(*middle, 1.0, 2.0));
  world.addObject("top", top, paramsFor(*top, 1.0, 2.0));
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
  std::printf("stack: middle->top %.4f N (weight %.4f), bottom->middle %.4f N (weight above %.4f), "
              "ground %.4f N (all %.4f); deepest overlap %.3g r, max speed %.3g m/s\n",
              mt.force.z(), Wt, bm.force.z(), Wt + Wm, -g.force.z(), Wt + Wm + Wb, overlap, maxSpeed(world));
  EXPECT_NEAR(mt.force.z(), Wt, 0.02 * Wt);
  EXPECT_NEAR(bm.force.z(), Wt + Wm, 0.02 * (Wt + Wm));
  EXPECT_NEAR(-g.force.z(), Wt + Wm + Wb, 0.02 * (Wt + Wm + Wb));
  EXPECT_NEAR(world.objectWrench("top", "middle").force.z(), -mt.force.z(), 0.1 * Wt) << "equal and opposite";
  EXPECT_LT(overlap, 0.1) << "no two spheres of different objects overlap by a tenth of a radius";
  EXPECT_LT(maxSpeed(world), 1e-3) << "the stack is at rest";
}
