#include "deformable_flsm/core/fast_summation.h"

#include "fixtures.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <cmath>
#include <memory>
#include <random>
#include <utility>
#include <vector>

using deformable_flsm::SliceStreamSummer;
using deformable_flsm::Lattice;
using deformable_flsm::NaiveSummer;
using deformable_flsm::test::makeVoxels;

namespace {

/// A ragged lattice with holes, overhangs and a separate island: every kind of run boundary.
/// `layers` cells along z; `emptyLayer` >= 0 empties that whole z-layer (two pieces, an empty
/// slice between them).
deformable_flsm::Voxelization raggedVoxels(unsigned seed, int layers = 9, int emptyLayer = -1) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  std::vector<char> keep(12 * 10 * static_cast<std::size_t>(layers));
  for (auto& k : keep) k = u(rng) < 0.7;
  return makeVoxels(Eigen::Vector3i(12, 10, layers), 0.01, [&](int i, int j, int k) {
    return k != emptyLayer && keep[(static_cast<std::size_t>(k) * 10 + j) * 12 + i] != 0;
  });
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
  SliceStreamSummer fast(lattice);
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
  SliceStreamSummer fast(lattice);
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

namespace {

/// A kernel whose three steps are recorded: particle data from a fixed random table, region
/// data a nonlinear function of the region's sums (so that a wrong or missing sum shows), the
/// particle results stored, every visit counted.
class RecordingKernel : public deformable_flsm::RegionKernel {
 public:
  RecordingKernel(std::size_t n, int Kg, int Ks, unsigned seed)
      : Kg_(Kg), Ks_(Ks), data_(randomData(n, Kg, seed)), result_(n * Ks, 0.0), visits_(3 * n, 0) {}
  int gatherChannels() const override { return Kg_; }
  int scatterChannels() const override { return Ks_; }
  void particleData(std::size_t begin, std::size_t end, double* out) override {
    for (std::size_t p = begin; p < end; ++p) {
      ++visits_[3 * p];
      for (int c = 0; c < Kg_; ++c) out[(p - begin) * Kg_ + c] = data_[p * Kg_ + c];
    }
  }
  void regionData(std::size_t begin, std::size_t end, const double* sums, double* out) override {
    for (std::size_t r = begin; r < end; ++r) {
      ++visits_[3 * r + 1];
      const double* s = sums + (r - begin) * Kg_;
      for (int c = 0; c < Ks_; ++c) out[(r - begin) * Ks_ + c] = std::sin(s[c % Kg_]) + 0.5 * s[(c + 1) % Kg_];
    }
  }
  void particleResult(std::size_t begin, std::size_t end, const double* sums) override {
    for (std::size_t p = begin; p < end; ++p) {
      ++visits_[3 * p + 2];
      for (int c = 0; c < Ks_; ++c) result_[p * Ks_ + c] = sums[(p - begin) * Ks_ + c];
    }
  }
  const std::vector<double>& result() const { return result_; }
  const std::vector<int>& visits() const { return visits_; }

 private:
  int Kg_, Ks_;
  std::vector<double> data_, result_;
  std::vector<int> visits_;
};

}  // namespace

// The streamed pass (slices, ring, z-window restarts, threads taking blocks and waiting for the
// regions of their neighbours) gives the naive summer's answer, visits every region and particle
// result once per pass, and gives bit-identical results for 1, 2 and 3 threads, also after the
// chunk boundaries have moved. The same with the slices swept in bands of rows (a band target
// far below the slices' ~85 particles forces bands of the minimum height, 2w rows, and a target
// of 60 taller ones).
TEST_P(SummationByWidth, StreamedPassEqualsNaiveAndIsThreadIndependent) {
  const int w = GetParam();
  const Lattice lattice(raggedVoxels(3, 14, 6), 1000.0, w);
  const std::size_t n = lattice.size();
  NaiveSummer naive(lattice);
  for (std::size_t band : {SliceStreamSummer::kBandParticles, std::size_t{60}, std::size_t{1}}) {
    const std::size_t bands = SliceStreamSummer(lattice, 1, band).bandCount();
    if (band == SliceStreamSummer::kBandParticles) {
      ASSERT_EQ(bands, 1u);
    } else {
      ASSERT_GE(bands, 2u) << "band target " << band;  // 10 rows: at least 2 bands for w <= 4
    }
    if (band == 1) {
      ASSERT_EQ(bands, static_cast<std::size_t>((10 + 2 * w - 1) / (2 * w)));
    }
    for (auto [Kg, Ks] : {std::pair<int, int>{24, 18}, {12, 12}, {3, 6}, {1, 1}}) {
      RecordingKernel reference(n, Kg, Ks, 5);
      naive.apply(reference);
      std::vector<double> single;
      for (int threads : {1, 2, 3}) {
        SliceStreamSummer fast(lattice, threads, band);
        RecordingKernel k(n, Kg, Ks, 5);
        for (int pass = 0; pass < 3; ++pass) fast.apply(k);  // boundaries move between passes
        // regions and results exactly once per pass; particle data once with one thread and one
        // band, and again for the w slices beyond a thread's own where its neighbour's begin and
        // the w rows beyond a band's own (the halos)
        for (std::size_t e = 0; e < 3 * n; ++e) {
          if (e % 3 == 0 && (threads > 1 || bands > 1))
            ASSERT_GE(k.visits()[e], 3) << "particle " << e / 3 << ", threads " << threads << ", bands " << bands;
          else
            ASSERT_EQ(k.visits()[e], 3) << "index " << e / 3 << ", step " << e % 3 << ", threads " << threads
                                        << ", bands " << bands;
        }
        for (std::size_t e = 0; e < k.result().size(); ++e)
          ASSERT_NEAR(k.result()[e], reference.result()[e], 1e-10)
              << "K " << Kg << "/" << Ks << ", threads " << threads << ", bands " << bands;
        if (threads == 1) {
          single = k.result();
        } else {
          for (std::size_t e = 0; e < single.size(); ++e)
            ASSERT_EQ(k.result()[e], single[e]) << "threads " << threads << ", bands " << bands;
        }
      }
    }
  }
}

namespace {

/// A kernel for the order of the threads' work: its particle data changes every pass (a region or
/// particle block run too early reads the last pass's values), its regions in one part of the
/// lattice are slow (so that one thread finishes its sweep long before the other), and it counts
/// breaches of RegionKernel's contract: a particle's data read after its result of the same pass.
class PassKernel : public deformable_flsm::RegionKernel {
 public:
  PassKernel(std::size_t n, unsigned seed, std::size_t slowFrom, std::size_t slowTo)
      : data_(randomData(n, 3, seed)), result_(n * 3, 0.0), resultsDone_(n), slowFrom_(slowFrom), slowTo_(slowTo) {}
  int gatherChannels() const override { return 3; }
  int scatterChannels() const override { return 3; }
  void beginPass(int pass) { pass_ = pass; }
  void particleData(std::size_t begin, std::size_t end, double* out) override {
    for (std::size_t p = begin; p < end; ++p) {
      if (resultsDone_[p].load() != pass_) ++breaches_;
      for (int c = 0; c < 3; ++c) out[(p - begin) * 3 + c] = data_[p * 3 + c] + 0.25 * pass_;
    }
  }
  void regionData(std::size_t begin, std::size_t end, const double* sums, double* out) override {
    for (std::size_t r = begin; r < end; ++r) {
      if (r >= slowFrom_ && r < slowTo_) {
        const auto until = std::chrono::steady_clock::now() + std::chrono::microseconds(3);
        while (std::chrono::steady_clock::now() < until) {
        }
      }
      const double* s = sums + (r - begin) * 3;
      for (int c = 0; c < 3; ++c) out[(r - begin) * 3 + c] = std::sin(s[c]) + 0.5 * s[(c + 1) % 3];
    }
  }
  void particleResult(std::size_t begin, std::size_t end, const double* sums) override {
    for (std::size_t p = begin; p < end; ++p) {
      for (int c = 0; c < 3; ++c) result_[p * 3 + c] = sums[(p - begin) * 3 + c];
      resultsDone_[p].fetch_add(1);
    }
  }
  const std::vector<double>& result() const { return result_; }
  int breaches() const { return breaches_.load(); }

 private:
  std::vector<double> data_, result_;
  std::vector<std::atomic<int>> resultsDone_;
  std::atomic<int> breaches_{0};
  int pass_ = 0;
  std::size_t slowFrom_, slowTo_;
};

}  // namespace

// With more than one thread, the particle blocks near the chunk edges go to whichever thread is
// free first: a block must wait for the regions it reads, in its own chunk and its neighbours',
// and for the neighbours' halo reads of its particles. The slow third of the lattice (bottom,
// middle or top) makes the other threads finish early and take those blocks; every pass must
// still equal one thread's, bit for bit, with and without bands, and no particle's data may be
// read after its result. A lattice of 3 slices leaves some of 3 threads' chunks without slices
// of their own (they still read their halo).
TEST_P(SummationByWidth, DeferredBlocksWaitForWhatTheyRead) {
  const int w = GetParam();
  for (int layers : {30, 3}) {
    const Lattice lattice(raggedVoxels(4, layers), 1000.0, w);
    const std::size_t n = lattice.size();
    for (std::size_t band : {SliceStreamSummer::kBandParticles, std::size_t{60}}) {
      for (int slow = 0; slow < 3; ++slow) {
        const std::size_t slowFrom = n * static_cast<std::size_t>(slow) / 3;
        const std::size_t slowTo = n * static_cast<std::size_t>(slow + 1) / 3;
        constexpr int kPasses = 4;
        std::vector<std::vector<double>> single;
        {
          SliceStreamSummer one(lattice, 1, band);
          PassKernel k(n, 9, n, n);
          for (int pass = 0; pass < kPasses; ++pass) {
            k.beginPass(pass);
            one.apply(k);
            single.push_back(k.result());
          }
        }
        for (int threads : {2, 3}) {
          SliceStreamSummer many(lattice, threads, band);
          PassKernel k(n, 9, slowFrom, slowTo);
          for (int pass = 0; pass < kPasses; ++pass) {
            k.beginPass(pass);
            many.apply(k);
            ASSERT_EQ(k.breaches(), 0) << "threads " << threads << ", slow third " << slow << ", pass " << pass;
            for (std::size_t e = 0; e < k.result().size(); ++e)
              ASSERT_EQ(k.result()[e], single[static_cast<std::size_t>(pass)][e])
                  << "threads " << threads << ", bands " << many.bandCount() << ", slow third " << slow << ", pass "
                  << pass << ", particle " << e / 3 << ", layers " << layers;
          }
        }
      }
    }
  }
}

INSTANTIATE_TEST_SUITE_P(W, SummationByWidth, ::testing::Values(1, 2, 3, 4));

// Summers sharing one set of slice buffers (the objects of a World) give, pass after pass and
// whichever swept last, exactly what each gives with buffers of its own: lattices of different
// sizes, widths, bands and thread counts, channel counts growing and shrinking between passes,
// so that a summer sweeps buffers another one has grown and left full of its own data.
TEST(Summation, SummersSharingTheirSliceBuffersGiveTheirOwnResults) {
  struct Case {
    int seed, layers, w, threads;
    std::size_t band;
  };
  const std::vector<Case> cases = {{3, 14, 1, 1, SliceStreamSummer::kBandParticles},
                                   {4, 30, 3, 2, SliceStreamSummer::kBandParticles},
                                   {5, 9, 2, 1, std::size_t{60}},
                                   {6, 5, 1, 3, std::size_t{1}}};
  std::vector<std::unique_ptr<Lattice>> lattices;
  std::vector<std::unique_ptr<SliceStreamSummer>> own, shared;
  auto scratch = std::make_shared<deformable_flsm::SliceStreamScratch>();
  for (const Case& c : cases) {
    lattices.push_back(std::make_unique<Lattice>(raggedVoxels(c.seed, c.layers), 1000.0, c.w));
    own.push_back(std::make_unique<SliceStreamSummer>(*lattices.back(), c.threads, c.band));
    shared.push_back(std::make_unique<SliceStreamSummer>(*lattices.back(), c.threads, c.band));
    shared.back()->shareScratch(scratch);
    ASSERT_EQ(shared.back()->scratch(), scratch);
    ASSERT_NE(own.back()->scratch(), scratch);
  }
  const std::vector<std::pair<int, int>> channels = {{3, 6}, {24, 18}, {1, 1}, {12, 12}, {6, 3}};
  for (std::size_t pass = 0; pass < 2 * channels.size(); ++pass) {
    const auto [Kg, Ks] = channels[pass % channels.size()];
    for (std::size_t i = 0; i < cases.size(); ++i) {
      // each object in turn, the order changing between passes
      const std::size_t o = (i + pass) % cases.size();
      const std::size_t n = lattices[o]->size();
      RecordingKernel mine(n, Kg, Ks, static_cast<unsigned>(pass + o)), theirs(n, Kg, Ks, static_cast<unsigned>(pass + o));
      own[o]->apply(mine);
      shared[o]->apply(theirs);
      for (std::size_t e = 0; e < mine.result().size(); ++e)
        ASSERT_EQ(theirs.result()[e], mine.result()[e])
            << "summer " << o << ", pass " << pass << ", K " << Kg << "/" << Ks << ", index " << e;
    }
  }
  EXPECT_THROW(shared[0]->shareScratch(nullptr), std::invalid_argument);
}

TEST(Summation, FullBoxRegionSizesAreClippedCubes) {
  // In a full 9^3 box with w = 2, the region of a corner particle has 3^3 members, of an interior
  // one 5^3: the gather of ones is the region size.
  const Lattice lattice(deformable_flsm::test::makeBox(9, 9, 9, 0.01), 1000.0, 2);
  SliceStreamSummer fast(lattice);
  std::vector<double> ones(lattice.size(), 1.0), counts;
  fast.gather(ones, 1, counts);
  EXPECT_DOUBLE_EQ(counts[lattice.particleAt(Eigen::Vector3i(0, 0, 0))], 27.0);
  EXPECT_DOUBLE_EQ(counts[lattice.particleAt(Eigen::Vector3i(4, 4, 4))], 125.0);
  EXPECT_DOUBLE_EQ(counts[lattice.particleAt(Eigen::Vector3i(1, 4, 8))], 4.0 * 5.0 * 3.0);
}

// Slices that fit in kBandParticles stay whole; wider ones go in as few bands as keep every
// band-slice (halo included) within kBandTarget, as even as that count allows. A full box of
// 100-particle rows, w = 2: 60 rows need 3 bands of at most 25 data rows (2,500 particles, the
// greedy first two), and 3 bands need no more than 23 (2,300): rows [0, 21), [21, 40), [40, 60)
// with data rows [0, 23), [19, 42), [38, 60).
TEST(Summation, BandsAreFewAndEven) {
  ASSERT_EQ(SliceStreamSummer::kBandParticles, 4096u);
  ASSERT_EQ(SliceStreamSummer::kBandTarget, 2560u);
  const Lattice whole(deformable_flsm::test::makeBox(100, 40, 3, 0.01), 1000.0, 2);
  const SliceStreamSummer unbanded(whole);
  EXPECT_EQ(unbanded.bandCount(), 1u);
  EXPECT_EQ(unbanded.widestBandSlice(), 4000u);
  const Lattice wide(deformable_flsm::test::makeBox(100, 60, 3, 0.01), 1000.0, 2);
  const SliceStreamSummer banded(wide);
  EXPECT_EQ(banded.bandCount(), 3u);
  EXPECT_EQ(banded.widestBandSlice(), 2300u);
  // a smaller bound given to the constructor wins over kBandTarget
  const SliceStreamSummer small(wide, 1, 1000);
  EXPECT_LE(small.widestBandSlice(), 1000u);
  EXPECT_GE(small.bandCount(), 6u);
}

TEST(Summation, RejectsUnsupportedChannelCount) {
  const Lattice lattice(deformable_flsm::test::makeBox(2, 2, 2, 0.01), 1000.0, 1);
  SliceStreamSummer fast(lattice);
  std::vector<double> in(lattice.size() * 5), out;
  EXPECT_THROW(fast.gather(in, 5, out), std::invalid_argument);
}
