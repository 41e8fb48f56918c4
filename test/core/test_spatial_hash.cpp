// The spatial hash against brute force: every point closer than a cell to a query point is
// visited, each once, whatever the buckets the cells share.
#include "deformable_flsm/core/spatial_hash.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <vector>

using namespace deformable_flsm;

namespace {

std::vector<Eigen::Vector3d> randomPoints(std::size_t n, double extent, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<Eigen::Vector3d> p(n);
  for (auto& x : p) x = Eigen::Vector3d(u(rng), u(rng), u(rng));
  return p;
}

}  // namespace

TEST(SpatialHash, FindsEveryPointWithinACellEachOnce) {
  // 2000 points in a cube of 20 cells a side: cells far apart share buckets (4096 of them)
  const double cell = 0.01;
  const auto points = randomPoints(2000, 0.1, 3);
  SpatialHash hash;
  hash.build(points, points.size(), cell);
  EXPECT_GE(hash.bucketCount(), 2 * points.size());
  std::vector<std::uint32_t> scratch;
  for (std::size_t i = 0; i < points.size(); i += 7) {
    std::vector<std::uint32_t> found, within;
    hash.forEachNear(points[i], [&](std::uint32_t j) { found.push_back(j); });
    hash.forEachWithin(points[i], 2.5 * cell, scratch, [&](std::uint32_t j) { within.push_back(j); });
    std::vector<std::uint32_t> sortedFound = found, sortedWithin = within;
    std::sort(sortedFound.begin(), sortedFound.end());
    std::sort(sortedWithin.begin(), sortedWithin.end());
    EXPECT_EQ(std::adjacent_find(sortedFound.begin(), sortedFound.end()), sortedFound.end()) << "each point once";
    EXPECT_EQ(std::adjacent_find(sortedWithin.begin(), sortedWithin.end()), sortedWithin.end()) << "each point once";
    for (std::size_t j = 0; j < points.size(); ++j) {
      const double d = (points[j] - points[i]).norm();
      if (d < cell) {
        EXPECT_TRUE(std::binary_search(sortedFound.begin(), sortedFound.end(), j)) << i << " misses " << j;
      }
      if (d < 2.5 * cell) {
        EXPECT_TRUE(std::binary_search(sortedWithin.begin(), sortedWithin.end(), j)) << i << " misses " << j;
      }
    }
  }
}

TEST(SpatialHash, RebuildsSmallerAndLargerAndRefusesABadCell) {
  const auto many = randomPoints(5000, 0.2, 4), few = randomPoints(10, 0.02, 5);
  SpatialHash hash;
  hash.build(many, many.size(), 0.01);
  hash.build(few, few.size(), 0.05);  // smaller after larger: only the new points are found
  std::size_t visited = 0;
  hash.forEachNear(few[0], [&](std::uint32_t j) {
    EXPECT_LT(j, few.size());
    ++visited;
  });
  EXPECT_EQ(visited, few.size()) << "all ten lie within a cell of each other";
  hash.build(few, 0, 0.05);
  hash.forEachNear(few[0], [&](std::uint32_t) { ADD_FAILURE() << "no points"; });
  EXPECT_THROW(hash.build(few, few.size(), 0.0), std::invalid_argument);
  EXPECT_THROW(hash.build(few, few.size() + 1, 0.05), std::invalid_argument);
}
