#include "deformable_flsm/core/fast_summation.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <random>

using deformable_flsm::BarSummer;
using deformable_flsm::Lattice;
using deformable_flsm::NaiveSummer;
using deformable_flsm::test::makeVoxels;

namespace {

/// A ragged lattice with holes, overhangs and a separate island: every kind of run boundary.
deformable_flsm::Voxelization raggedVoxels(unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<char> keep(12 * 10 * 9);
  for (auto& k : keep) k = u(rng) < 0.7;
  return makeVoxels(Eigen::Vector3i(12, 10, 9), 0.01,
                    [&](int i, int j, int k) { return keep[(k * 10 + j) * 12 + i] != 0; });
}

std::vector<double> randomData(std::size_t n, int K, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<double> d(n * K);
  for (auto& x : d) x = u(rng);
  return d;
}

}  // namespace

class SummationByWidth : public ::testing::TestWithParam<int> {};

// The separable bar sums equal the direct sums over the explicit member lists, for gather and
// scatter alike; inputs are O(1) and regions hold at most 729 members, so 1e-12 bounds round-off.
TEST_P(SummationByWidth, FastEqualsNaiveOnRaggedLattice) {
  const Lattice lattice(raggedVoxels(7), 1000.0, GetParam());
  BarSummer fast(lattice);
  NaiveSummer naive(lattice);
  for (int K : {1, 3, 6, 12, 24}) {
    const auto in = randomData(lattice.size(), K, 11 + K);
    std::vector<double> a, b;
    fast.gather(in, K, a);
    naive.gather(in, K, b);
    for (std::size_t e = 0; e < a.size(); ++e) ASSERT_NEAR(a[e], b[e], 1e-12) << "gather K=" << K;
    fast.scatter(in, K, a);
    naive.scatter(in, K, b);
    for (std::size_t e = 0; e < a.size(); ++e) ASSERT_NEAR(a[e], b[e], 1e-12) << "scatter K=" << K;
  }
}

// Scatter is the transpose of gather: <gather(f), h> = <f, scatter(h)>.
TEST_P(SummationByWidth, ScatterIsTransposeOfGather) {
  const Lattice lattice(raggedVoxels(5), 1000.0, GetParam());
  BarSummer fast(lattice);
  const auto f = randomData(lattice.size(), 1, 1);
  const auto h = randomData(lattice.size(), 1, 2);
  std::vector<double> gf, sh;
  fast.gather(f, 1, gf);
  fast.scatter(h, 1, sh);
  double lhs = 0.0, rhs = 0.0;
  for (std::size_t i = 0; i < f.size(); ++i) {
    lhs += gf[i] * h[i];
    rhs += f[i] * sh[i];
  }
  EXPECT_NEAR(lhs, rhs, 1e-9 * std::abs(lhs) + 1e-12);
}

INSTANTIATE_TEST_SUITE_P(W, SummationByWidth, ::testing::Values(1, 2, 3, 4));

TEST(Summation, FullBoxRegionSizesAreClippedCubes) {
  // In a full 9^3 box with w = 2, the region of a corner particle has 3^3 members, of an interior
  // one 5^3: the gather of ones is the region size.
  const Lattice lattice(deformable_flsm::test::makeBox(9, 9, 9, 0.01), 1000.0, 2);
  BarSummer fast(lattice);
  std::vector<double> ones(lattice.size(), 1.0), counts;
  fast.gather(ones, 1, counts);
  EXPECT_DOUBLE_EQ(counts[lattice.particleAt(Eigen::Vector3i(0, 0, 0))], 27.0);
  EXPECT_DOUBLE_EQ(counts[lattice.particleAt(Eigen::Vector3i(4, 4, 4))], 125.0);
  EXPECT_DOUBLE_EQ(counts[lattice.particleAt(Eigen::Vector3i(1, 4, 8))], 4.0 * 5.0 * 3.0);
}

TEST(Summation, RejectsUnsupportedChannelCount) {
  const Lattice lattice(deformable_flsm::test::makeBox(2, 2, 2, 0.01), 1000.0, 1);
  BarSummer fast(lattice);
  std::vector<double> in(lattice.size() * 5), out;
  EXPECT_THROW(fast.gather(in, 5, out), std::invalid_argument);
}
