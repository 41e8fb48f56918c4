/// @file slice_stream_summer.h
/// FastLSM's region sums (Rivers & James 2007, sec. 4) streamed through the lattice one z-slice
/// at a time, in bands of rows, split over threads. Its parts: slice_layout.cpp (slices, rows,
/// bands), slice_stream_summer.cpp (the sweep), thread_schedule.cpp (chunks, deferred blocks,
/// rebalancing); the sliding windows are in sliding_window.h and window_sums.h.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/region_summer.h"

#include <atomic>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace deformable_flsm {

/// The slice buffers SliceStreamSummer::apply() sweeps through, one set per thread: a few
/// slices' worth, rewritten in every pass (nothing in them outlives an apply()). Summers that
/// never apply at once may share one set (SliceStreamSummer::shareScratch()): the objects of a
/// World, stepped one after another, then sweep the same buffers, which stay in cache, instead
/// of one set each; with many small objects those sets together outgrow the cache.
class SliceStreamScratch {
 public:
  struct alignas(64) Thread {
    std::vector<double> run, rowSum, ring, sumPrev, sumCur, zPrev, zCur, colSum, regionRing;
    // the z-window's sources of the current slice k: slice z's rows and first particle at
    // z - k + w + 1 (2w + 2 entries)
    std::vector<const double*> zRow;
    std::vector<std::uint32_t> zStart;
  };
  /// one set per thread, grown (never shrunk) by the summers that use them
  std::vector<Thread> threads;
};

/// FastLSM (Rivers & James 2007, sec. 4): sums along x-runs, then y-runs, then z-runs, each a
/// sliding window of half-width w over the run, O(1) per particle and channel whatever w.
/// Scatter applies the same windows in reverse order (z, y, x): the windows are symmetric, so
/// this is the transpose of gather.
///
/// apply() streams the lattice one z-slice at a time (the particles are sorted by (k, j, i), so a
/// slice is a contiguous index range holding whole x- and y-runs): a slice's data is generated x-run
/// by x-run and summed along x, then along y, into a ring of 2w + 2 planes for the sliding
/// z-window, and each region slice is computed as soon as its z-window is complete; the scatter
/// follows w slices behind, its region data in a second ring, its x-sums handed to the kernel
/// run by run. The working set is a few slices, not a few copies of the whole lattice.
///
/// Slices wider than kBandParticles are swept in bands of rows (y), one band after the other, so
/// that the rings (2w + 2 planes of a slice each) stay in cache whatever the lattice's
/// cross-section: as few bands as keep every band-slice within kBandTarget particles, halo
/// included, as even as that allows (even bands leave no thin last band). Slices that fit stay
/// whole: a band's halo is recomputed, so bands much smaller than a slice cost more in halo than
/// they save (their cost: docs/performance.md). A band computes the regions of its rows [y0, y1)
/// from the data of rows [y0 - w, y1 + w) (the halo, generated twice), and the particle results of
/// rows [y0 - w, y1 - w), which need the regions of rows [y0 - 2w, y1): the band below leaves its
/// top 2w region rows in a boundary store. Regions and particle results are computed once; only the
/// halo's data and the boundary rows' z-windows are redone (2w of every band's rows; bands are at
/// least 2w rows high).
///
/// The z-windows restart (a direct sum over the window) every kBlock slices, and threads take
/// whole blocks: every sum is the same sequence of additions for any thread count, and the
/// blocks can move between threads (they do, towards equal busy times) without changing a bit.
/// The bands depend on the lattice only, never on the thread count. Each thread sweeps a chunk
/// of slices; the particle blocks near a chunk's inner edges (whose windows reach the next
/// chunk's regions, and kSpareBlocks more) are left to whichever thread is free first, each as
/// soon as the chunks it depends on have published the regions it reads. A thread that
/// finishes its sweep early takes over its neighbour's blocks instead of waiting at a barrier.
class SliceStreamSummer : public RegionSummer {
 public:
  /// Slices per block: z-windows restart at block starts, threads split the lattice at them.
  static constexpr int kBlock = 2;
  /// Slices with more particles than this are swept in bands (see above).
  static constexpr std::size_t kBandParticles = 4096;
  /// Largest band-slice the bands then aim for (particles in a band's rows of one slice, halo
  /// included).
  static constexpr std::size_t kBandTarget = 2560;
  /// Blocks beyond the necessary that each inner chunk edge leaves to whichever thread is free
  /// first (threads > 1), so that one that finishes its sweep early takes work over from its
  /// neighbour instead of waiting for it.
  static constexpr int kSpareBlocks = 1;
  /// @param[in] threads  OpenMP threads (>= 1); results are identical for any count
  /// @param[in] bandParticles  slices with more particles are swept in bands of rows of at most
  ///                           min(bandParticles, kBandTarget) (see above)
  /// @throws std::invalid_argument if the lattice's particles are not sorted by (k, j, i)
  explicit SliceStreamSummer(const Lattice& lattice, int threads = 1, std::size_t bandParticles = kBandParticles);
  using RegionSummer::gather;
  using RegionSummer::scatter;
  void gather(const double* in, int K, double* out) override;
  void scatter(const double* in, int K, double* out) override;
  void apply(RegionKernel& kernel) override;
  /// Makes room for passes of up to Kg gathered and Ks scattered channels now, so that the
  /// first apply() with them does not allocate (apply() otherwise grows on first use).
  void reserve(int Kg, int Ks) { reserveSliceScratch(Kg, Ks); }
  /// Sweeps `scratch` from now on, grown to what this summer has reserved, instead of its own
  /// buffers (released). Only for summers whose apply() never runs while another one's sharing
  /// it does; the results are the same to the bit.
  /// @throws std::invalid_argument for a null scratch
  void shareScratch(std::shared_ptr<SliceStreamScratch> scratch);
  /// the buffers apply() sweeps (this summer's own unless shared)
  const std::shared_ptr<SliceStreamScratch>& scratch() const { return scratch_; }
  /// Bands of rows apply() sweeps one after the other (1: whole slices).
  std::size_t bandCount() const { return bandY_.size() - 1; }
  /// Particles in the widest slice of a band's data rows (its rows and the halo): the largest
  /// band-slice the rings are sized for.
  std::size_t widestBandSlice() const { return maxData_; }

 private:
  using SliceScratch = SliceStreamScratch::Thread;
  /// One thread's sweep of a chunk of slices in one pass (slice_stream_summer.cpp).
  class Sweep;
  /// The initial chunks of the threads and the schedule's storage (thread_schedule.cpp).
  void initSchedule();
  /// Grows the two scratch buffers to #P*K; never shrinks them (no refill between passes).
  void reserveScratch(int K);
  void reserveSliceScratch(int Kg, int Ks);
  void growSliceScratch(SliceStreamScratch& scratch) const;
  /// apply() for the slices [k0, k1) (whole blocks), `t` the thread's scratch. The sweep calls
  /// published(b, r) after region slice r of band b, then drain(finish) once: the particle
  /// blocks near other chunks (ownsBlock()) are left to it (finish(b, c0, c1) does the
  /// particle slices [c0, c1) of band b, in this thread's scratch).
  template <typename Published, typename Drain>
  void applyChunk(RegionKernel& kernel, int Kg, int Ks, std::size_t k0, std::size_t k1, SliceScratch& t,
                  Published published, Drain drain);
  /// Slices from a chunk's inner edge within which its sweep leaves the particle blocks to
  /// drain(): w, the reach of their windows into the next chunk's regions, and kSpareBlocks more.
  std::ptrdiff_t deferMargin() const { return lattice_.regionHalfWidth() + kSpareBlocks * kBlock; }
  /// Whether the sweep of chunk [lo, hi) does the particle block [first, last] itself (else drain()).
  bool ownsBlock(std::ptrdiff_t first, std::ptrdiff_t last, std::ptrdiff_t lo, std::ptrdiff_t hi) const {
    const std::ptrdiff_t m = deferMargin(), slices = static_cast<std::ptrdiff_t>(sliceStart_.size()) - 1;
    return (lo == 0 || first - m >= lo) && (hi == slices || last + m < hi);
  }
  /// A block of particle slices that its chunk's sweep leaves (see listDeferred()): band, slices
  /// [c0, c1), and its conditions deps_[depBegin, depEnd).
  struct Deferred {
    std::uint32_t band, c0, c1, depBegin, depEnd;
  };
  /// A condition of a deferred block: chunk `chunk` has published at least `need` (progress()).
  struct Dependency {
    std::uint32_t chunk;
    std::uint64_t need;
  };
  /// What a chunk has published in this pass: progress(b, r) after region slice r of band b,
  /// progress(b, slices) at the end of band b. Increasing through a sweep.
  std::uint64_t progress(std::size_t band, std::size_t slice) const {
    return band * (sliceStart_.size()) + slice + 1;
  }
  /// deferred_ and deps_ for the current chunk boundaries (at construction and whenever
  /// rebalance() moves them, like markSharedSlices()).
  void listDeferred();
  struct alignas(64) Progress {
    std::atomic<std::uint64_t> value{0};
  };
  /// The rows of the lattice (y) in bands: band b holds region rows [bandY_[b], bandY_[b + 1]).
  void makeBands(std::size_t bandParticles);
  /// First particle of slice k in row j or above (rows counted from the lowest occupied row;
  /// j = rows_ gives the slice's end).
  std::uint32_t rowStart(std::size_t k, int j) const {
    return rowStart_[k * static_cast<std::size_t>(rows_ + 1) + static_cast<std::size_t>(j)];
  }
  const Lattice& lattice_;
  int threads_;
  std::vector<double> tmpA_, tmpB_;
  // slices: slice k holds particles [sliceStart_[k], sliceStart_[k+1]) and the x-runs (y-runs)
  // [sliceXRun_[k], sliceXRun_[k+1]) ([sliceYRun_[k], ...)) of the lattice's run lists
  std::vector<std::uint32_t> sliceStart_, sliceXRun_, sliceYRun_;
  std::size_t maxRun_ = 0;  // the longest x-run
  int rows_ = 0;                         // rows (y) from the lowest to the highest occupied one
  std::vector<std::uint32_t> rowStart_;  // slices x (rows_ + 1), see rowStart()
  std::vector<int> bandY_;               // band boundaries in rows: 0 = bandY_[0] < ... = rows_
  // the largest band-slice of the three row ranges a band works on: data (its rows and the halo),
  // regions (its rows), scatter (the rows whose regions reach its particle results)
  std::size_t maxData_ = 0, maxRegion_ = 0, maxScatter_ = 0;
  // region data of the 2w rows below each inner band boundary b (1 <= b < bands), per slice k at
  // boundaryBase_[(b - 1) * slices + k] (in regions)
  std::vector<std::size_t> boundaryBase_;
  std::vector<double> boundaryStore_;
  // per particle: position in its z-run, the run's length and its start in runOrder(2)
  std::vector<std::uint32_t> zPos_, zLen_, zBase_;
  /// Moves the chunk boundaries towards equal busy times (see the definition).
  void rebalance();
  std::vector<std::size_t> chunkStart_;  // threads_ + 1 slice indices, multiples of kBlock
  std::vector<double> busySeconds_;         // per thread: time of its sweep in the last apply()
  std::vector<double> secondsPerParticle_;  // per chunk: smoothed busy time per particle
  /// sharedSlice_ from the chunk boundaries (see the definition).
  void markSharedSlices();
  std::shared_ptr<SliceStreamScratch> scratch_;
  std::vector<double> regionOut_;    // #P * K_s region data of the slices near chunk boundaries
  std::vector<char> sharedSlice_;    // per slice: its region data goes to regionOut_ (threads > 1)
  int scratchKg_ = 0, scratchKs_ = 0;
  // threads > 1: the deferred blocks of this pass and their conditions (capacity reserved at
  // construction), a claim flag per block, each chunk's published progress
  std::vector<Deferred> deferred_;
  std::vector<Dependency> deps_;
  std::vector<std::atomic<std::uint8_t>> claimed_;
  std::vector<Progress> progress_;
};

}  // namespace deformable_flsm
