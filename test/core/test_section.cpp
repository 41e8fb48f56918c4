/// @file test_section.cpp
/// Tests of core/section.h: the section thickness of bars, plates, boxes and balls of known size,
/// gaps that must not pass thickness on, the thin-fraction rule, and the region half-width chosen
/// from a section. (test_solver_material checks the chosen regions against the FEM oracle.)
#include "deformable_flsm/core/section.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>

namespace deformable_flsm {
namespace {

int minOf(const SectionThickness& s) { return *std::min_element(s.cells.begin(), s.cells.end()); }
int maxOf(const SectionThickness& s) { return *std::max_element(s.cells.begin(), s.cells.end()); }

// Every cell of an n x n bar, corners and ends included, reads n, for even n as for odd n.
TEST(SectionThickness, EveryCellOfABarReadsItsSection) {
  for (int n = 1; n <= 8; ++n) {
    const SectionThickness s = measureSectionThickness(test::makeBox(4 * n + 3, n, n, 0.01));
    EXPECT_EQ(minOf(s), n) << n << " cells across";
    EXPECT_EQ(maxOf(s), n) << n << " cells across";
    EXPECT_EQ(s.thinnest, n);
  }
  // a rectangular section reads its thinner side
  const SectionThickness flat = measureSectionThickness(test::makeBox(30, 6, 3, 0.01));
  EXPECT_EQ(minOf(flat), 3);
  EXPECT_EQ(maxOf(flat), 3);
}

TEST(SectionThickness, PlatesAndCubesReadTheirThickness) {
  for (int t : {1, 2, 3, 4, 5}) {
    const SectionThickness s = measureSectionThickness(test::makeBox(16, 16, t, 0.01));
    EXPECT_EQ(minOf(s), t);
    EXPECT_EQ(maxOf(s), t);
  }
  for (int n : {2, 5, 8}) {
    const SectionThickness s = measureSectionThickness(test::makeBox(n, n, n, 0.01));
    EXPECT_EQ(minOf(s), n);
    EXPECT_EQ(maxOf(s), n);
  }
  // beyond the widest region the reading stops: no choice of w depends on more
  const SectionThickness big = measureSectionThickness(test::makeBox(26, 26, 26, 0.01));
  EXPECT_EQ(minOf(big), kMaxSectionThickness);
  EXPECT_EQ(maxOf(big), kMaxSectionThickness);
}

// A voxelized ball: its surface cells (the lattice's staircase) belong to the ball, not to thin
// sections. Every cell reads the diameter d or d - 1: the voxel ball is narrower than d between
// its axes, where the staircase cuts in.
TEST(SectionThickness, ABallReadsItsDiameter) {
  for (int d : {8, 12, 16}) {
    const double r = 0.5 * d;
    const Voxelization v = test::makeVoxels(Eigen::Vector3i(d, d, d), 0.01, [&](int i, int j, int k) {
      const Eigen::Vector3d c(i + 0.5 - r, j + 0.5 - r, k + 0.5 - r);
      return c.norm() <= r;
    });
    const SectionThickness s = measureSectionThickness(v);
    EXPECT_GE(minOf(s), d - 1) << "diameter " << d;
    EXPECT_LE(maxOf(s), d) << "diameter " << d;
  }
}

// Thickness is not passed on across a gap: a 2-cell plate one empty cell away from a thick block
// reads 2 in every cell. Joined to the block, the plate's cells within reach of the block's regions
// read more, those further out 2.
TEST(SectionThickness, AGapKeepsAThinPlateThin) {
  for (bool gap : {true, false}) {
    // block x in [0, 10), plate x in [10 + gap, 26), z in [4, 6)
    const Voxelization v = test::makeVoxels(Eigen::Vector3i(26, 10, 10), 0.01, [&](int i, int, int k) {
      if (i < 10) return true;
      if (gap && i == 10) return false;
      return k >= 4 && k < 6;
    });
    const SectionThickness s = measureSectionThickness(v);
    int farPlate = 0, nearPlate = 0;
    for (std::size_t p = 0; p < v.cells.size(); ++p) {
      if (v.cells[p].x() < 10) {
        EXPECT_EQ(s.cells[p], 10);
        continue;
      }
      if (v.cells[p].x() >= 16) {
        EXPECT_EQ(s.cells[p], 2) << "far end of the plate, x " << v.cells[p].x();
        ++farPlate;
      } else if (gap) {
        EXPECT_EQ(s.cells[p], 2) << "plate beyond a gap, x " << v.cells[p].x();
      } else if (s.cells[p] > 2) {
        ++nearPlate;
      }
    }
    EXPECT_GT(farPlate, 0);
    if (!gap) {
      EXPECT_GT(nearPlate, 0) << "the plate's root lies in the block's regions";
    }
  }
}

// The thinnest section is the one under which at most 5 % of the particles lie: a thin fin of a
// few cells on a block does not decide, a thin part with a fair share of the particles does.
TEST(SectionThickness, AFewThinCellsDoNotDecide) {
  auto blockWithFin = [](int finLength) {
    // 12^3 block, fin of 1 x 1 x finLength cells on its top face
    return test::makeVoxels(Eigen::Vector3i(12, 12, 12 + finLength), 0.01, [](int i, int j, int k) {
      return k < 12 || (i == 6 && j == 6);
    });
  };
  const Voxelization small = blockWithFin(20);  // 20 of 1748 particles: 1.1 %
  EXPECT_EQ(measureSectionThickness(small).thinnest, 12);
  EXPECT_EQ(measureSectionThickness(small, 0.0).thinnest, 1) << "the thinnest cell itself";
  // a plate of 12 x 12 x 1 next to the block (separated by a gap): 144 of 1872 particles, 7.7 %
  const Voxelization withPlate = test::makeVoxels(Eigen::Vector3i(12, 12, 14), 0.01, [](int, int, int k) {
    return k < 12 || k == 13;
  });
  EXPECT_EQ(measureSectionThickness(withPlate).thinnest, 1);
  EXPECT_EQ(measureSectionThickness(withPlate, 0.0).thinnest, 1);
}

TEST(SectionThickness, RefusesWhatItCannotMeasure) {
  EXPECT_THROW(measureSectionThickness(Voxelization()), std::invalid_argument);
  // two cells far apart: a bounding box of 253^3 cells with padding, beyond kMaxSectionGridCells
  Voxelization sparse;
  sparse.spacing = 0.01;
  sparse.cells = {Eigen::Vector3i(0, 0, 0), Eigen::Vector3i(250, 250, 250)};
  sparse.fillFraction = {1.0, 1.0};
  try {
    measureSectionThickness(sparse);
    FAIL() << "no error";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("253 x 253 x 253"), std::string::npos) << e.what();
  }
  EXPECT_THROW(measureSectionThickness(test::makeBox(2, 2, 2, 0.01), 1.0), std::invalid_argument);
  EXPECT_THROW(measureSectionThickness(test::makeBox(2, 2, 2, 0.01), -0.1), std::invalid_argument);
}

// Regions 2w + 1 cells wide, no wider than the section; never more than asked, never below 1.
TEST(RegionForSection, TheWidestRegionThatFitsTheSection) {
  EXPECT_EQ(regionHalfWidthForSection(1, 3), 1);
  EXPECT_EQ(regionHalfWidthForSection(2, 3), 1);
  EXPECT_EQ(regionHalfWidthForSection(3, 3), 1);
  EXPECT_EQ(regionHalfWidthForSection(4, 3), 1);
  EXPECT_EQ(regionHalfWidthForSection(5, 3), 2);
  EXPECT_EQ(regionHalfWidthForSection(6, 3), 2);
  EXPECT_EQ(regionHalfWidthForSection(7, 3), 3);
  EXPECT_EQ(regionHalfWidthForSection(21, 3), 3);
  EXPECT_EQ(regionHalfWidthForSection(21, kMaxRegionHalfWidth), kMaxRegionHalfWidth);
  EXPECT_THROW(regionHalfWidthForSection(0, 3), std::invalid_argument);
  EXPECT_THROW(regionHalfWidthForSection(4, 0), std::invalid_argument);
  EXPECT_THROW(regionHalfWidthForSection(4, kMaxRegionHalfWidth + 1), std::invalid_argument);
}

// The estimate follows the measured cantilever table and grows with the region over the section.
TEST(RegionForSection, BendingStiffeningEstimateGrowsWithTheRegion) {
  EXPECT_NEAR(bendingStiffeningEstimate(1, 4), 0.96, 1e-12);
  EXPECT_NEAR(bendingStiffeningEstimate(3, 4), 1.40, 1e-12);
  EXPECT_NEAR(bendingStiffeningEstimate(2, 2), 1.61, 1e-12);
  EXPECT_NEAR(bendingStiffeningEstimate(5, 8), 0.5 * (1.12 + 1.40), 1e-12);
  double last = 0.0;
  for (int w = 1; w <= 10; ++w) {
    const double f = bendingStiffeningEstimate(w, 4);
    EXPECT_GE(f, last);
    last = f;
  }
  EXPECT_THROW(bendingStiffeningEstimate(0, 4), std::invalid_argument);
  EXPECT_THROW(bendingStiffeningEstimate(1, 0), std::invalid_argument);
}

}  // namespace
}  // namespace deformable_flsm
