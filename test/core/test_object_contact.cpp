// The object contact pass alone: the per-contact updates of its Gauss-Seidel passes
// (pairUpdate(), colliderUpdate()) against hand-computed cases, and its candidate list against
// brute force.
#include "deformable_flsm/core/object_contact.h"

#include "deformable_flsm/core/world.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <set>
#include <vector>

using namespace deformable_flsm;

namespace {

constexpr double kH = 1.0 / 480.0;  // a sub-step: 60 Hz in 8
constexpr double kR = 0.01;         // r1 + r2
const Eigen::Vector3d kUp = Eigen::Vector3d::UnitZ();

/// A pair contact along +z (from particle 2 to 1) that came from outside (target 0), prepared for kH.
ContactRow pairRow(double w1, double w2, double muS = 0.6, double muK = 0.5) {
  ContactRow c;
  c.n = kUp;
  c.offset = kR;
  c.target = 0.0;
  c.wsum = w1 + w2;
  c.muS = muS;
  c.muK = muK;
  c.prepare(kH);
  return c;
}

/// The relative velocity of the particles after the corrections.
Eigen::Vector3d relative(const ContactCorrection& u, const Eigen::Vector3d& v1, const Eigen::Vector3d& v2) {
  return (v1 + u.dv1) - (v2 + u.dv2);
}

Eigen::Vector3d tangential(const Eigen::Vector3d& v) { return v - v.dot(kUp) * kUp; }

}  // namespace

// Two particles overlapping by d: the end positions move apart along the normal by d in all,
// split by inverse mass; the impulses are equal and opposite (momentum is conserved).
TEST(ContactUpdate, AnOverlapIsRemovedAlongTheNormalSplitByInverseMass) {
  const double d = 0.002;
  for (const auto& masses : {std::pair<double, double>(1.0, 1.0), std::pair<double, double>(1.0, 3.0)}) {
    const double m1 = masses.first, m2 = masses.second, w1 = 1.0 / m1, w2 = 1.0 / m2;
    const ContactRow c = pairRow(w1, w2);
    const Eigen::Vector3d x1(0.0, 0.0, kR - d), x2 = Eigen::Vector3d::Zero(), v = Eigen::Vector3d::Zero();
    const ContactCorrection u = pairUpdate(c, x1, v, w1, x2, v, w2);
    ASSERT_TRUE(u.applies);
    EXPECT_NEAR(u.lambda, d / (kH * (w1 + w2)), 1e-12);
    EXPECT_TRUE(u.friction.isZero(0.0));
    // end positions move by h dv: particle 1 up by w1 / (w1 + w2) of d, particle 2 down by the rest
    EXPECT_NEAR((kH * u.dv1 - w1 / (w1 + w2) * d * kUp).norm(), 0.0, 1e-15);
    EXPECT_NEAR((kH * u.dv2 + w2 / (w1 + w2) * d * kUp).norm(), 0.0, 1e-15);
    EXPECT_NEAR((m1 * u.dv1 + m2 * u.dv2).norm(), 0.0, 1e-12) << "momentum is conserved";
    EXPECT_NEAR((u.impulse - u.lambda * kUp).norm(), 0.0, 1e-12);
    // the gap at the end of the sub-step is closed
    EXPECT_NEAR(kUp.dot((x1 + kH * u.dv1) - (x2 + kH * u.dv2)) - kR, 0.0, 1e-15);
  }
}

// A particle held still (w = 0) takes no correction: the other moves by the whole overlap.
TEST(ContactUpdate, AParticleHeldStillTakesNoCorrection) {
  const double d = 0.001;
  const ContactRow c = pairRow(2.0, 0.0);
  const Eigen::Vector3d v = Eigen::Vector3d::Zero();
  const ContactCorrection u = pairUpdate(c, Eigen::Vector3d(0.0, 0.0, kR - d), v, 2.0, Eigen::Vector3d::Zero(), v, 0.0);
  ASSERT_TRUE(u.applies);
  EXPECT_TRUE(u.dv2.isZero(0.0));
  EXPECT_NEAR((kH * u.dv1 - d * kUp).norm(), 0.0, 1e-15);
}

// Apart with nothing accumulated: no correction. Apart with a normal impulse from an earlier pass:
// it is taken back (to zero, never pulling).
TEST(ContactUpdate, ParticlesApartGetNoCorrectionAndAnEarlierPushIsTakenBack) {
  ContactRow c = pairRow(1.0, 1.0);
  const Eigen::Vector3d v = Eigen::Vector3d::Zero(), x2 = Eigen::Vector3d::Zero();
  const Eigen::Vector3d x1(0.0, 0.0, kR + 0.001);
  const ContactCorrection none = pairUpdate(c, x1, v, 1.0, x2, v, 1.0);
  EXPECT_FALSE(none.applies);
  EXPECT_EQ(none.lambda, 0.0);
  EXPECT_TRUE(none.dv1.isZero(0.0) && none.dv2.isZero(0.0));

  c.lambda = 0.1;  // far less than the gap asks back
  const ContactCorrection back = pairUpdate(c, x1, v, 1.0, x2, v, 1.0);
  ASSERT_TRUE(back.applies);
  EXPECT_EQ(back.lambda, 0.0);
  EXPECT_NEAR((back.impulse + 0.1 * kUp).norm(), 0.0, 1e-15);
  EXPECT_NEAR((back.dv1 + 0.1 * kUp).norm(), 0.0, 1e-15);
  EXPECT_NEAR((back.dv2 - 0.1 * kUp).norm(), 0.0, 1e-15);
}

// Friction: a tangential relative motion within the static cone is stopped; beyond it the
// friction is mu_s lambda (sticking regime) or mu_k lambda (sliding), against the motion.
TEST(ContactUpdate, FrictionStopsSlowTangentialMotionAndBoundsFastMotionByTheCone) {
  const double d = 0.001, w = 1.0;
  const Eigen::Vector3d x1(0.0, 0.0, kR - d), x2 = Eigen::Vector3d::Zero();
  const double lambda = d / (kH * 2.0 * w);  // the normal impulse that closes the overlap
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  {
    const ContactRow c = pairRow(w, w, 0.6, 0.5);
    const Eigen::Vector3d slow(0.3 * lambda * 2.0 * w, 0.0, 0.0);  // |f| = 0.3 lambda < mu_s lambda
    const ContactCorrection u = pairUpdate(c, x1, slow, w, x2, zero, w);
    EXPECT_NEAR(u.lambda, lambda, 1e-12);
    EXPECT_NEAR(tangential(relative(u, slow, zero)).norm(), 0.0, 1e-12) << "static friction stops it";
    EXPECT_NEAR((u.dv1 + u.dv2).norm(), 0.0, 1e-12) << "equal masses: equal and opposite";
  }
  const Eigen::Vector3d fast(2.0 * lambda * 2.0 * w, 1.0 * lambda * 2.0 * w, 0.0);  // |f| > mu lambda
  const Eigen::Vector3d direction = tangential(fast).normalized();
  for (bool sliding : {false, true}) {
    ContactRow c = pairRow(w, w, 0.6, 0.5);
    c.sliding = sliding;
    const double mu = sliding ? 0.5 : 0.6;
    const ContactCorrection u = pairUpdate(c, x1, fast, w, x2, zero, w);
    EXPECT_NEAR((u.friction + mu * lambda * direction).norm(), 0.0, 1e-12) << "the cone's bound, against the motion";
    // the relative tangential velocity is reduced by (w1 + w2) mu lambda
    const Eigen::Vector3d after = tangential(relative(u, fast, zero));
    EXPECT_NEAR((after - (tangential(fast) - 2.0 * w * mu * lambda * direction)).norm(), 0.0, 1e-12);
    EXPECT_NEAR((u.dv1 + u.dv2).norm(), 0.0, 1e-12) << "equal masses: equal and opposite";
  }
}

// The implicit step's spring impulse bounds friction as the normal impulse does: with no
// overlap to remove, tangential motion is still held, up to mu_s times the spring's impulse.
TEST(ContactUpdate, ASpringsImpulseBoundsTheFriction) {
  const double w = 1.0, spring = 0.05;
  ContactRow c = pairRow(w, w, 0.6, 0.5);
  c.spring = contact_update::springBound(spring);
  const Eigen::Vector3d x1(0.0, 0.0, kR), x2 = Eigen::Vector3d::Zero(), zero = Eigen::Vector3d::Zero();
  const Eigen::Vector3d fast(1.0, 0.0, 0.0);  // |f| = 0.5 N s > 0.6 spring
  const ContactCorrection u = pairUpdate(c, x1, fast, w, x2, zero, w);
  ASSERT_TRUE(u.applies);
  EXPECT_EQ(u.lambda, 0.0);
  EXPECT_NEAR((u.friction + 0.6 * spring * Eigen::Vector3d::UnitX()).norm(), 0.0, 1e-15);
  c.spring = contact_update::springBound(-spring);
  EXPECT_EQ(c.spring, 0.0) << "a pulling spring bounds nothing";
  EXPECT_FALSE(pairUpdate(c, x1, fast, w, x2, zero, w).applies) << "without a pushing spring: no contact to hold";
}

// Against a collider: the particle takes the whole correction, and friction drags it toward
// the surface's velocity.
TEST(ContactUpdate, AColliderContactMovesTheParticleOnlyAndDragsItWithTheSurface) {
  const double d = 0.002, w = 0.5;
  ContactRow c;
  c.n = kUp;
  c.offset = 0.005;  // the gap is z - r
  c.wsum = w;
  c.muS = 1.0;
  c.muK = 1.0;
  c.prepare(kH);
  const Eigen::Vector3d x(0.0, 0.0, 0.005 - d), v = Eigen::Vector3d::Zero(), vc(0.01, 0.0, 0.0);
  const ContactCorrection u = colliderUpdate(c, x, v, w, vc);
  ASSERT_TRUE(u.applies);
  EXPECT_TRUE(u.dv2.isZero(0.0));
  EXPECT_NEAR(u.lambda, d / (kH * w), 1e-12);
  // within the cone: the tangential velocity becomes the surface's
  EXPECT_NEAR((tangential(v + u.dv1) - vc).norm(), 0.0, 1e-15);
  EXPECT_NEAR((kH * u.dv1).z(), d, 1e-15);
}

namespace {

constexpr double kStep = 1.0 / 60.0;
constexpr int kSubsteps = 8;

/// A full box of nx x ny x nz cells of `spacing` whose lower corner is `lo`.
std::shared_ptr<const Lattice> boxAt(int nx, int ny, int nz, double spacing, const Eigen::Vector3d& lo) {
  Voxelization v = test::makeBox(nx, ny, nz, spacing);
  v.origin = lo;
  return std::make_shared<const Lattice>(v, 1000.0, 1);
}

/// Classic FastLSM (alpha 0.3), 60 Hz in kSubsteps sub-steps.
SolverParams paramsFor(const Lattice& lattice) {
  SolverParams p;
  p.regionHalfWidth = lattice.regionHalfWidth();
  p.stiffness = 0.3;
  p.ambientDamping = 0.5;
  p.timeStep = kStep;
  p.substeps = kSubsteps;
  return p;
}

/// Brute force over every particle pair (of two objects, and of one object more than
/// selfExclusion cells apart when `self`): those within 1.25 (r1 + r2) at the end or the start of
/// the sub-step of length h are counted into nearPairs, and those of them missing from the
/// contact's candidate list into missing.
void countListed(const std::vector<Solver*>& objects, const std::vector<std::vector<Eigen::Vector3d>>& x,
                 const std::vector<std::vector<Eigen::Vector3d>>& v, double h, const ObjectContactSolver& contact,
                 bool self, int selfExclusion, std::size_t& nearPairs, std::size_t& missing) {
  const std::set<std::pair<std::uint32_t, std::uint32_t>> listed(contact.candidatePairs().begin(),
                                                                 contact.candidatePairs().end());
  std::uint32_t g1 = 0;
  for (std::size_t a = 0; a < objects.size(); ++a)
    for (std::size_t i = 0; i < x[a].size(); ++i, ++g1) {
      std::uint32_t g2 = 0;
      for (std::size_t b = 0; b < objects.size(); ++b)
        for (std::size_t j = 0; j < x[b].size(); ++j, ++g2) {
          if (g2 <= g1 || (a == b && !self)) continue;
          if (a == b) {
            const Eigen::Vector3i d = objects[a]->lattice().cells()[i] - objects[a]->lattice().cells()[j];
            if (d.cwiseAbs().maxCoeff() <= selfExclusion) continue;
          }
          const double reach = 1.25 * (objects[a]->contactRadius() + objects[b]->contactRadius());
          const bool atEnd = (x[a][i] - x[b][j]).norm() < reach;
          const bool atStart = ((x[a][i] - h * v[a][i]) - (x[b][j] - h * v[b][j])).norm() < reach;
          if (!atEnd && !atStart) continue;
          ++nearPairs;
          if (!listed.count({g1, g2})) ++missing;
        }
    }
}

}  // namespace

// The candidate list is built again for the objects whose particles left their allowances only:
// objects swinging into each other and others at rest beside them, moved by hand each sub-step
// (the pass's own corrections ignored: any motion must be caught), against every pair of
// particles closer than their reaches at the end or the start of the sub-step, by brute force.
TEST(ObjectContact, TheCandidateListHoldsEveryPairThatComesWithinReach) {
  const double h = kStep / kSubsteps;
  std::vector<std::unique_ptr<Solver>> solvers;
  std::vector<Solver*> objects;
  for (int o = 0; o < 8; ++o) {
    auto lattice = boxAt(3, 3, 3, 0.01, Eigen::Vector3d(0.035 * (o % 4), 0.035 * (o / 4), 0.0));
    solvers.push_back(std::make_unique<Solver>(lattice, paramsFor(*lattice)));
    objects.push_back(solvers.back().get());
  }
  ObjectContactParams params;
  params.selfContact = true;
  params.selfExclusion = 1;
  ObjectContactSolver contact;
  std::mt19937 rng(5);
  std::normal_distribution<double> jitter(0.0, 0.01);
  std::vector<std::vector<Eigen::Vector3d>> x, v;
  for (const Solver* s : objects) {
    x.push_back(s->positions());
    v.emplace_back(s->positions().size(), Eigen::Vector3d::Zero());
  }
  std::size_t nearPairs = 0, listed = 0, missing = 0, substeps = 0;
  for (int step = 0; step < 400; ++step, ++substeps) {
    const double t = step * h;
    for (std::size_t o = 0; o < objects.size(); ++o) {
      // the first row swings along x and y into its neighbours (0.3 m/s at most; the first
      // of it 3 m/s, more than its radius in a sub-step: its particles search wide); the second
      // rests, its particles trembling (1 cm/s)
      const double a = o == 0 ? 3.0 : 0.3, w = o == 0 ? 40.0 : 8.0;
      const Eigen::Vector3d V = o < 4 ? Eigen::Vector3d(a * std::sin(w * t + o), 0.3 * std::sin(5.0 * t), 0.0)
                                      : Eigen::Vector3d::Zero();
      for (std::size_t i = 0; i < x[o].size(); ++i) {
        v[o][i] = V + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
        x[o][i] += h * v[o][i];
      }
      objects[o]->setPositions(x[o]);
      objects[o]->setVelocities(v[o]);
    }
    contact.substep(objects, {}, params, h, true);
    listed += contact.candidatePairs().size();
    countListed(objects, x, v, h, contact, true, params.selfExclusion, nearPairs, missing);
  }
  std::printf("candidate list: %zu builds in %zu sub-steps, %zu pairs within reach, %zu listed, %zu missing\n",
              contact.listBuilds(), substeps, nearPairs, listed, missing);
  EXPECT_GT(nearPairs, 1000u) << "the objects come near each other";
  EXPECT_EQ(missing, 0u);
  EXPECT_LT(contact.listBuilds(), substeps) << "the list is kept over some sub-steps";
  // 8 x 27 particles: 23,220 pairs a sub-step; the list holds a small share
  EXPECT_LT(listed, substeps * 23220 / 5);
}

// A pile moving as one keeps its list: eight touching blocks carried together at 2.3 m/s, 4.8 mm
// a sub-step (more than five times a particle's allowance at rest), their particles trembling. The allowances are measured against each object's own motion and the
// objects' drift from each other, so the list is built once; every pair that comes within reach
// is listed all the same (brute force). Then one block slides along the others at 0.3 m/s: the
// list is built again as it drifts, and still misses nothing. (A pile that turns moves its
// particles within their objects and builds its list again: the allowances follow translation.)
TEST(ObjectContact, APileMovingAsOneKeepsItsListAndOneThatSlidesBuildsIt) {
  const double h = kStep / kSubsteps;
  std::vector<std::unique_ptr<Solver>> solvers;
  std::vector<Solver*> objects;
  for (int o = 0; o < 8; ++o) {
    // 3 x 3 x 3 cells of 1 cm, 0.2 mm apart: touching within the contact margin
    const Eigen::Vector3d lo(0.0302 * (o % 2), 0.0302 * ((o / 2) % 2), 0.0302 * (o / 4));
    auto lattice = boxAt(3, 3, 3, 0.01, lo);
    solvers.push_back(std::make_unique<Solver>(lattice, paramsFor(*lattice)));
    objects.push_back(solvers.back().get());
  }
  ObjectContactParams params;
  ObjectContactSolver contact;
  std::mt19937 rng(11);
  std::normal_distribution<double> jitter(0.0, 0.001);
  std::vector<std::vector<Eigen::Vector3d>> rest, x, v;
  for (const Solver* s : objects) {
    rest.push_back(s->positions());
    x.push_back(s->positions());
    v.emplace_back(s->positions().size(), Eigen::Vector3d::Zero());
  }
  const Eigen::Vector3d carry(2.0, 0.5, -1.0);
  auto run = [&](int from, int to, double slide, std::size_t& nearPairs, std::size_t& missing) {
    for (int step = from; step < to; ++step) {
      const double t = (step + 1) * h;
      // the pile where it is at t: carried, block 0 slid along x
      for (std::size_t o = 0; o < objects.size(); ++o) {
        const Eigen::Vector3d own = o == 0 ? Eigen::Vector3d(slide * (t - from * h), 0.0, 0.0) : Eigen::Vector3d::Zero();
        for (std::size_t i = 0; i < x[o].size(); ++i) {
          const Eigen::Vector3d target = carry * t + rest[o][i] + own;
          v[o][i] = (target - x[o][i]) / h + Eigen::Vector3d(jitter(rng), jitter(rng), jitter(rng));
          x[o][i] += h * v[o][i];
        }
        objects[o]->setPositions(x[o]);
        objects[o]->setVelocities(v[o]);
      }
      contact.substep(objects, {}, params, h, true);
      // every particle pair of two blocks within reach at the end or the start of the sub-step is listed
      countListed(objects, x, v, h, contact, false, 0, nearPairs, missing);
    }
  };
  std::size_t nearCarried = 0, missingCarried = 0, nearSliding = 0, missingSliding = 0;
  run(0, 400, 0.0, nearCarried, missingCarried);
  const std::size_t carriedBuilds = contact.listBuilds();
  run(400, 600, 0.3, nearSliding, missingSliding);
  const std::size_t slidingBuilds = contact.listBuilds() - carriedBuilds;
  std::printf("carried as one: %zu builds in 400 sub-steps (%.1f mm a sub-step), %zu pairs within reach, %zu missing; "
              "one block sliding: %zu builds in 200 sub-steps, %zu pairs within reach, %zu missing\n",
              carriedBuilds, 1e3 * carry.norm() * h, nearCarried, missingCarried, slidingBuilds, nearSliding,
              missingSliding);
  EXPECT_GT(nearCarried, 10000u) << "the blocks touch";
  EXPECT_EQ(missingCarried, 0u);
  EXPECT_EQ(carriedBuilds, 1u) << "a pile moving as one keeps its list";
  EXPECT_EQ(missingSliding, 0u);
  EXPECT_GT(slidingBuilds, 3u) << "a block sliding along the others has the list built again";
}

// Sleeping objects (setAsleep) cost the passes nothing among themselves, yet nothing is missed:
// two sleeping blocks overlapping each other are left as they are; a sleeping block woken beside one
// it overlaps is pushed out in the next sub-step, though nothing moved and the list was not
// built again; a sleeping block moved from outside (setPositions) into an awake one has its pairs
// listed and pushes the awake one out while it stays put.
TEST(ObjectContact, SleepingObjectsAreLeftAloneUntilMovedOrWoken) {
  const double h = kStep / kSubsteps;
  // A awake; B and C asleep, 2 mm into each other; D and E asleep, 2 mm into each other, far off
  const std::vector<Eigen::Vector3d> lo = {{0.0, 0.0, 0.0}, {0.0302, 0.0, 0.0}, {0.0582, 0.0, 0.0},
                                           {0.0, 0.2, 0.0}, {0.028, 0.2, 0.0}};
  std::vector<std::unique_ptr<Solver>> solvers;
  std::vector<Solver*> objects;
  for (const Eigen::Vector3d& l : lo) {
    auto lattice = boxAt(3, 3, 3, 0.01, l);
    solvers.push_back(std::make_unique<Solver>(lattice, paramsFor(*lattice)));
    objects.push_back(solvers.back().get());
  }
  std::vector<char> asleep = {0, 1, 1, 1, 1};
  ObjectContactParams params;
  ObjectContactSolver contact;
  contact.setAsleep(&asleep);
  auto positions = [&] {
    std::vector<std::vector<Eigen::Vector3d>> x;
    for (const Solver* s : objects) x.push_back(s->positions());
    return x;
  };
  auto listedAll = [&] {
    std::vector<std::vector<Eigen::Vector3d>> x = positions(), v;
    for (const Solver* s : objects) v.push_back(s->velocities());
    std::size_t nearPairs = 0, missing = 0;
    countListed(objects, x, v, h, contact, false, 0, nearPairs, missing);
    return missing == 0 && nearPairs > 0;
  };
  const auto start = positions();
  for (int s = 0; s < 20; ++s) contact.substep(objects, {}, params, h, true);
  for (std::size_t o = 1; o < objects.size(); ++o)
    EXPECT_EQ(positions()[o], start[o]) << "sleeping object " << o << " moved";
  EXPECT_TRUE(listedAll());

  // D woken: nothing moved, the list stays, and D is pushed out of E
  const std::size_t builds = contact.listBuilds();
  const std::vector<Eigen::Vector3d> d = objects[3]->positions(), e = objects[4]->positions();
  asleep[3] = 0;
  contact.substep(objects, {}, params, h, true);
  EXPECT_EQ(contact.listBuilds(), builds);
  auto most = [](const std::vector<Eigen::Vector3d>& x) {
    double m = x[0].x();
    for (const Eigen::Vector3d& p : x) m = std::max(m, p.x());
    return m;
  };
  EXPECT_LT(most(objects[3]->positions()), most(d) - 1e-5) << "D's +x face is pushed back out of E";
  EXPECT_EQ(positions()[4], e) << "E, asleep, stays put";

  // C, still asleep, set 2 mm into A's other side
  std::vector<Eigen::Vector3d> c = objects[2]->positions();
  for (Eigen::Vector3d& x : c) x.x() -= 0.0582 + 0.0282;
  objects[2]->setPositions(c);
  auto least = [](const std::vector<Eigen::Vector3d>& x) {
    double m = x[0].x();
    for (const Eigen::Vector3d& p : x) m = std::min(m, p.x());
    return m;
  };
  const double aLeft = least(objects[0]->positions());
  contact.substep(objects, {}, params, h, true);
  EXPECT_TRUE(listedAll()) << "the moved sleeping object's pairs are listed";
  EXPECT_GT(least(objects[0]->positions()), aLeft + 1e-5) << "A is pushed out of the sleeping block";
  EXPECT_EQ(positions()[2], c) << "the sleeping block stays put";
}
