// The implicit coupling of several objects (ImplicitCoupling): its contact spring's functions
// against hand-computed cases, and a stack of three cubes in one solve against statics (each
// contact carries the weight above it).
#include "deformable_flsm/core/implicit_coupling.h"

#include "deformable_flsm/core/world.h"
#include "fixtures.h"
#include "support/world_scenes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <string>

using namespace deformable_flsm;
using namespace deformable_flsm::world_scenes;
namespace spring = deformable_flsm::coupling_spring;

// --- the spring's functions -------------------------------------------------------------------

// Two spheres of radii 3 and 2 mm, centres 5.5 mm apart along (2, 3, 6) / 7: the normal points from
// particle 2 to particle 1, the gap is the distance less (r1 + r2)(1 + skin).
TEST(CouplingSpring, GeometryIsTheCentresDirectionAndTheGapOutsideTheSkin) {
  const Eigen::Vector3d dir = Eigen::Vector3d(2.0, 3.0, 6.0) / 7.0;
  const Eigen::Vector3d x2(0.1, -0.2, 0.3), x1 = x2 + 0.0055 * dir;
  Eigen::Vector3d n;
  double gap = 0.0;
  ASSERT_TRUE(spring::geometry(x1, 0.003, x2, 0.002, n, gap));
  EXPECT_NEAR((n - dir).norm(), 0.0, 1e-15);
  EXPECT_NEAR(gap, 0.0055 - 0.005 * (1.0 + spring::kSkin), 1e-15);
  EXPECT_GT(gap, 0.0) << "0.5 mm beyond touching is outside the 0.25 mm skin";
  Eigen::Vector3d unchanged = Eigen::Vector3d::Constant(7.0);
  double gapUnchanged = 7.0;
  EXPECT_FALSE(spring::geometry(x2, 0.003, x2, 0.002, unchanged, gapUnchanged)) << "centres met: no normal";
  EXPECT_EQ(unchanged, Eigen::Vector3d::Constant(7.0));
  EXPECT_EQ(gapUnchanged, 7.0);
}

// h^2 k: kStiffness times the particles' diagonals in series, capped at kMassCap times their reduced
// mass; a particle whose velocity is prescribed leaves the other's own.
TEST(CouplingSpring, StiffnessIsTheDiagonalsInSeriesCappedByTheReducedMass) {
  // equal particles: diagonal 4 and mass 1 each, in series 2 and 0.5
  EXPECT_DOUBLE_EQ(spring::stiffness(4.0, 1.0, false, 4.0, 1.0, false), spring::kStiffness * 2.0);
  // unequal, either way round
  const double d = 2.0 * 6.0 / (2.0 + 6.0);
  EXPECT_DOUBLE_EQ(spring::stiffness(2.0, 1.0, false, 6.0, 3.0, false), spring::kStiffness * d);
  EXPECT_DOUBLE_EQ(spring::stiffness(6.0, 3.0, false, 2.0, 1.0, false), spring::kStiffness * d);
  // one end prescribed: the other's diagonal and mass alone
  EXPECT_DOUBLE_EQ(spring::stiffness(4.0, 1.0, true, 10.0, 2.0, false), spring::kStiffness * 10.0);
  EXPECT_DOUBLE_EQ(spring::stiffness(4.0, 1.0, false, 10.0, 2.0, true), spring::kStiffness * 4.0);
  // a stiff material (diagonals of thousands of masses): the reduced mass caps it
  EXPECT_DOUBLE_EQ(spring::stiffness(1e4, 1.0, false, 1e4, 1.0, false), spring::kMassCap * 0.5);
}

// One-sided: a spring pushes while the solution ends its sub-step within the skin; one that would
// pull lets go, one the solution carries within the skin joins, and a gap of exactly zero keeps
// what the spring was.
TEST(CouplingSpring, OneSidedActiveSet) {
  EXPECT_TRUE(spring::activeAfter(true, -1e-4));
  EXPECT_FALSE(spring::activeAfter(true, 1e-4)) << "it would pull: let go";
  EXPECT_TRUE(spring::activeAfter(false, -1e-4)) << "carried within the skin: joins";
  EXPECT_FALSE(spring::activeAfter(false, 1e-4));
  EXPECT_TRUE(spring::activeAfter(true, 0.0));
  EXPECT_FALSE(spring::activeAfter(false, 0.0));
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(spring::activeAfter(true, nan)) << "no change on a gap that is not a number";
  EXPECT_FALSE(spring::activeAfter(false, nan));
}

// The impulse is that of a linear spring k_phys = k / h^2 over the sub-step at the gap it ends at
// (backward Euler): h k_phys times the compression, pushing particle 1 along n.
TEST(CouplingSpring, ImpulseIsTheSpringForceAtTheEndOfTheSubstepTimesTheSubstep) {
  const double h = 1.0 / 60.0, kPhys = 2000.0;  // N/m
  const double k = h * h * kPhys;
  const Eigen::Vector3d n = Eigen::Vector3d(0.0, 0.6, 0.8);
  // 1 mm inside the skin at the start, closing at 3 cm/s along n: 1.5 mm at the end
  const double gap = -0.001;
  const Eigen::Vector3d dv = -0.03 * n + Eigen::Vector3d(0.0, 0.8, -0.6);  // a tangential part moves no gap
  const double end = spring::gapAfter(gap, n, dv, h);
  EXPECT_NEAR(end, -0.001 - 0.03 * h, 1e-15);
  EXPECT_NEAR(spring::impulse(k, end, h), h * kPhys * (0.001 + 0.03 * h), 1e-15);
  EXPECT_GT(spring::impulse(k, end, h), 0.0) << "compressed: pushes particle 1 away from 2";
  EXPECT_LT(spring::impulse(k, 0.0005, h), 0.0) << "stretched: pulls (the active set then lets go)";
}

// --- the joint solve -------------------------------------------------------------------------

// Three 8 cm cubes of a physical material (1.6 cm cells), one implicit sub-step of 1/60 s: each
// contact carries the weight above it within 2 %, the stack stands (no centre moves sideways by
// a tenth of a cell) and comes to rest, nothing interpenetrates, from a soft foam to a stiff
// plastic. With the contact between objects after each object's solve (a splitting), the 30 kPa
// stack crushed to half its height and toppled within 1.4 s (docs/method.md).
class SoftStack : public ::testing::TestWithParam<double> {};

TEST_P(SoftStack, StandsAndCarriesTheWeightAtOneImplicitSubstep) {
  const double E = GetParam();
  World world(kStep, 1);
  world.setCollider("ground", ground(0.0));
  const double s = 0.016;
  const char* names[3] = {"bottom", "middle", "top"};
  double weight[3];
  for (int k = 0; k < 3; ++k) {
    auto lattice = boxAt(5, 5, 5, s, Eigen::Vector3d(0, 0, 0.082 * k + 0.002));
    world.addObject(names[k], lattice, implicitCube(E));
    weight[k] = lattice->totalMass() * kG;
  }
  const int steps = stepsFor(3.0), last = stepsFor(1.0);
  double mt = 0.0, bm = 0.0, g = 0.0, overlap = 0.0, drift = 0.0;
  for (int i = 0; i < steps; ++i) {
    world.step();
    overlap = std::max(overlap, deepestOverlap(world));
    for (const char* name : names) {
      const Eigen::Vector3d c = centreOfMass(*world.object(name));
      drift = std::max(drift, (c.head<2>() - Eigen::Vector2d(0.04, 0.04)).norm());
    }
    if (i < steps - last) continue;
    mt += world.objectWrench("middle", "top").force.z() / last;
    bm += world.objectWrench("bottom", "middle").force.z() / last;
    g += -world.contactWrench("ground").force.z() / last;
  }
  const double Wt = weight[2], Wm = weight[1], Wb = weight[0];
  std::printf("soft stack, E = %g Pa, one implicit sub-step: middle->top %.4f N (weight %.4f), bottom->middle %.4f N "
              "(%.4f), ground %.4f N (%.4f); deepest overlap %.3g r, largest sideways drift %.3g m, max speed %.3g m/s, "
              "CG iterations in the last step %d\n",
              E, mt, Wt, bm, Wt + Wm, g, Wt + Wm + Wb, overlap, drift, maxSpeed(world),
              world.object("top")->lastImplicitSolve().iterations);
  EXPECT_NEAR(mt, Wt, 0.02 * Wt);
  EXPECT_NEAR(bm, Wt + Wm, 0.02 * (Wt + Wm));
  EXPECT_NEAR(g, Wt + Wm + Wb, 0.02 * (Wt + Wm + Wb));
  // the 5 x 5 faces rest flat on each other and on the ground: 25 particles (or pairs) push at each
  EXPECT_EQ(world.objectWrench("middle", "top").contacts, 25u);
  EXPECT_EQ(world.objectWrench("bottom", "middle").contacts, 25u);
  EXPECT_EQ(world.contactWrench("ground").contacts, 25u) << "the solve's contacts are counted";
  EXPECT_LT(drift, 0.1 * s) << "the stack stands";
  // and friction holds it in every sub-step, those that build the candidate list again too:
  // with the springs' impulses lost there the 30 kPa stack drifted 0.088 mm (0.0078 with them)
  EXPECT_LT(drift, 2e-5) << "no cube slides on another";
  EXPECT_LT(overlap, 0.1) << "no two spheres of different objects overlap by a tenth of a radius";
  EXPECT_LT(maxSpeed(world), 1e-3) << "the stack is at rest";
}

INSTANTIATE_TEST_SUITE_P(Moduli, SoftStack, ::testing::Values(30e3, 1e6, 10e6),
                         [](const ::testing::TestParamInfo<double>& info) {
                           return std::to_string(static_cast<long>(info.param / 1000)) + "kPa";
                         });

TEST(ImplicitCoupling, AnObjectSwitchedToTheExplicitStepShowsNoSystem) {
  // a coupled solve reads a member's system through these accessors: an object that now steps
  // explicitly has none, though its implicit step is kept for a switch back
  auto lattice = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0, 0, 0.001));
  Solver s(lattice, implicitCube(1e5));
  s.setCollider("ground", ground(0.0));
  s.step();
  ASSERT_EQ(s.implicitRhs().size(), s.positions().size());
  SolverParams p = s.params();
  p.integrator = Integrator::Explicit;
  p.substeps = kSubsteps;
  s.setParams(p);
  EXPECT_TRUE(s.implicitRhs().empty());
  EXPECT_TRUE(s.implicitConstraints().empty());
  EXPECT_TRUE(s.implicitInvDiagonal().empty());
  EXPECT_EQ(s.implicitFreeCount(), 0u);
  s.step();
  p.integrator = Integrator::Implicit;
  p.substeps = 1;
  s.setParams(p);
  s.step();
  EXPECT_EQ(s.implicitRhs().size(), s.positions().size()) << "switched back";
}
