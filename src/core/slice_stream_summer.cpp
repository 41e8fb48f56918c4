// SliceStreamSummer's sweep: each thread streams its chunk of slices through the gather's and
// the scatter's sliding windows (see the class comment), band by band.
#include "deformable_flsm/core/slice_stream_summer.h"

#include "deformable_flsm/core/window_sums.h"
#include "simd_dispatch.h"
#include "sliding_window.h"

#include <omp.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <thread>
#include <utility>

namespace deformable_flsm {

using detail::slideRun;
using detail::withChannels;
using detail::kBuiltWide;
using detail::withSimdWidth;
using detail::zWindowRows;

void SliceStreamSummer::reserveSliceScratch(int Kg, int Ks) {
  if (Kg <= scratchKg_ && Ks <= scratchKs_) return;
  scratchKg_ = std::max(scratchKg_, Kg);
  scratchKs_ = std::max(scratchKs_, Ks);
  growSliceScratch(*scratch_);
  boundaryStore_.resize(boundaryBase_.back() * static_cast<std::size_t>(scratchKs_));
  // With one thread every region slice lives in the ring (and the boundary store) only.
  if (threads_ > 1) regionOut_.resize(particles_ * static_cast<std::size_t>(scratchKs_));
}

// Grows (never shrinks: a shared set serves larger summers too) the buffers of the threads this
// summer sweeps with to its reservation.
void SliceStreamSummer::growSliceScratch(SliceStreamScratch& scratch) const {
  const std::size_t g = maxData_ * static_cast<std::size_t>(scratchKg_);
  const std::size_t r = maxRegion_ * static_cast<std::size_t>(scratchKg_);
  const std::size_t s = maxScatter_ * static_cast<std::size_t>(scratchKs_);
  const std::size_t ring = 2 * static_cast<std::size_t>(lattice_.regionHalfWidth()) + 2;
  const std::size_t T = static_cast<std::size_t>(threads_);
  if (scratch.threads.size() < T) scratch.threads.resize(T);
  const auto grow = [](auto& buffer, std::size_t size) {
    if (buffer.size() < size) buffer.resize(size);
  };
  // the sets of the threads this summer uses only
  for (std::size_t th = 0; th < T; ++th) {
    SliceScratch& t = scratch.threads[th];
    grow(t.run, maxRun_ * static_cast<std::size_t>(std::max(scratchKg_, scratchKs_)));
    grow(t.rowSum, g);
    grow(t.ring, ring * g);
    grow(t.sumPrev, r);
    grow(t.sumCur, r);
    grow(t.zPrev, s);
    grow(t.zCur, s);
    grow(t.colSum, s);
    grow(t.regionRing, ring * s);
    grow(t.zRow, ring);
    grow(t.zStart, ring);
  }
}

void SliceStreamSummer::shareScratch(std::shared_ptr<SliceStreamScratch> scratch) {
  if (!scratch) throw std::invalid_argument("SliceStreamSummer::shareScratch: no scratch given");
  growSliceScratch(*scratch);
  scratch_ = std::move(scratch);
}

/// One thread's sweep of a chunk of slices in one pass: the kernel, the thread's scratch and the
/// current band's rows; a step per member (the data of a slice, its regions, its particle
/// results). Reads the summer's layout, writes its boundary store and shared region data.
class SliceStreamSummer::Sweep {
 public:
  Sweep(SliceStreamSummer& summer, RegionKernel& kernel, int Kg, int Ks, SliceScratch& t)
      : s_(summer),
        kernel_(kernel),
        Kg_(Kg),
        Ks_(Ks),
        t_(t),
        w_(summer.lattice_.regionHalfWidth()),
        wr_(static_cast<int>(w_)),
        slices_(static_cast<std::ptrdiff_t>(summer.sliceStart_.size()) - 1),
        ringSize_(2 * static_cast<std::size_t>(w_) + 2),
        bands_(summer.bandCount()),
        dataStride_(summer.maxData_ * static_cast<std::size_t>(Kg)) {}

  /// The rows of band b (see the class comment): regions [yR0, yR1), their data [yD0, yD1), the
  /// regions the scatter reads [yN0, yR1), the particle results [yP0, yP1).
  void setBand(std::size_t b) {
    band_ = b;
    yR0_ = s_.bandY_[b];
    yR1_ = s_.bandY_[b + 1];
    yD0_ = std::max(0, yR0_ - wr_);
    yD1_ = std::min(s_.rows_, yR1_ + wr_);
    yN0_ = std::max(0, yR0_ - 2 * wr_);
    yP0_ = b == 0 ? 0 : yR0_ - wr_;
    yP1_ = b + 1 == bands_ ? s_.rows_ : yR1_ - wr_;
  }

  /// Gather: the data of slice a, summed along x and y into the ring.
  void dataSlice(std::ptrdiff_t a) {
    const std::size_t k = static_cast<std::size_t>(a);
    xGather(k, t_.rowSum.data());
    yPass(k, s_.rowStart(k, yD0_), s_.rowStart(k, yD1_), Kg_, t_.rowSum.data(), ringRow(a));
  }

  /// The gather's z-window, then the kernel's region data for slice b; the region rows below the
  /// band (left by the band below) and those the band above will need go between the ring and
  /// the boundary store.
  void regionSlice(std::ptrdiff_t b) {
    const std::size_t k = static_cast<std::size_t>(b);
    const std::uint32_t r0 = s_.rowStart(k, yR0_), r1 = s_.rowStart(k, yR1_);
    const std::ptrdiff_t off = windowSources(b, yD0_, [this](std::ptrdiff_t z) { return ringRow(z); });
    withChannels(Kg_, [&](auto kc) {
      constexpr int KK = decltype(kc)::value;
      const double* const* row = t_.zRow.data();
      const std::uint32_t* start = t_.zStart.data();
      auto src = [=](std::uint32_t p, std::ptrdiff_t z) {
        return row[z + off] + static_cast<std::size_t>(p - start[z + off]) * KK;
      };
      const std::uint32_t prevBase = k > 0 ? s_.rowStart(k - 1, yR0_) : 0;
      withSimdWidth<kBuiltWide>([&](auto wide) {
        zWindowRows<KK, decltype(wide)::value>(k, r0, r1, prevBase, b % kBlock == 0, w_, zOrder(), s_.zPos_.data(),
                                               s_.zLen_.data(), s_.zBase_.data(), src, t_.sumPrev.data(),
                                               t_.sumCur.data());
      });
    });
    double* regions = regionRow(b);
    const std::uint32_t n0 = s_.rowStart(k, yN0_);
    kernel_.regionData(r0, r1, t_.sumCur.data(), regions + static_cast<std::size_t>(r0 - n0) * Ks_);
    if (!shared(k)) {
      const std::size_t perBand = static_cast<std::size_t>(slices_);
      if (band_ > 0)  // rows [yR0 - 2w, yR0) = [yN0, yR0)
        std::memcpy(regions, s_.boundaryStore_.data() + s_.boundaryBase_[(band_ - 1) * perBand + k] * Ks_,
                    sizeof(double) * (r0 - n0) * static_cast<std::size_t>(Ks_));
      if (band_ + 1 < bands_) {  // rows [yR1 - 2w, yR1)
        const std::uint32_t top = s_.rowStart(k, yR1_ - 2 * wr_);
        std::memcpy(s_.boundaryStore_.data() + s_.boundaryBase_[band_ * perBand + k] * Ks_,
                    regions + static_cast<std::size_t>(top - n0) * Ks_, sizeof(double) * (r1 - top) * static_cast<std::size_t>(Ks_));
      }
    }
    std::swap(t_.sumPrev, t_.sumCur);
  }

  /// The scatter's z-window over the region data, then y and x, then the kernel's particle result.
  void particleSlice(std::ptrdiff_t c) {
    const std::size_t k = static_cast<std::size_t>(c);
    const std::uint32_t n0 = s_.rowStart(k, yN0_), n1 = s_.rowStart(k, yR1_);
    const std::ptrdiff_t off = windowSources(c, yN0_, [this](std::ptrdiff_t z) { return regionRow(z); });
    withChannels(Ks_, [&](auto kc) {
      constexpr int KK = decltype(kc)::value;
      const double* const* row = t_.zRow.data();
      const std::uint32_t* start = t_.zStart.data();
      auto src = [=](std::uint32_t p, std::ptrdiff_t z) {
        return row[z + off] + static_cast<std::size_t>(p - start[z + off]) * KK;
      };
      const std::uint32_t prevBase = k > 0 ? s_.rowStart(k - 1, yN0_) : 0;
      withSimdWidth<kBuiltWide>([&](auto wide) {
        zWindowRows<KK, decltype(wide)::value>(k, n0, n1, prevBase, c % kBlock == 0, w_, zOrder(), s_.zPos_.data(),
                                               s_.zLen_.data(), s_.zBase_.data(), src, t_.zPrev.data(), t_.zCur.data());
      });
    });
    yPass(k, n0, n1, Ks_, t_.zCur.data(), t_.colSum.data());
    xScatter(k, t_.colSum.data());
    std::swap(t_.zPrev, t_.zCur);
  }

 private:
  const std::uint32_t* zOrder() const { return s_.lattice_.runOrder(2).data(); }

  /// The z-window of slice k reads slices k - w - 1 .. k + w: their rows (rowOf(z), from row y0)
  /// and first particles (from row y0) go to the scratch's table, once per slice rather than per
  /// particle (the ring slot is a division). Returns the offset of slice z's entry: z + offset.
  template <typename RowOf>
  std::ptrdiff_t windowSources(std::ptrdiff_t k, int y0, RowOf rowOf) {
    const std::ptrdiff_t off = w_ + 1 - k;
    const std::ptrdiff_t lo = std::max<std::ptrdiff_t>(0, k - w_ - 1), hi = std::min(slices_ - 1, k + w_);
    for (std::ptrdiff_t z = lo; z <= hi; ++z) {
      t_.zRow[static_cast<std::size_t>(z + off)] = rowOf(z);
      t_.zStart[static_cast<std::size_t>(z + off)] = s_.rowStart(static_cast<std::size_t>(z), y0);
    }
    return off;
  }

  /// Sliding windows over the y-runs of slice k within the particles [i0, i1) (whole rows), from
  /// and to rows at (p - i0) * K. A run cut by the range gives the right sums for the rows at
  /// least w inside it, which are the rows the caller reads.
  void yPass(std::size_t k, std::uint32_t i0, std::uint32_t i1, int K, const double* in, double* out) const {
    const std::uint32_t* sliceStart = s_.sliceStart_.data();
    const auto& yStarts = s_.lattice_.runStarts(1);
    const auto& yOrder = s_.lattice_.runOrder(1);
    const std::ptrdiff_t w = w_;
    const bool whole = i0 == sliceStart[k] && i1 == sliceStart[k + 1];
    withChannels(K, [&](auto kc) {
      constexpr int KK = decltype(kc)::value;
      for (std::uint32_t q = s_.sliceYRun_[k]; q < s_.sliceYRun_[k + 1]; ++q) {
        const std::uint32_t* run = yOrder.data() + yStarts[q];
        const std::uint32_t* end = yOrder.data() + yStarts[q + 1];
        if (!whole) {
          if (run[0] >= i1) break;  // the runs are listed in the order of their first particle
          if (end[-1] < i0) continue;
          run = std::lower_bound(run, end, i0);
          end = std::lower_bound(run, end, i1);
          if (end == run) continue;
        }
        withSimdWidth<kBuiltWide>([&](auto wide) {
          slideRun<KK, decltype(wide)::value>(in, out, end - run, w, [run, i0](std::ptrdiff_t u) {
            return static_cast<std::ptrdiff_t>(run[u] - i0);
          });
        });
      }
    });
  }

  /// The x-runs of slice k within the particles [i0, i1) (each a range of consecutive
  /// particles), one at a time: body(channels, first particle, length) for each. The gather
  /// generates its data run by run and sums it along x; the scatter sums its rows along x and
  /// hands them to the kernel's particle result run by run: no slice-sized buffer between the
  /// kernel and the window passes.
  template <typename Body>
  void forXRuns(std::size_t k, std::uint32_t i0, std::uint32_t i1, int K, Body&& body) const {
    const std::uint32_t* sliceStart = s_.sliceStart_.data();
    const auto& xStarts = s_.lattice_.runStarts(0);
    const auto& xOrder = s_.lattice_.runOrder(0);
    std::uint32_t q0 = s_.sliceXRun_[k], q1 = s_.sliceXRun_[k + 1];
    if (i0 != sliceStart[k] || i1 != sliceStart[k + 1]) {
      auto firstAt = [&](std::uint32_t a, std::uint32_t b, std::uint32_t i) {  // first run from i on
        while (a < b) {
          const std::uint32_t mid = a + (b - a) / 2;
          if (xOrder[xStarts[mid]] < i) a = mid + 1;
          else b = mid;
        }
        return a;
      };
      q0 = firstAt(q0, q1, i0);
      q1 = firstAt(q0, q1, i1);
    }
    withChannels(K, [&](auto kc) {
      for (std::uint32_t q = q0; q < q1; ++q)
        body(kc, xOrder[xStarts[q]], static_cast<std::ptrdiff_t>(xStarts[q + 1] - xStarts[q]));
    });
  }

  /// The gather's data of slice k (the band's data rows), generated through the run-sized
  /// buffer and summed along x into `out`.
  void xGather(std::size_t k, double* out) {
    const std::uint32_t i0 = s_.rowStart(k, yD0_);
    forXRuns(k, i0, s_.rowStart(k, yD1_), Kg_, [&](auto kc, std::uint32_t first, std::ptrdiff_t len) {
      constexpr int KK = decltype(kc)::value;
      kernel_.particleData(first, first + static_cast<std::size_t>(len), t_.run.data());
      withSimdWidth<kBuiltWide>([&](auto wide) {
        slideRun<KK, decltype(wide)::value>(t_.run.data(), out + static_cast<std::size_t>(first - i0) * KK, len, w_,
                                            [](std::ptrdiff_t u) { return u; });
      });
    });
  }

  /// The scatter's rows of slice k summed along x, run by run, into the kernel's particle result
  /// (the band's particle-result rows).
  void xScatter(std::size_t k, const double* in) {
    const std::uint32_t n0 = s_.rowStart(k, yN0_);
    forXRuns(k, s_.rowStart(k, yP0_), s_.rowStart(k, yP1_), Ks_, [&](auto kc, std::uint32_t first, std::ptrdiff_t len) {
      constexpr int KK = decltype(kc)::value;
      withSimdWidth<kBuiltWide>([&](auto wide) {
        slideRun<KK, decltype(wide)::value>(in + static_cast<std::size_t>(first - n0) * KK, t_.run.data(), len, w_,
                                            [](std::ptrdiff_t u) { return u; });
      });
      kernel_.particleResult(first, first + static_cast<std::size_t>(len), t_.run.data());
    });
  }

  /// The ring slot of data slice k.
  double* ringRow(std::ptrdiff_t k) const {
    return t_.ring.data() + (static_cast<std::size_t>(k) % ringSize_) * dataStride_;
  }
  /// Whether the region data of slice z goes to the shared regionOut_ (a block left to drain()
  /// may read it).
  bool shared(std::size_t z) const { return !s_.sharedSlice_.empty() && s_.sharedSlice_[z] != 0; }
  /// Region data of slice k, from row yN0 on: in the thread's ring of 2w + 2 slices (a particle
  /// slice's z-window reads w slices either side and, when it slides, the one leaving), or for
  /// the slices that a block left to drain() may read, in the shared regionOut_ (indexed by
  /// particle).
  double* regionRow(std::ptrdiff_t k) {
    const std::size_t z = static_cast<std::size_t>(k);
    if (!shared(z)) return t_.regionRing.data() + (z % ringSize_) * s_.maxScatter_ * static_cast<std::size_t>(Ks_);
    return s_.regionOut_.data() + static_cast<std::size_t>(s_.rowStart(z, yN0_)) * Ks_;
  }

  SliceStreamSummer& s_;
  RegionKernel& kernel_;
  const int Kg_, Ks_;
  SliceScratch& t_;
  const std::ptrdiff_t w_;
  const int wr_;
  const std::ptrdiff_t slices_;
  const std::size_t ringSize_;
  const std::size_t bands_;
  const std::size_t dataStride_;
  std::size_t band_ = 0;
  int yR0_ = 0, yR1_ = 0, yD0_ = 0, yD1_ = 0, yN0_ = 0, yP0_ = 0, yP1_ = 0;
};

template <typename Published, typename Drain>
void SliceStreamSummer::applyChunk(RegionKernel& kernel, int Kg, int Ks, std::size_t k0, std::size_t k1,
                                   SliceScratch& t, Published published, Drain drain) {
  const std::ptrdiff_t w = lattice_.regionHalfWidth();
  const std::ptrdiff_t slices = static_cast<std::ptrdiff_t>(sliceStart_.size()) - 1;
  const std::ptrdiff_t lo = static_cast<std::ptrdiff_t>(k0), hi = static_cast<std::ptrdiff_t>(k1);
  // A block of particle slices [c, c + kBlock) reads region slices [c - w, c + kBlock - 1 + w]:
  // near another chunk it is left to drain() (ownsBlock(); listDeferred() lists the same blocks).
  auto ownBlock = [&](std::ptrdiff_t c) {
    const std::ptrdiff_t first = c - c % kBlock;
    return ownsBlock(first, std::min(first + kBlock, hi) - 1, lo, hi);
  };
  Sweep sweep(*this, kernel, Kg, Ks, t);
  for (std::size_t b = 0; b < bandCount(); ++b) {
    sweep.setBand(b);
    for (std::ptrdiff_t a = lo - w; a < hi + 2 * w; ++a) {
      if (a >= 0 && a < slices && a < hi + w) sweep.dataSlice(a);
      const std::ptrdiff_t r = a - w;
      if (r >= lo && r < hi) {
        sweep.regionSlice(r);
        published(b, static_cast<std::size_t>(r));
      }
      const std::ptrdiff_t c = r - w;
      if (c >= lo && c < hi && ownBlock(c)) sweep.particleSlice(c);
    }
    published(b, static_cast<std::size_t>(slices));
  }
  drain([&](std::size_t b, std::size_t c0, std::size_t c1) {
    sweep.setBand(b);
    for (std::size_t c = c0; c < c1; ++c) sweep.particleSlice(static_cast<std::ptrdiff_t>(c));
  });
}

void SliceStreamSummer::apply(RegionKernel& kernel) {
  const int Kg = kernel.gatherChannels(), Ks = kernel.scatterChannels();
  withChannels(Kg, [](auto) {});
  withChannels(Ks, [](auto) {});
  reserveSliceScratch(Kg, Ks);
  const std::size_t slices = sliceStart_.size() - 1;
  auto unpublished = [](std::size_t, std::size_t) {};
  auto nothingLeft = [](auto&&) {};
  if (threads_ == 1) {
    applyChunk(kernel, Kg, Ks, 0, slices, scratch_->threads[0], unpublished, nothingLeft);
    return;
  }
  for (Progress& p : progress_) p.value.store(0, std::memory_order_relaxed);
  for (std::size_t i = 0; i < deferred_.size(); ++i) claimed_[i].store(0, std::memory_order_relaxed);
#pragma omp parallel num_threads(threads_)
  {
    // A smaller team than asked for (nested parallelism, thread limits): one thread does all,
    // with the same sums.
    const int th = omp_get_thread_num();
    if (omp_get_num_threads() != threads_) {
      if (th == 0) applyChunk(kernel, Kg, Ks, 0, slices, scratch_->threads[0], unpublished, nothingLeft);
    } else {
      const std::size_t me = static_cast<std::size_t>(th);
      const double start = omp_get_wtime();
      auto publish = [this, me](std::size_t b, std::size_t r) {
        progress_[me].value.store(progress(b, r), std::memory_order_release);
      };
      // The deferred blocks, of any chunk, go to whichever thread finds them ready first: a thread
      // that finishes its sweep early does its neighbour's instead of waiting for it.
      auto drain = [this, me, start](auto&& finish) {
        busySeconds_[me] = omp_get_wtime() - start;  // the sweep: what rebalance() evens out
        int idle = 0;
        for (;;) {
          bool left = false, ran = false;
          for (std::size_t i = 0; i < deferred_.size(); ++i) {
            if (claimed_[i].load(std::memory_order_relaxed) != 0) continue;
            left = true;
            const Deferred& d = deferred_[i];
            bool ready = true;
            for (std::uint32_t e = d.depBegin; e < d.depEnd && ready; ++e)
              ready = progress_[deps_[e].chunk].value.load(std::memory_order_acquire) >= deps_[e].need;
            if (!ready || claimed_[i].exchange(1, std::memory_order_acq_rel) != 0) continue;
            finish(d.band, d.c0, d.c1);
            ran = true;
          }
          if (!left) return;
          if (ran) {
            idle = 0;
          } else if (++idle < 64) {
#if defined(__x86_64__) || defined(__i386__)
            __builtin_ia32_pause();
#endif
          } else {
            std::this_thread::yield();  // more threads than free cores: let the others run
          }
        }
      };
      applyChunk(kernel, Kg, Ks, chunkStart_[me], chunkStart_[me + 1], scratch_->threads[me], publish, drain);
    }
  }
  rebalance();
}

void SliceStreamSummer::reserveScratch(int K) {
  const std::size_t size = particles_ * static_cast<std::size_t>(K);
  if (tmpA_.size() < size) {
    tmpA_.resize(size);
    tmpB_.resize(size);
  }
}

void SliceStreamSummer::gather(const double* in, int K, double* out) {
  reserveScratch(K);
  windowPass(lattice_, 0, in, K, tmpA_.data(), threads_);
  windowPass(lattice_, 1, tmpA_.data(), K, tmpB_.data(), threads_);
  windowPass(lattice_, 2, tmpB_.data(), K, out, threads_);
}

void SliceStreamSummer::scatter(const double* in, int K, double* out) {
  reserveScratch(K);
  windowPass(lattice_, 2, in, K, tmpA_.data(), threads_);
  windowPass(lattice_, 1, tmpA_.data(), K, tmpB_.data(), threads_);
  windowPass(lattice_, 0, tmpB_.data(), K, out, threads_);
}

}  // namespace deformable_flsm
