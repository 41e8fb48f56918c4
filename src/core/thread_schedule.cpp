// SliceStreamSummer's thread schedule: the chunks of slices the threads sweep, the particle
// blocks near their edges that any thread may finish (and what each waits for), and the moving
// of the chunk boundaries towards equal busy times.
#include "deformable_flsm/core/slice_stream_summer.h"

#include <algorithm>
#include <cmath>

namespace deformable_flsm {

// Threads take whole blocks, about the same number of particles each; with more than one, the
// schedule's storage at its whole capacity (apply() only clears and refills).
void SliceStreamSummer::initSchedule() {
  const std::size_t n = particles_;
  const std::size_t slices = sliceStart_.size() - 1;
  chunkStart_.assign(static_cast<std::size_t>(threads_) + 1, slices);
  chunkStart_[0] = 0;
  for (int t = 1; t < threads_; ++t) {
    const std::size_t target = n * static_cast<std::size_t>(t) / static_cast<std::size_t>(threads_);
    std::size_t k = chunkStart_[t - 1];
    while (k + kBlock < slices && sliceStart_[k + kBlock] < target) k += kBlock;
    // the block boundary nearest to the target: k or k + kBlock
    const std::size_t next = std::min(k + kBlock, slices);
    if (k < slices && target - sliceStart_[k] > sliceStart_[next] - target) k = next;
    chunkStart_[t] = std::min(k, slices);
  }
  scratch_ = std::make_shared<SliceStreamScratch>();
  scratch_->threads.resize(static_cast<std::size_t>(threads_));
  if (threads_ > 1) {  // whole capacity now: apply() only clears and refills
    const std::size_t T = static_cast<std::size_t>(threads_);
    const std::size_t blocks = bandCount() * (slices / kBlock + T + 1);
    deferred_.reserve(blocks);
    deps_.reserve(blocks * T);
    claimed_ = std::vector<std::atomic<std::uint8_t>>(blocks);
    progress_ = std::vector<Progress>(T);
    markSharedSlices();
    listDeferred();
  }
  busySeconds_.assign(static_cast<std::size_t>(threads_), 0.0);
  secondsPerParticle_.assign(static_cast<std::size_t>(threads_), 0.0);
}

// The particle blocks each chunk's sweep leaves, and what must be published before any thread
// may do one (block [c0, c1) of chunk t, band b):
//  - every chunk u holding some of the region slices it reads, [c0 - w, c1 - 1 + w]: progress up
//    to the highest of them;
//  - every other chunk u whose halo holds some of its particles (u reads their data in band b,
//    and the block overwrites them): the data below u's chunk is read before u's first region
//    slice, the data above it before u's last. For a chunk with slices of its own the regions
//    the block reads already ask as much; a chunk left without any (more threads than blocks)
//    still reads its halo, and publishes only at the end of each band (the 3-slice lattice of
//    test DeferredBlocksWaitForWhatTheyRead).
// Particles of band b's results lie in no other band's data rows but band b - 1's, which every
// chunk finishes before any band-b progress. Within a band, the block is finished after the
// regions it reads, as in a single sweep.
void SliceStreamSummer::listDeferred() {
  const std::ptrdiff_t w = lattice_.regionHalfWidth();
  const std::ptrdiff_t slices = static_cast<std::ptrdiff_t>(sliceStart_.size()) - 1;
  const std::size_t T = static_cast<std::size_t>(threads_);
  deferred_.clear();
  deps_.clear();
  for (std::size_t t = 0; t < T; ++t) {
    const std::ptrdiff_t lo = static_cast<std::ptrdiff_t>(chunkStart_[t]), hi = static_cast<std::ptrdiff_t>(chunkStart_[t + 1]);
    for (std::size_t b = 0; b < bandCount(); ++b) {
      for (std::ptrdiff_t first = lo; first < hi; first += kBlock) {
        const std::ptrdiff_t last = std::min(first + kBlock, hi) - 1;
        if (ownsBlock(first, last, lo, hi)) continue;
        Deferred d{static_cast<std::uint32_t>(b), static_cast<std::uint32_t>(first), static_cast<std::uint32_t>(last + 1),
                   static_cast<std::uint32_t>(deps_.size()), 0};
        const std::ptrdiff_t readLo = std::max<std::ptrdiff_t>(first - w, 0);
        const std::ptrdiff_t readHi = std::min<std::ptrdiff_t>(last + w, slices - 1);
        for (std::size_t u = 0; u < T; ++u) {
          const std::ptrdiff_t ulo = static_cast<std::ptrdiff_t>(chunkStart_[u]);
          const std::ptrdiff_t uhi = static_cast<std::ptrdiff_t>(chunkStart_[u + 1]);
          std::uint64_t need = 0;
          const std::ptrdiff_t top = std::min(readHi, uhi - 1);
          if (std::max(readLo, ulo) <= top) need = progress(b, static_cast<std::size_t>(top));
          if (u != t) {
            if (first < ulo && last >= ulo - w) need = std::max(need, progress(b, static_cast<std::size_t>(ulo)));
            if (last >= uhi && first < uhi + w)
              need = std::max(need, uhi > ulo ? progress(b, static_cast<std::size_t>(uhi - 1))
                                              : progress(b, static_cast<std::size_t>(slices)));
          }
          if (need > 0) deps_.push_back(Dependency{static_cast<std::uint32_t>(u), need});
        }
        d.depEnd = static_cast<std::uint32_t>(deps_.size());
        deferred_.push_back(d);
      }
    }
  }
}

// A block left to drain() reads region slices up to w beyond its own, and its first slice lies
// within deferMargin() + kBlock - 1 of its chunk's edge: the region slices within deferMargin() +
// w + kBlock of an inner chunk boundary go to regionOut_, where any thread can read them after the
// sweeps have moved on.
void SliceStreamSummer::markSharedSlices() {
  const std::size_t slices = sliceStart_.size() - 1;
  const std::ptrdiff_t reach = deferMargin() + lattice_.regionHalfWidth() + kBlock;
  sharedSlice_.assign(slices, 0);
  for (int t = 1; t < threads_; ++t) {
    const std::ptrdiff_t B = static_cast<std::ptrdiff_t>(chunkStart_[static_cast<std::size_t>(t)]);
    const std::ptrdiff_t from = std::max<std::ptrdiff_t>(0, B - reach);
    const std::ptrdiff_t to = std::min<std::ptrdiff_t>(static_cast<std::ptrdiff_t>(slices), B + reach);
    for (std::ptrdiff_t z = from; z < to; ++z) sharedSlice_[static_cast<std::size_t>(z)] = 1;
  }
}

// Chunks of equal particle counts need not take equal times (slices of short, broken runs cost
// more per particle; another process may share a core): each boundary moves to where the two
// chunks' smoothed cost per particle (of their sweeps) predicts equal times, at whole blocks; the
// blocks left to drain() even out the rest. The sums do not depend on where the boundaries are.
void SliceStreamSummer::rebalance() {
  const std::size_t T = static_cast<std::size_t>(threads_);
  for (std::size_t t = 0; t < T; ++t) {
    const double particles = double(sliceStart_[chunkStart_[t + 1]] - sliceStart_[chunkStart_[t]]);
    if (!(particles > 0.0) || !(busySeconds_[t] > 0.0)) continue;
    const double rate = busySeconds_[t] / particles;
    secondsPerParticle_[t] = secondsPerParticle_[t] > 0.0 ? 0.8 * secondsPerParticle_[t] + 0.2 * rate : rate;
  }
  bool moved = false;
  for (std::size_t t = 1; t < T; ++t) {
    const double r0 = secondsPerParticle_[t - 1], r1 = secondsPerParticle_[t];
    if (!(r0 > 0.0) || !(r1 > 0.0)) continue;
    const std::size_t lo = chunkStart_[t - 1], hi = chunkStart_[t + 1];
    if (hi - lo <= static_cast<std::size_t>(kBlock)) continue;
    // r0 P0 = r1 P1, P0 + P1 = the particles of both chunks
    const double target = double(sliceStart_[lo]) + double(sliceStart_[hi] - sliceStart_[lo]) * r1 / (r0 + r1);
    std::size_t best = chunkStart_[t];
    double bestMiss = std::abs(double(sliceStart_[best]) - target);
    for (std::size_t k = lo + kBlock; k < hi; k += kBlock) {
      const double miss = std::abs(double(sliceStart_[k]) - target);
      if (miss < bestMiss) {
        best = k;
        bestMiss = miss;
      }
    }
    moved = moved || best != chunkStart_[t];
    chunkStart_[t] = best;
  }
  if (moved) {  // what depends on the boundaries, for the next pass
    markSharedSlices();
    listDeferred();
  }
}

}  // namespace deformable_flsm
