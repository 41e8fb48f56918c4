// The solver (FastLSM shape matching): rest, rigid motions, momentum, recovery from a drag and
// from degenerate starts, parameter checks, the fast and naive summations and threads giving the
// same results, region weights, and steps that allocate nothing.
#include "deformable_flsm/core/solver.h"

#include "deformable_flsm/core/fast_summation.h"
#include "deformable_flsm/core/mesh.h"
#include "allocation_counter.h"
#include "fixtures.h"
#include "solver_fixtures.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <atomic>
#include <cstdlib>
#include <new>
#include <random>
#include <sstream>
#include <utility>

using deformable_flsm::Lattice;
using deformable_flsm::Solver;
using deformable_flsm::SolverKind;
using deformable_flsm::SolverParams;
using deformable_flsm::test::makeBox;
using namespace deformable_flsm::solver_fixtures;

namespace {

/// Scales against which momentum round-off is measured: sum m|v| and sum m|x||v|.
std::pair<double, double> momentumScales(const Solver& s) {
  double p = 0.0, l = 0.0;
  for (std::size_t i = 0; i < s.positions().size(); ++i) {
    p += s.lattice().masses()[i] * s.velocities()[i].norm();
    l += s.lattice().masses()[i] * s.positions()[i].norm() * s.velocities()[i].norm();
  }
  return {p, l};
}

}  // namespace

TEST(Solver, RestStaysAtRest) {
  Solver s(bar(), weightless());
  for (int i = 0; i < 200; ++i) s.step();
  // Only round-off moves anything: rotations converge to 1e-13 rad per sub-step, so 800
  // sub-steps may drift by ~1e-11 of the object size; a real force would move it by far more.
  EXPECT_LT(s.maxDisplacement(), 1e-10 * s.lattice().objectSize());
  EXPECT_LT(s.kineticEnergy(), 1e-20);
}

TEST(Solver, RigidlyMovedObjectHasGoalsEqualToPositions) {
  for (SolverKind kind : {SolverKind::Fast, SolverKind::Naive}) {
    SolverParams p = weightless();
    p.kind = kind;
    Solver s(bar(), p);
    const Eigen::Isometry3d T = someRigidMotion();
    std::vector<Eigen::Vector3d> x;
    for (const auto& x0 : s.lattice().restPositions()) x.push_back(T * x0);
    s.setPositions(x);
    std::vector<Eigen::Vector3d> g;
    s.computeGoals(g);
    double err = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) err = std::max(err, (g[i] - x[i]).norm());
    EXPECT_LT(err, 1e-12 * s.lattice().objectSize() * 10) << toString(kind);
    // and the rigid frame recovers T
    const Eigen::Isometry3d F = s.rigidFrame();
    // entry by entry: GCC 12 warns falsely inside Eigen's AVX-512 reductions of a 4x4 matrix
    double frameError = 0.0;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j) frameError = std::max(frameError, std::abs(F.matrix()(i, j) - T.matrix()(i, j)));
    EXPECT_LT(frameError, 1e-10);
  }
}

TEST(Solver, ConservesLinearAndAngularMomentum) {
  // No pins, gravity, forces or medium: shape matching and region damping exchange momentum only
  // inside the object. Start deformed and spinning so that every term is exercised.
  Solver s(bar(), isolated());
  std::mt19937 rng(9);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> x = s.positions(), v(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] += 0.003 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    v[i] = Eigen::Vector3d(0.1, 0.0, 0.2) + Eigen::Vector3d(0, 0, 3.0).cross(x[i]) +
           0.5 * Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  s.setPositions(x);
  s.setVelocities(v);
  const Eigen::Vector3d P0 = s.linearMomentum(), L0 = s.angularMomentum();
  const auto [pScale, lScale] = momentumScales(s);
  const double error0 = s.shapeError();
  for (int i = 0; i < 300; ++i) s.step();
  // Linear momentum: exact algebra; round-off of eps ~1e-16 in sums of ~100 terms accumulates
  // linearly, ~1e-14 of the momentum scale per sub-step at most, so 1e-11 over 1200.
  EXPECT_LT((s.linearMomentum() - P0).norm(), 1e-11 * pScale);
  // Angular momentum: exact when rotations are exact polar factors (R^T A symmetric); they
  // converge to 1e-13 rad.
  EXPECT_LT((s.angularMomentum() - L0).norm(), 1e-10 * lScale);
  // Damping removed the random deformation; what is left is the centrifugal stretch of the spin.
  EXPECT_LT(s.shapeError(), 0.1 * error0);
}

TEST(Solver, RecoversRestShapeAfterLargeDragIsReleased) {
  Solver s(bar(), weightless());
  const double size = s.lattice().objectSize();
  // grab the 4 particles nearest the tip and pull them 50% of the object size sideways
  // and hold the other end: the bar is bent by the drag, held until it settles, then let go
  const Eigen::Vector3d tip(0.12, 0.02, 0.02);
  const auto grabbed = s.nearestParticles(tip, 4);
  s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(0.016, 1.0, 1.0), true);
  s.grab("tip", grabbed, tip + Eigen::Vector3d(0.0, 0.5 * size, 0.0), 0.0);
  for (int i = 0; i < 300; ++i) s.step();
  const double bent = s.shapeError();
  EXPECT_GT(bent, 0.02 * size) << "the drag did not deform the bar";
  ASSERT_TRUE(s.release("tip"));
  s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(0.016, 1.0, 1.0), false);
  for (int i = 0; i < 600; ++i) s.step();
  EXPECT_TRUE(allFinite(s.positions()));
  // back to the rest shape to 0.1% of the object size (it was bent by > 2%)
  EXPECT_LT(s.shapeError(), 1e-3 * size);
}

// Stability where explicit methods blow up: a time step of 1/30 s, one sub-step, and starting
// states with no resemblance to the rest shape. No NaN, and back to the rest shape.
class Stability : public ::testing::TestWithParam<const char*> {};

TEST_P(Stability, RecoversFromDegenerateStartWithLargeStep) {
  SolverParams p = weightless();
  p.timeStep = 1.0 / 30.0;
  p.substeps = 1;
  Solver s(bar(), p);
  const std::string name = GetParam();
  const double size = s.lattice().objectSize();
  deformable_flsm::test::degenerateStart(s, name);
  for (int i = 0; i < 900; ++i) {
    s.step();
    ASSERT_TRUE(allFinite(s.positions())) << "NaN at step " << i;
  }
  EXPECT_LT(s.shapeError(), 1e-3 * size);
}

INSTANTIATE_TEST_SUITE_P(Starts, Stability, ::testing::Values("point", "plane", "scrambled", "stretched"));

TEST(SolverParams, ValidateNamesTheFieldAndRange) {
  auto message = [](const SolverParams& p) {
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  SolverParams p;
  EXPECT_EQ(message(p), "");
  p.stiffness = 1.5;
  EXPECT_NE(message(p).find("stiffness"), std::string::npos);
  p = SolverParams();
  p.regionHalfWidth = 0;
  EXPECT_NE(message(p).find("region_half_width"), std::string::npos);
  p = SolverParams();
  p.timeStep = std::nan("");
  EXPECT_NE(message(p).find("time_step"), std::string::npos);
  p = SolverParams();
  p.gravity.x() = INFINITY;
  EXPECT_NE(message(p).find("gravity"), std::string::npos);
  p = SolverParams();
  p.substeps = 0;
  EXPECT_NE(message(p).find("substeps"), std::string::npos);
  p = SolverParams();
  p.damping = -1;
  EXPECT_NE(message(p).find("damping"), std::string::npos);
  EXPECT_THROW(deformable_flsm::parseSolverKind("fastest"), std::invalid_argument);
  EXPECT_EQ(deformable_flsm::parseSolverKind("naive"), SolverKind::Naive);
  // a solver refuses a width that differs from its lattice's
  p = SolverParams();
  p.regionHalfWidth = 3;
  EXPECT_THROW(Solver(bar(2), p), std::invalid_argument);
}

// A region radius too large for the lattice names the largest radius that fits it.
TEST(SolverParams, RegionRadiusTooLargeNamesTheLargestThatFits) {
  EXPECT_EQ(deformable_flsm::regionHalfWidthForRadius(0.1, 0.01), 10);
  EXPECT_EQ(deformable_flsm::regionHalfWidthForRadius(0.004, 0.01), 1);
  std::string what;
  try {
    deformable_flsm::regionHalfWidthForRadius(0.2, 0.01);
  } catch (const std::invalid_argument& e) {
    what = e.what();
  }
  EXPECT_NE(what.find("region_radius"), std::string::npos) << what;
  EXPECT_NE(what.find("20 cells"), std::string::npos) << what;
  EXPECT_NE(what.find("at most 0.1 m"), std::string::npos) << what;
  EXPECT_NE(what.find("coarser lattice"), std::string::npos) << what;
}

// The fast (separable) and naive (explicit member lists) solvers compute the same sums in a
// different order: over 500 steps of a drag and release on the bunny lattice their positions
// agree to 1e-10 of the object size (round-off is ~1e-16 per sum; the dynamics is damped, so
// differences do not grow).
class FastVersusNaive : public ::testing::TestWithParam<int> {};

TEST_P(FastVersusNaive, AgreeOnBunnyOverDragAndRelease) {
  const std::string path = deformable_flsm::kBunnyMeshPath;
  ASSERT_TRUE(std::filesystem::exists(path)) << path << " missing: install glmark2-data (a test dependency)";
  const int w = GetParam();
  const auto mesh = deformable_flsm::loadMesh(path, 0.1);
  deformable_flsm::VoxelizeOptions opts;
  opts.resolution = 14;
  auto lattice = std::make_shared<const Lattice>(deformable_flsm::voxelize(mesh, opts), 1000.0, w);
  SolverParams p;
  p.regionHalfWidth = w;
  p.substeps = 1;
  p.kind = SolverKind::Fast;
  Solver fast(lattice, p);
  p.kind = SolverKind::Naive;
  Solver naive(lattice, p);
  const double size = lattice->objectSize();
  // grab near the top of the bunny and pull 30% of its size sideways, then let go
  const Eigen::Vector3d top = lattice->restMax();
  const auto grabbed = fast.nearestParticles(top, 3);
  for (Solver* s : {&fast, &naive}) {
    s->pinBox(lattice->restMin() - Eigen::Vector3d::Constant(1.0),
              Eigen::Vector3d(1.0, 1.0, lattice->restMin().z() + 0.5 * lattice->spacing()), true);
    s->grab("ear", grabbed, top + Eigen::Vector3d(0.3 * size, 0.0, 0.0), 0.0);
  }
  double worst = 0.0;
  for (int i = 0; i < 500; ++i) {
    if (i == 150) {
      fast.release("ear");
      naive.release("ear");
    }
    fast.step();
    naive.step();
    for (std::size_t j = 0; j < lattice->size(); ++j)
      worst = std::max(worst, (fast.positions()[j] - naive.positions()[j]).norm());
  }
  EXPECT_LT(worst, 1e-10 * size) << "w=" << w << ", " << lattice->size() << " particles";
  EXPECT_GT(fast.maxDisplacement(), 1e-3 * size) << "the drag should have moved the bunny";
  std::ostringstream ratio;
  ratio << std::scientific << worst / size;
  RecordProperty("max_difference_over_size", ratio.str());
}

INSTANTIATE_TEST_SUITE_P(W, FastVersusNaive, ::testing::Values(1, 2, 3));

// A plate whose slices (68 x 64 = 4352 particles) are wider than SliceStreamSummer::kBandParticles, so
// that the fast solver sweeps them in bands of rows: it must still agree with the naive solver,
// and two threads with one, bit for bit, through a drag (a corner pinned, the far corner pulled
// up).
TEST(Solver, BandsAgreeWithNaiveAndAcrossThreads) {
  auto lattice = std::make_shared<const Lattice>(makeBox(68, 64, 3, 0.01), 1000.0, 2);
  ASSERT_GE(deformable_flsm::SliceStreamSummer(*lattice).bandCount(), 2u);
  SolverParams p;
  p.regionHalfWidth = 2;
  p.substeps = 1;
  Solver fast(lattice, p);
  p.threads = 2;
  Solver two(lattice, p);
  p.threads = 1;
  p.kind = SolverKind::Naive;
  Solver naive(lattice, p);
  const double size = lattice->objectSize();
  const auto corner = fast.nearestParticles(lattice->restMax(), 4);
  for (Solver* s : {&fast, &two, &naive}) {
    s->pinBox(Eigen::Vector3d::Constant(-1.0), lattice->restMin() + Eigen::Vector3d(0.1, 0.1, 1.0), true);
    s->grab("corner", corner, lattice->restMax() + Eigen::Vector3d(0.0, 0.0, 0.2 * size), 0.0);
  }
  double worst = 0.0;
  for (int i = 0; i < 30; ++i) {
    for (Solver* s : {&fast, &two, &naive}) s->step();
    for (std::size_t j = 0; j < lattice->size(); ++j) {
      worst = std::max(worst, (fast.positions()[j] - naive.positions()[j]).norm());
      ASSERT_EQ(fast.positions()[j], two.positions()[j]) << "step " << i << ", particle " << j;
    }
  }
  EXPECT_LT(worst, 1e-10 * size);
  EXPECT_GT(fast.maxDisplacement(), 0.01 * size) << "the drag should have bent the plate";
}

TEST(PhysicalMaterial, RegionWeightsAreOneInsideAndRestoreClippedRegions) {
  SolverParams p = weightless();
  p.youngsModulus = 1e3;
  Solver s(std::make_shared<const Lattice>(makeBox(9, 9, 9, 0.01), 1000.0, 2), p);
  const auto& L = s.lattice();
  // interior region: full (2w+1)^3 cube, beta = 1 exactly (to round-off of the moment sums)
  EXPECT_NEAR(s.regionWeights()[L.particleAt(Eigen::Vector3i(4, 4, 4))], 1.0, 1e-9);
  // corner region: clipped to 3^3 cells, smaller along every axis, the largest too: beta > 1
  EXPECT_GT(s.regionWeights()[L.particleAt(Eigen::Vector3i(0, 0, 0))], 1.2);
  // classic mode keeps FastLSM's uniform regions
  Solver classic(std::make_shared<const Lattice>(makeBox(9, 9, 9, 0.01), 1000.0, 2), weightless());
  for (double beta : classic.regionWeights()) ASSERT_EQ(beta, 1.0);
}

TEST(PhysicalMaterial, ConservesMomentumWithRegionWeights) {
  SolverParams p = isolated();
  p.youngsModulus = 5e3;
  Solver s(bar(), p);
  std::mt19937 rng(17);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> x = s.positions(), v(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] += 0.002 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    v[i] = Eigen::Vector3d(0.0, 0.2, 0.0) + Eigen::Vector3d(2.0, 0.0, 0.0).cross(x[i]) +
           0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  s.setPositions(x);
  s.setVelocities(v);
  const auto [pScale, lScale] = momentumScales(s);
  const Eigen::Vector3d P0 = s.linearMomentum(), L0 = s.angularMomentum();
  for (int i = 0; i < 200; ++i) s.step();
  // same round-off bounds as in Solver.ConservesLinearAndAngularMomentum (800 sub-steps here)
  EXPECT_LT((s.linearMomentum() - P0).norm(), 1e-11 * pScale);
  EXPECT_LT((s.angularMomentum() - L0).norm(), 1e-10 * lScale);
}

// Threads split runs and regions, never a sum: results are bit-for-bit those of one thread.
TEST(Solver, ThreadsGiveIdenticalResults) {
  SolverParams p;
  p.youngsModulus = 5e3;
  Solver one(bar(), p);
  p.threads = 2;
  Solver two(bar(), p);
  for (Solver* s : {&one, &two}) s->grab("tip", {0, 1}, Eigen::Vector3d(-0.02, 0.03, 0.0), 0.0);
  for (int i = 0; i < 60; ++i) {
    one.step();
    two.step();
  }
  for (std::size_t i = 0; i < one.positions().size(); ++i) ASSERT_EQ(one.positions()[i], two.positions()[i]);
}

// A step allocates nothing once the solver is built and has stepped once (scratch buffers reach
// their size): drags, timed forces, pins, damping and both summers included.
// A lattice tall in z, so that every thread gets several blocks of slices, some processed before
// the threads meet and some after; pins, a hard drag, a spring drag, a force and an impulse all
// act, and the chunk boundaries move between steps (SliceStreamSummer balances busy times). Every
// position and velocity must be bit-identical to one thread's, whichever steps the threaded
// solver's governor gave to one thread (it tries one thread after 8 steps whatever the machine).
TEST(Solver, ThreadsGiveIdenticalResultsOnATallLattice) {
  for (int w : {1, 2, 3}) {
    for (int threads : {2, 3}) {
      auto lattice = std::make_shared<const Lattice>(makeBox(5, 4, 30, 0.01), 1000.0, w);
      SolverParams p;
      p.regionHalfWidth = w;
      p.gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
      Solver one(lattice, p);
      p.threads = threads;
      Solver many(lattice, p);
      for (Solver* s : {&one, &many}) {
        s->pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(1.0, 1.0, 0.011), true);
        s->grab("top", s->nearestParticles(Eigen::Vector3d(0.0, 0.0, 0.3), 4), Eigen::Vector3d(0.05, 0.0, 0.28), 0.0);
        s->grab("side", s->nearestParticles(Eigen::Vector3d(0.05, 0.04, 0.15), 3), Eigen::Vector3d(0.08, 0.06, 0.15),
                50.0);
        s->applyForce(s->nearestParticles(Eigen::Vector3d(0.0, 0.04, 0.2), 5), Eigen::Vector3d(0.0, 2.0, 0.0), 0.1);
        s->applyImpulse({7, 8}, Eigen::Vector3d(0.0, 0.0, 0.01));
      }
      for (int i = 0; i < 40; ++i) {
        one.step();
        many.step();
      }
      for (std::size_t i = 0; i < one.positions().size(); ++i) {
        ASSERT_EQ(one.positions()[i], many.positions()[i]) << "w " << w << ", threads " << threads << ", particle " << i;
        ASSERT_EQ(one.velocities()[i], many.velocities()[i]) << "w " << w << ", threads " << threads;
      }
      EXPECT_GT(one.maxDisplacement(), 0.01);  // the object did move
      ASSERT_NE(many.threadGovernor(), nullptr);
      EXPECT_GT(many.threadGovernor()->singleSteps(), 0u);
      EXPECT_GT(many.threadGovernor()->threadedSteps(), 0u);
      EXPECT_EQ(one.threadGovernor(), nullptr);
    }
  }
}

TEST(Solver, StepDoesNotAllocate) {
  // (two threads: the blocks left near the chunk edges are listed anew whenever the boundaries
  // move, within the capacity reserved at construction)
  for (auto [kind, threads] : {std::pair<SolverKind, int>{SolverKind::Fast, 1}, {SolverKind::Fast, 2}, {SolverKind::Naive, 1}}) {
    SolverParams p;
    p.kind = kind;
    p.threads = threads;
    p.youngsModulus = 5e3;
    Solver s(bar(), p);
    s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(0.016, 1.0, 1.0), true);
    s.grab("hard", {100}, Eigen::Vector3d(0.15, 0.0, 0.0), 0.0);
    s.grab("spring", {120}, Eigen::Vector3d(0.15, 0.05, 0.0), 20.0);
    s.applyForce({150, 151}, Eigen::Vector3d(0.0, 0.0, 1.0), 10.0);
    s.step();
    s.applyImpulse({152}, Eigen::Vector3d(0.0, 0.01, 0.0));
    const long before = gAllocations.load();
    for (int i = 0; i < 20; ++i) s.step();
    EXPECT_EQ(gAllocations.load() - before, 0) << toString(kind) << ", threads " << threads;
  }
}

TEST(Solver, StepWithCollidersDoesNotAllocate) {
  // The bar on the ground, a kinematic box pressing on it, a sphere, a capsule and a mesh box
  // touching it: every shape's contact path, the wrench sums and the kinematic poses.
  for (int threads : {1, 2}) {
    SolverParams p;
    p.threads = threads;
    Solver s(bar(), p);
    deformable_flsm::Collider ground;
    ground.pose.translation() = Eigen::Vector3d(0, 0, -0.001);
    s.setCollider("ground", ground);
    deformable_flsm::Collider press;
    press.shape.type = deformable_flsm::ColliderType::Box;
    press.shape.halfExtents = Eigen::Vector3d(0.02, 0.05, 0.01);
    press.pose.translation() = Eigen::Vector3d(0.06, 0.02, 0.05);
    press.linearVelocity = Eigen::Vector3d(0, 0, -0.05);
    press.angularVelocity = Eigen::Vector3d(0, 0, 0.5);
    s.setCollider("press", press);
    deformable_flsm::Collider ball;
    ball.shape.type = deformable_flsm::ColliderType::Sphere;
    ball.shape.radius = 0.01;
    ball.pose.translation() = Eigen::Vector3d(0.125, 0.02, 0.02);
    s.setCollider("ball", ball);
    deformable_flsm::Collider rod;
    rod.shape.type = deformable_flsm::ColliderType::Capsule;
    rod.shape.radius = 0.005;
    rod.shape.halfLength = 0.03;
    rod.pose.translation() = Eigen::Vector3d(-0.004, 0.02, 0.02);
    s.setCollider("rod", rod);
    deformable_flsm::Collider block;
    block.shape.type = deformable_flsm::ColliderType::Mesh;
    block.shape.mesh = std::make_shared<const deformable_flsm::TriMesh>(
        deformable_flsm::test::boxMesh(Eigen::Vector3d(0.02, -0.03, 0.0), Eigen::Vector3d(0.04, 0.002, 0.04)));
    s.setCollider("block", block);
    s.step();
    const long before = gAllocations.load();
    for (int i = 0; i < 20; ++i) s.step();
    EXPECT_EQ(gAllocations.load() - before, 0) << "threads " << threads;
    for (const char* id : {"ground", "press", "ball", "rod", "block"})
      EXPECT_GT(s.contactWrench(id).contacts, 0u) << id << " touches the bar";
  }
}
