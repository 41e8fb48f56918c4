/// @file test_resolution.cpp
/// Tests of core/resolution.h: the chosen lattice fits the budget and the next finer one does
/// not, on a box (exact counts), a sphere and the Stanford bunny.
#include "deformable_flsm/core/resolution.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <limits>
#include <utility>

namespace deformable_flsm {
namespace {

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;


std::size_t countAt(const TriMesh& mesh, int resolution) {
  VoxelizeOptions o;
  o.resolution = resolution;
  o.maxParticles = std::numeric_limits<std::size_t>::max();
  return voxelize(mesh, o).cells.size();
}

/// The defining property: the choice fits, one resolution finer does not.
void expectBoundary(const TriMesh& mesh, std::size_t budget) {
  const ResolutionChoice c = finestResolutionWithin(mesh, budget);
  EXPECT_LE(c.voxels.cells.size(), budget);
  EXPECT_EQ(c.voxels.cells.size(), countAt(mesh, c.resolution));
  EXPECT_GT(countAt(mesh, c.resolution + 1), budget) << "resolution " << c.resolution + 1
                                                      << " also fits " << budget;
}

TEST(FinestResolutionWithin, CubeCountsAreExactCubes) {
  // A cube voxelized at resolution r occupies exactly r^3 cells.
  const TriMesh cube = test::boxMesh(Eigen::Vector3d::Ones());
  for (const std::size_t budget : {1u, 7u, 8u, 26u, 27u, 999u, 1000u, 1001u, 4000u}) {
    const ResolutionChoice c = finestResolutionWithin(cube, budget);
    const std::size_t r = static_cast<std::size_t>(c.resolution);
    EXPECT_LE(r * r * r, budget) << budget;
    EXPECT_GT((r + 1) * (r + 1) * (r + 1), budget) << budget;
    EXPECT_EQ(c.voxels.cells.size(), r * r * r);
  }
}

TEST(FinestResolutionWithin, FlatBoxUsesItsLongestAxis) {
  // 4 x 2 x 1: resolution r gives r x r/2 x r/4 cells (r a multiple of 4).
  const TriMesh slab = test::boxMesh(Eigen::Vector3d(4.0, 2.0, 1.0));
  const ResolutionChoice c = finestResolutionWithin(slab, 8 * 4 * 2);
  EXPECT_EQ(c.resolution, 8);
  EXPECT_EQ(c.voxels.cells.size(), 64u);
  expectBoundary(slab, 500);
}

TEST(FinestResolutionWithin, FewVoxelizations) {
  // Calibration, prediction, one step to the boundary, sometimes one more: the node's start-up
  // cost is a handful of voxelizations, not a scan over resolutions.
  const ResolutionChoice c = finestResolutionWithin(test::boxMesh(Eigen::Vector3d::Ones()), 20000);
  EXPECT_EQ(c.resolution, 27);  // 27^3 = 19683 <= 20000 < 28^3
  EXPECT_LE(c.voxelizations, 5);
}

TEST(FinestResolutionWithin, MaxResolutionCapsTheChoice) {
  const ResolutionChoice c = finestResolutionWithin(test::boxMesh(Eigen::Vector3d::Ones()), 100000, 10);
  EXPECT_EQ(c.resolution, 10);
  EXPECT_EQ(c.voxels.cells.size(), 1000u);
}

TEST(FinestResolutionWithin, RefusesZeroBudgetAndBadCap) {
  const TriMesh cube = test::boxMesh(Eigen::Vector3d::Ones());
  EXPECT_THROW(finestResolutionWithin(cube, 0), VoxelizationError);
  EXPECT_THROW(finestResolutionWithin(cube, 10, 0), VoxelizationError);
  EXPECT_THROW(finestResolutionWithin(TriMesh(), 10), MeshError);
}

TEST(FinestResolutionWithin, Bunny) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const TriMesh bunny = loadMesh(kBunnyPath, 0.1);
  for (const std::size_t budget : {500u, 4000u}) {
    SCOPED_TRACE(budget);
    expectBoundary(bunny, budget);
  }
}

}  // namespace
}  // namespace deformable_flsm

namespace deformable_flsm {
namespace {

// A cube at resolution r has r^3 cells: the nearest count to a target is the nearer of the two
// cubes around it, and the voxels returned are that resolution's.
TEST(NearestResolution, CubePicksTheNearerCube) {
  const TriMesh cube = test::boxMesh(Eigen::Vector3d::Ones());
  const std::pair<std::size_t, int> cases[] = {{8, 2}, {9, 2}, {17, 2}, {18, 3}, {27, 3}, {600, 8}, {700, 9}, {1000, 10}};
  for (const auto& [target, expected] : cases) {
    const ResolutionChoice c = nearestResolution(cube, target);
    EXPECT_EQ(c.resolution, expected) << "target " << target;
    EXPECT_EQ(c.voxels.cells.size(), static_cast<std::size_t>(expected * expected * expected));
  }
  EXPECT_EQ(nearestResolution(cube, 100000, 10).resolution, 10);  // capped: 1000 cells
}

}  // namespace
}  // namespace deformable_flsm
