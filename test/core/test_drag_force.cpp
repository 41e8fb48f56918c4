// The force and torque a drag exerts on the object (Drag::force, Drag::torque), with either
// integrator: a block hung by a drag comes to rest, where the drag carries its weight and the
// weight's moment about the drag's origin (statics: nothing else holds it), and a bonded punch
// pressed into a block by a hard drag against the FEM oracle's on the same voxels.
#include "deformable_flsm/core/solver.h"

#include "fixtures.h"
#include "support/fem_oracle.h"
#include "support/indentation.h"
#include "support/params.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <string>
#include <tuple>
#include <vector>

namespace deformable_flsm {
namespace {

constexpr double kSpacing = 0.01;  // m
constexpr double kGravity = 9.81;  // m/s^2

struct HangCase {
  Integrator integrator;
  ImplicitScheme scheme;
  double stiffness;  // 0: a hard drag
  const char* name;
};

class DragForce : public ::testing::TestWithParam<HangCase> {};

// A 6 x 6 x 6 block of 1 cm cells hung from a 3 x 3 patch of its top layer at a corner: the
// block's centre of mass is off the drag's origin, so the drag carries a moment as well.
TEST_P(DragForce, AHungBlockAtRestHangsOnItsDragWithItsWeightAndItsMoment) {
  const HangCase c = GetParam();
  auto lattice = std::make_shared<const Lattice>(test::makeBox(6, 6, 6, kSpacing), 1000.0, 1);
  const int substeps = c.integrator == Integrator::Explicit ? 32 : 2;
  SolverParams p = test::physicalParams(2e4, 0.3, 1, 1.0 / 60.0, substeps, c.integrator);
  p.gravity = Eigen::Vector3d(0, 0, -kGravity);
  p.ambientDamping = 20.0;
  p.implicitScheme = c.scheme;
  Solver s(lattice, p);
  std::vector<std::uint32_t> patch;
  for (std::uint32_t i = 0; i < lattice->size(); ++i) {
    const Eigen::Vector3i& cell = lattice->cells()[i];
    if (cell.z() == 5 && cell.x() < 3 && cell.y() < 3) patch.push_back(i);
  }
  ASSERT_EQ(patch.size(), 9u);
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  for (std::uint32_t i : patch) centroid += s.positions()[i];
  centroid /= 9.0;
  s.grab("hand", patch, centroid, c.stiffness);
  for (int i = 0; i < 240; ++i) s.step();
  ASSERT_LT(s.kineticEnergy(), 1e-12);

  const Drag& drag = s.drags().at("hand");
  double M = 0.0;
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < lattice->size(); ++i) {
    M += lattice->masses()[i];
    com += lattice->masses()[i] * s.positions()[i];
  }
  com /= M;
  const Eigen::Vector3d weight = M * p.gravity;
  // statics: the drag's force and moment balance the weight's
  EXPECT_LT((drag.force + weight).norm(), 1e-3 * weight.norm()) << drag.force.transpose();
  const Eigen::Vector3d moment = (com - drag.frame.translation()).cross(weight);
  ASSERT_GT(moment.norm(), 0.1 * weight.norm() * kSpacing);  // the case has a moment to carry
  EXPECT_LT((drag.torque + moment).norm(), 2e-3 * moment.norm())
      << drag.torque.transpose() << " against " << -moment.transpose();
}

INSTANTIATE_TEST_SUITE_P(
    Integrators, DragForce,
    ::testing::Values(HangCase{Integrator::Explicit, ImplicitScheme::BackwardEuler, 0.0, "ExplicitHard"},
                      HangCase{Integrator::Explicit, ImplicitScheme::BackwardEuler, 500.0, "ExplicitSpring"},
                      HangCase{Integrator::Implicit, ImplicitScheme::BackwardEuler, 0.0, "ImplicitHard"},
                      HangCase{Integrator::Implicit, ImplicitScheme::Bdf2, 0.0, "Bdf2Hard"},
                      HangCase{Integrator::Implicit, ImplicitScheme::BackwardEuler, 500.0, "ImplicitSpring"}),
    [](const ::testing::TestParamInfo<HangCase>& info) { return std::string(info.param.name); });

// A bonded flat punch (the top-layer particles under it held by a hard drag, lowered 1 mm) on a
// 13-cell cube held by its bottom layer, against the oracle's punch whose top nodes over the same
// 5 x 5 cells are moved 1 mm down and held sideways: the drag's force is the punch's, within the
// frictionless punch's bound, and the same static answer from both integrators.
TEST(DragForce, ABondedPunchPressesWithTheOraclesForce) {
  double force[2] = {0.0, 0.0};  // explicit, implicit (N)
  Voxelization vox = test::makeBox(13, 13, 13, 0.05 / 13);
  vox.origin = Eigen::Vector3d(-6.5 * vox.spacing, -6.5 * vox.spacing, 0.0);
  constexpr double depth = 1e-3, nu = 0.3;
  const indentation::Press defaults;  // the press's modulus and density
  const double oracle =
      indentation::femPunch(vox, 5, depth, FemMaterial{defaults.youngsModulus, nu, defaults.density}, true);
  for (const Integrator integrator : {Integrator::Explicit, Integrator::Implicit}) {
    indentation::Press how;
    how.integrator = integrator;
    how.substeps = integrator == Integrator::Explicit ? 120 : 4;
    how.w = 1;  // the node's default regions
    how.nu = nu;
    auto lattice = std::make_shared<const Lattice>(vox, how.density, how.w);
    Solver s(lattice, indentation::solverParams(how));
    indentation::holdBase(s, vox);
    std::vector<std::uint32_t> under;
    Eigen::Vector3d start = Eigen::Vector3d::Zero();
    for (std::uint32_t i = 0; i < lattice->size(); ++i) {
      const Eigen::Vector3i& cell = lattice->cells()[i];
      if (cell.z() == 12 && std::abs(cell.x() - 6) <= 2 && std::abs(cell.y() - 6) <= 2) {
        under.push_back(i);
        start += lattice->restPositions()[i] / 25.0;
      }
    }
    ASSERT_EQ(under.size(), 25u);
    s.grab("punch", under, start, 0.0);
    // lowered over how.pressSeconds, then held how.holdSeconds (as indentation::lower())
    const int press = static_cast<int>(std::lround(how.pressSeconds / how.timeStep));
    const int hold = static_cast<int>(std::lround(how.holdSeconds / how.timeStep));
    for (int i = 1; i <= press + hold; ++i) {
      s.moveDrag("punch", Eigen::Vector3d(start - Eigen::Vector3d(0, 0, depth * std::min(1.0, double(i) / press))));
      s.step();
    }
    force[integrator == Integrator::Implicit] = -s.drags().at("punch").force.z();
    std::printf("[ bonded  ] %s: %.4f N, oracle %.4f N (%+.1f %%)\n", toString(integrator),
                force[integrator == Integrator::Implicit], oracle,
                100 * (force[integrator == Integrator::Implicit] / oracle - 1));
    // the frictionless punch's bound (test_local_stiffness)
    EXPECT_NEAR(force[integrator == Integrator::Implicit] / oracle, 1.0, 0.12) << toString(integrator);
  }
  EXPECT_NEAR(force[0] / force[1], 1.0, 0.02) << "the two integrators' static answers";
}

}  // namespace
}  // namespace deformable_flsm
