#include "deformable_flsm/core/lattice.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <queue>
#include <random>
#include <set>

using deformable_flsm::Lattice;
using deformable_flsm::test::makeBox;
using deformable_flsm::test::makeVoxels;

TEST(Lattice, ParticlesMassesAndRestPositionsFollowTheVoxels) {
  auto vox = makeBox(3, 2, 2, 0.05);
  vox.fillFraction[0] = 0.25;
  const Lattice lattice(vox, 800.0, 1);
  ASSERT_EQ(lattice.size(), 12u);
  const double cellMass = 800.0 * 0.05 * 0.05 * 0.05;
  EXPECT_DOUBLE_EQ(lattice.masses()[0], 0.25 * cellMass);
  EXPECT_DOUBLE_EQ(lattice.masses()[1], cellMass);
  EXPECT_NEAR(lattice.totalMass(), 11.25 * cellMass, 1e-15);
  EXPECT_TRUE(lattice.restPositions()[0].isApprox(Eigen::Vector3d(0.025, 0.025, 0.025)));
  EXPECT_EQ(lattice.particleAt(Eigen::Vector3i(2, 1, 1)), 11);
  EXPECT_EQ(lattice.particleAt(Eigen::Vector3i(3, 0, 0)), Lattice::kNone);
  EXPECT_EQ(lattice.particleAt(Eigen::Vector3i(-1, 0, 0)), Lattice::kNone);
}

TEST(Lattice, TwoBoxesOneCellApartShareNoRegion) {
  // Two 4x4x4 boxes with an empty slab of one cell between them (like the bunny's ears).
  const auto vox = makeVoxels(Eigen::Vector3i(9, 4, 4), 0.01, [](int i, int, int) { return i != 4; });
  for (int w : {1, 2, 3, 4}) {
    const Lattice lattice(vox, 1000.0, w);
    std::vector<std::uint32_t> members;
    for (std::size_t r = 0; r < lattice.size(); ++r) {
      lattice.regionMembers(r, members);
      const bool left = lattice.cells()[r].x() < 4;
      for (std::uint32_t j : members)
        ASSERT_EQ(lattice.cells()[j].x() < 4, left) << "w=" << w << " region " << r << " bridges the gap";
    }
  }
}

TEST(Lattice, RegionMembersAreWithinWAndConnectedInsideTheCube) {
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<char> keep(10 * 10 * 10);
  for (auto& k : keep) k = u(rng) < 0.75;
  const auto vox = makeVoxels(Eigen::Vector3i(10, 10, 10), 0.01,
                              [&](int i, int j, int k) { return keep[(k * 10 + j) * 10 + i] != 0; });
  const int w = 2;
  const Lattice lattice(vox, 1000.0, w);
  std::vector<std::uint32_t> members;
  for (std::size_t r = 0; r < lattice.size(); ++r) {
    lattice.regionMembers(r, members);
    ASSERT_EQ(members.front(), r);
    const std::set<std::uint32_t> unique(members.begin(), members.end());
    ASSERT_EQ(unique.size(), members.size()) << "a member listed twice";
    // Reachability from r through links that stay inside the cube of half-width w.
    const Eigen::Vector3i c = lattice.cells()[r];
    std::set<std::uint32_t> reached{static_cast<std::uint32_t>(r)};
    std::queue<std::uint32_t> todo;
    todo.push(static_cast<std::uint32_t>(r));
    while (!todo.empty()) {
      const std::uint32_t p = todo.front();
      todo.pop();
      for (int axis = 0; axis < 3; ++axis)
        for (bool pos : {false, true}) {
          const std::int32_t q = lattice.neighbor(p, axis, pos);
          if (q == Lattice::kNone) continue;
          if ((lattice.cells()[q] - c).cwiseAbs().maxCoeff() > w) continue;
          if (reached.insert(static_cast<std::uint32_t>(q)).second) todo.push(static_cast<std::uint32_t>(q));
        }
    }
    for (std::uint32_t j : members) ASSERT_TRUE(reached.count(j)) << "member not connected to the centre";
  }
}

TEST(Lattice, RegionCountsAndMassFractionsConserveMass) {
  const auto vox = makeVoxels(Eigen::Vector3i(7, 6, 5), 0.02, [](int i, int j, int k) { return (i + j + k) % 7 != 3; });
  const Lattice lattice(vox, 1000.0, 2);
  // n_i counted from the explicit member lists equals the lattice's fast count.
  std::vector<int> counts(lattice.size(), 0);
  std::vector<std::uint32_t> members;
  for (std::size_t r = 0; r < lattice.size(); ++r) {
    lattice.regionMembers(r, members);
    for (auto j : members) ++counts[j];
  }
  double massInRegions = 0.0;
  for (std::size_t i = 0; i < lattice.size(); ++i) {
    EXPECT_EQ(counts[i], lattice.regionCounts()[i]);
    massInRegions += lattice.regionMassFractions()[i] * lattice.regionCounts()[i];
  }
  // Every particle's mass is shared out whole among the regions containing it.
  EXPECT_NEAR(massInRegions, lattice.totalMass(), 1e-12 * lattice.totalMass());
}

TEST(Lattice, RunsCoverEveryParticleOnceInOrder) {
  const auto vox = makeVoxels(Eigen::Vector3i(6, 5, 4), 0.01, [](int i, int j, int) { return i != 2 || j == 1; });
  const Lattice lattice(vox, 1000.0, 1);
  for (int axis = 0; axis < 3; ++axis) {
    auto order = lattice.runOrder(axis);
    const auto& starts = lattice.runStarts(axis);
    ASSERT_EQ(order.size(), lattice.size());
    for (std::size_t q = 0; q + 1 < starts.size(); ++q)
      for (auto e = starts[q] + 1; e < starts[q + 1]; ++e) {
        const Eigen::Vector3i d = lattice.cells()[order[e]] - lattice.cells()[order[e - 1]];
        Eigen::Vector3i unit = Eigen::Vector3i::Zero();
        unit[axis] = 1;
        ASSERT_EQ(d, unit) << "run is not a contiguous line along axis " << axis;
      }
    std::sort(order.begin(), order.end());
    ASSERT_TRUE(std::adjacent_find(order.begin(), order.end()) == order.end());
  }
}

TEST(Lattice, RejectsEmptyVoxelsAndBadArguments) {
  deformable_flsm::Voxelization empty;
  empty.spacing = 0.01;
  EXPECT_THROW(Lattice(empty, 1000.0, 1), std::invalid_argument);
  EXPECT_THROW(Lattice(makeBox(2, 2, 2, 0.01), 0.0, 1), std::invalid_argument);
  EXPECT_THROW(Lattice(makeBox(2, 2, 2, 0.01), 1000.0, 0), std::invalid_argument);
}
