#include "deformable_flsm/core/fast_summation.h"

#include <omp.h>

#include <algorithm>
#include <cstring>
#include <stdexcept>
#include <string>
#include <thread>
#include <type_traits>

namespace deformable_flsm {

namespace {

/// Calls f(std::integral_constant<int, K>) for the supported channel counts.
template <typename F>
void withChannels(int K, F&& f) {
  switch (K) {
    case 1: return f(std::integral_constant<int, 1>{});
    case 3: return f(std::integral_constant<int, 3>{});
    case 6: return f(std::integral_constant<int, 6>{});
    case 12: return f(std::integral_constant<int, 12>{});
    case 18: return f(std::integral_constant<int, 18>{});
    case 24: return f(std::integral_constant<int, 24>{});
    default: break;
  }
  throw std::invalid_argument("region summation: unsupported channel count " + std::to_string(K));
}

/// K running sums held in SIMD registers: K / kWide vectors of kWide doubles (4 where the target
/// has AVX, else 2: GCC/Clang vector types wider than the target's registers are lowered
/// poorly), then a two-wide vector and a scalar for the rest. Rows are loaded and stored
/// unaligned.
template <int K>
struct Accumulator {
#ifdef __AVX__
  static constexpr int kWide = 4;
#else
  static constexpr int kWide = 2;
#endif
  typedef double VW __attribute__((vector_size(kWide * sizeof(double))));
  typedef double V2 __attribute__((vector_size(2 * sizeof(double))));
  static constexpr int kFull = K / kWide;
  static constexpr bool kTwo = (K % kWide) >= 2;
  static constexpr bool kOne = (K % 2) == 1;
  static constexpr int kTwoAt = kWide * kFull;
  static constexpr int kOneAt = kTwoAt + (kTwo ? 2 : 0);
  VW full[kFull > 0 ? kFull : 1];
  V2 two;
  double one;

  void zero() {
    for (int i = 0; i < kFull; ++i) full[i] = VW{} + 0.0;
    two = V2{0.0, 0.0};
    one = 0.0;
  }
  void set(const double* p) {
    for (int i = 0; i < kFull; ++i) std::memcpy(&full[i], p + kWide * i, sizeof(VW));
    if constexpr (kTwo) std::memcpy(&two, p + kTwoAt, sizeof(V2));
    if constexpr (kOne) one = p[kOneAt];
  }
  void add(const double* p) {
    for (int i = 0; i < kFull; ++i) {
      VW v;
      std::memcpy(&v, p + kWide * i, sizeof(VW));
      full[i] += v;
    }
    if constexpr (kTwo) {
      V2 v;
      std::memcpy(&v, p + kTwoAt, sizeof(V2));
      two += v;
    }
    if constexpr (kOne) one += p[kOneAt];
  }
  void sub(const double* p) {
    for (int i = 0; i < kFull; ++i) {
      VW v;
      std::memcpy(&v, p + kWide * i, sizeof(VW));
      full[i] -= v;
    }
    if constexpr (kTwo) {
      V2 v;
      std::memcpy(&v, p + kTwoAt, sizeof(V2));
      two -= v;
    }
    if constexpr (kOne) one -= p[kOneAt];
  }
  void store(double* p) const {
    for (int i = 0; i < kFull; ++i) std::memcpy(p + kWide * i, &full[i], sizeof(VW));
    if constexpr (kTwo) std::memcpy(p + kTwoAt, &two, sizeof(V2));
    if constexpr (kOne) p[kOneAt] = one;
  }
};

/// Sliding window of half-width w over one run of `len` elements, element u of the run at
/// in/out + idx(u) * K: out_t = sum of in_u over |u - t| <= w. O(1) per element and channel: the
/// window of element t is that of t - 1 plus element t + w, minus element t - w - 1.
template <int K, typename Index>
inline void slideRun(const double* in, double* out, std::ptrdiff_t len, std::ptrdiff_t w, Index idx) {
  Accumulator<K> acc;
  acc.zero();
  // window of element 0: [0, min(w, len-1)]
  const std::ptrdiff_t first = std::min(w, len - 1);
  for (std::ptrdiff_t u = 0; u <= first; ++u) acc.add(in + idx(u) * K);
  acc.store(out + idx(0) * K);
  std::ptrdiff_t t = 1;
  for (; t < len && t <= w; ++t) {  // nothing leaves yet
    if (t + w < len) acc.add(in + idx(t + w) * K);
    acc.store(out + idx(t) * K);
  }
  for (; t + w < len; ++t) {  // one enters, one leaves
    acc.add(in + idx(t + w) * K);
    acc.sub(in + idx(t - w - 1) * K);
    acc.store(out + idx(t) * K);
  }
  for (; t < len; ++t) {  // nothing enters any more
    acc.sub(in + idx(t - w - 1) * K);
    acc.store(out + idx(t) * K);
  }
}

/// One sliding-window pass over every run along `axis`, for a compile-time channel count.
template <int K>
void windowPassK(const Lattice& lattice, int axis, const double* in, double* out, int threads) {
  const auto& order = lattice.runOrder(axis);
  const auto& starts = lattice.runStarts(axis);
  const std::ptrdiff_t w = lattice.regionHalfWidth();
  const std::size_t runs = starts.size() - 1;
#pragma omp parallel for schedule(static) num_threads(threads) if (threads > 1)
  for (std::size_t q = 0; q < runs; ++q) {
    const std::uint32_t* run = order.data() + starts[q];
    const std::ptrdiff_t len = static_cast<std::ptrdiff_t>(starts[q + 1] - starts[q]);
    slideRun<K>(in, out, len, w, [run](std::ptrdiff_t u) { return static_cast<std::ptrdiff_t>(run[u]); });
  }
}

}  // namespace

void windowPass(const Lattice& lattice, int axis, const double* in, int K, double* out, int threads) {
  withChannels(K, [&](auto k) { windowPassK<decltype(k)::value>(lattice, axis, in, out, threads); });
}

void RegionSummer::gather(const std::vector<double>& in, int K, std::vector<double>& out) {
  out.resize(in.size());
  gather(in.data(), K, out.data());
}

void RegionSummer::scatter(const std::vector<double>& in, int K, std::vector<double>& out) {
  out.resize(in.size());
  scatter(in.data(), K, out.data());
}

SliceStreamSummer::SliceStreamSummer(const Lattice& lattice, int threads, std::size_t bandParticles)
    : RegionSummer(lattice.size()), lattice_(lattice), threads_(std::max(1, threads)) {
  const auto& cells = lattice.cells();
  const std::size_t n = cells.size();
  auto before = [](const Eigen::Vector3i& a, const Eigen::Vector3i& b) {
    return a.z() != b.z() ? a.z() < b.z() : a.y() != b.y() ? a.y() < b.y() : a.x() < b.x();
  };
  for (std::size_t p = 1; p < n; ++p)
    if (!before(cells[p - 1], cells[p]))
      throw std::invalid_argument("SliceStreamSummer: the lattice's particles must be sorted by (k, j, i)");

  // slices: one per z from the lowest to the highest occupied layer (empty ones allowed)
  const int zmin = cells.front().z();
  const std::size_t slices = static_cast<std::size_t>(cells.back().z() - zmin) + 1;
  sliceStart_.assign(slices + 1, 0);
  for (std::size_t p = 0; p < n; ++p) ++sliceStart_[static_cast<std::size_t>(cells[p].z() - zmin) + 1];
  for (std::size_t k = 0; k < slices; ++k) sliceStart_[k + 1] += sliceStart_[k];
  {
    const auto& starts = lattice.runStarts(0);
    for (std::size_t q = 0; q + 1 < starts.size(); ++q) maxRun_ = std::max<std::size_t>(maxRun_, starts[q + 1] - starts[q]);
  }
  // x- and y-runs lie in one slice and are listed in the order of their first particle
  for (int axis = 0; axis < 2; ++axis) {
    auto& sliceRun = axis == 0 ? sliceXRun_ : sliceYRun_;
    const auto& order = lattice.runOrder(axis);
    const auto& starts = lattice.runStarts(axis);
    sliceRun.assign(slices + 1, static_cast<std::uint32_t>(starts.size() - 1));
    for (std::size_t q = starts.size() - 1; q-- > 0;)
      sliceRun[static_cast<std::size_t>(cells[order[starts[q]]].z() - zmin)] = static_cast<std::uint32_t>(q);
    for (std::size_t k = slices; k-- > 0;) sliceRun[k] = std::min(sliceRun[k], sliceRun[k + 1]);
  }
  {
    const auto& starts = lattice.runStarts(2);
    zPos_.resize(n);
    zLen_.resize(n);
    zBase_.resize(n);
    const auto& order = lattice.runOrder(2);
    for (std::size_t q = 0; q + 1 < starts.size(); ++q)
      for (std::uint32_t e = starts[q]; e < starts[q + 1]; ++e) {
        zPos_[order[e]] = e - starts[q];
        zLen_[order[e]] = starts[q + 1] - starts[q];
        zBase_[order[e]] = starts[q];
      }
  }
  // rows: the particles of slice k in row j are [rowStart(k, j), rowStart(k, j + 1))
  {
    int ymin = cells.front().y(), ymax = ymin;
    for (const auto& c : cells) {
      ymin = std::min(ymin, c.y());
      ymax = std::max(ymax, c.y());
    }
    rows_ = ymax - ymin + 1;
    const std::size_t R = static_cast<std::size_t>(rows_) + 1;
    rowStart_.assign(slices * R, 0);
    for (std::size_t p = 0; p < n; ++p)
      ++rowStart_[static_cast<std::size_t>(cells[p].z() - zmin) * R + static_cast<std::size_t>(cells[p].y() - ymin) + 1];
    for (std::size_t k = 0; k < slices; ++k) {
      rowStart_[k * R] = sliceStart_[k];
      for (std::size_t j = 1; j < R; ++j) rowStart_[k * R + j] += rowStart_[k * R + j - 1];
    }
  }
  makeBands(bandParticles);
  // threads take whole blocks, about the same number of particles each
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
  sliceScratch_.resize(static_cast<std::size_t>(threads_));
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

// One band when the whole slices fit in `bandParticles`. Otherwise as few bands as keep the
// widest slice of every band's data rows (halo included) within min(bandParticles,
// kBandTarget) particles, as even as that count allows, and each at least 2w rows high, so that
// the region rows a band leaves to the next one are its own.
void SliceStreamSummer::makeBands(std::size_t bandParticles) {
  const int w = lattice_.regionHalfWidth();
  const std::size_t slices = sliceStart_.size() - 1;
  auto widest = [&](int y0, int y1) {  // the largest slice of rows [y0, y1), clipped to the lattice
    y0 = std::max(y0, 0);
    y1 = std::min(y1, rows_);
    std::size_t most = 0;
    for (std::size_t k = 0; k < slices && y0 < y1; ++k) most = std::max<std::size_t>(most, rowStart(k, y1) - rowStart(k, y0));
    return most;
  };
  // bands from the bottom up, each as high as `most` allows (and at least 2w rows)
  auto greedy = [&](std::size_t most, std::vector<int>& bands) {
    bands.assign(1, 0);
    for (int y0 = 0; y0 < rows_;) {
      int y1 = std::min(y0 + 2 * w, rows_);
      while (y1 < rows_ && widest(y0 - w, y1 + 1 + w) <= most) ++y1;
      bands.push_back(y1);
      y0 = y1;
    }
  };
  if (widest(0, rows_) <= bandParticles) {
    bandY_ = {0, rows_};
  } else {
    const std::size_t bound = std::min(bandParticles, kBandTarget);
    greedy(bound, bandY_);
    // the smallest bound that needs no more bands evens them out (the greedy bands' last one
    // can be a sliver that costs its halo for little)
    const std::size_t count = bandY_.size() - 1;
    std::vector<int> trial;
    std::size_t lo = 1, hi = bound;
    while (lo < hi) {
      const std::size_t mid = lo + (hi - lo) / 2;
      greedy(mid, trial);
      if (trial.size() - 1 <= count) hi = mid;
      else lo = mid + 1;
    }
    greedy(lo, bandY_);
  }
  const std::size_t bands = bandCount();
  maxData_ = maxRegion_ = maxScatter_ = 0;
  for (std::size_t b = 0; b < bands; ++b) {
    const int y0 = bandY_[b], y1 = bandY_[b + 1];
    maxData_ = std::max(maxData_, widest(y0 - w, y1 + w));
    maxRegion_ = std::max(maxRegion_, widest(y0, y1));
    maxScatter_ = std::max(maxScatter_, widest(y0 - 2 * w, y1));
  }
  boundaryBase_.assign((bands - 1) * slices + 1, 0);
  std::size_t total = 0;
  for (std::size_t b = 1; b < bands; ++b)
    for (std::size_t k = 0; k < slices; ++k) {
      boundaryBase_[(b - 1) * slices + k] = total;
      total += rowStart(k, bandY_[b]) - rowStart(k, bandY_[b] - 2 * w);
    }
  boundaryBase_.back() = total;
}

void SliceStreamSummer::reserveSliceScratch(int Kg, int Ks) {
  if (Kg <= scratchKg_ && Ks <= scratchKs_) return;
  scratchKg_ = std::max(scratchKg_, Kg);
  scratchKs_ = std::max(scratchKs_, Ks);
  const std::size_t g = maxData_ * static_cast<std::size_t>(scratchKg_);
  const std::size_t r = maxRegion_ * static_cast<std::size_t>(scratchKg_);
  const std::size_t s = maxScatter_ * static_cast<std::size_t>(scratchKs_);
  const std::size_t ring = 2 * static_cast<std::size_t>(lattice_.regionHalfWidth()) + 2;
  for (SliceScratch& t : sliceScratch_) {
    t.run.resize(maxRun_ * static_cast<std::size_t>(std::max(scratchKg_, scratchKs_)));
    t.rowSum.resize(g);
    t.ring.resize(ring * g);
    t.sumPrev.resize(r);
    t.sumCur.resize(r);
    t.zPrev.resize(s);
    t.zCur.resize(s);
    t.colSum.resize(s);
    t.regionRing.resize(ring * s);
  }
  boundaryStore_.resize(boundaryBase_.back() * static_cast<std::size_t>(scratchKs_));
  // With one thread every region slice lives in the ring (and the boundary store) only.
  if (threads_ > 1) regionOut_.resize(particles_ * static_cast<std::size_t>(scratchKs_));
}

namespace {

/// The sliding z-window for the particles [p0, p1) of slice s (some rows of it), element (p,
/// slice k) of the source at src(p, k): out row of p = sum over p's z-run within |dz| <= w, at
/// out + (p - p0) * K. A restart (or a run's first element) sums the window directly; otherwise
/// the row of p's lower neighbour q in `prev` (the same rows of slice s - 1, q at prev + (q -
/// prevBase) * K) is updated by the element entering and the one leaving, as in slideRun().
template <int K, typename Source>
inline void zWindowRows(std::size_t s, std::uint32_t p0, std::uint32_t p1, std::uint32_t prevBase, bool restart,
                        std::ptrdiff_t w, const std::uint32_t* order, const std::uint32_t* zPos,
                        const std::uint32_t* zLen, const std::uint32_t* zBase, Source src, const double* prev,
                        double* out) {
  const std::ptrdiff_t k = static_cast<std::ptrdiff_t>(s);
  for (std::uint32_t p = p0; p < p1; ++p) {
    const std::ptrdiff_t t = zPos[p], len = zLen[p];
    const std::uint32_t* run = order + zBase[p];
    Accumulator<K> acc;
    if (restart || t == 0) {
      acc.zero();
      const std::ptrdiff_t lo = std::max(-w, -t), hi = std::min(w, len - 1 - t);
      for (std::ptrdiff_t d = lo; d <= hi; ++d) acc.add(src(run[t + d], k + d));
    } else {
      acc.set(prev + static_cast<std::size_t>(run[t - 1] - prevBase) * K);
      if (t + w < len) acc.add(src(run[t + w], k + w));
      if (t - w - 1 >= 0) acc.sub(src(run[t - w - 1], k - w - 1));
    }
    acc.store(out + static_cast<std::size_t>(p - p0) * K);
  }
}

}  // namespace

template <typename Published, typename Drain>
void SliceStreamSummer::applyChunk(RegionKernel& kernel, int Kg, int Ks, std::size_t k0, std::size_t k1,
                           SliceScratch& t, Published published, Drain drain) {
  const std::ptrdiff_t w = lattice_.regionHalfWidth();
  const int wr = static_cast<int>(w);
  const std::ptrdiff_t slices = static_cast<std::ptrdiff_t>(sliceStart_.size()) - 1;
  const std::ptrdiff_t lo = static_cast<std::ptrdiff_t>(k0), hi = static_cast<std::ptrdiff_t>(k1);
  const std::size_t ringSize = 2 * static_cast<std::size_t>(w) + 2;
  const std::size_t bands = bandCount();
  const std::uint32_t* sliceStart = sliceStart_.data();
  const auto& xStarts = lattice_.runStarts(0);
  const auto& yStarts = lattice_.runStarts(1);
  const auto& xOrder = lattice_.runOrder(0);
  const auto& yOrder = lattice_.runOrder(1);
  const std::uint32_t* zOrder = lattice_.runOrder(2).data();

  // The current band's rows (see the class comment): regions [yR0, yR1), their data [yD0, yD1),
  // the regions the scatter reads [yN0, yR1), the particle results [yP0, yP1).
  std::size_t band = 0;
  int yR0 = 0, yR1 = 0, yD0 = 0, yD1 = 0, yN0 = 0, yP0 = 0, yP1 = 0;
  auto setBand = [&](std::size_t b) {
    band = b;
    yR0 = bandY_[b];
    yR1 = bandY_[b + 1];
    yD0 = std::max(0, yR0 - wr);
    yD1 = std::min(rows_, yR1 + wr);
    yN0 = std::max(0, yR0 - 2 * wr);
    yP0 = b == 0 ? 0 : yR0 - wr;
    yP1 = b + 1 == bands ? rows_ : yR1 - wr;
  };

  // Sliding windows over the y-runs of slice k within the particles [i0, i1) (whole rows), from
  // and to rows at (p - i0) * K. A run cut by the range gives the right sums for the rows at least
  // w inside it, which are the rows the caller reads.
  auto yPass = [&](std::size_t k, std::uint32_t i0, std::uint32_t i1, int K, const double* in, double* out) {
    const bool whole = i0 == sliceStart[k] && i1 == sliceStart[k + 1];
    withChannels(K, [&](auto kc) {
      constexpr int KK = decltype(kc)::value;
      for (std::uint32_t q = sliceYRun_[k]; q < sliceYRun_[k + 1]; ++q) {
        const std::uint32_t* run = yOrder.data() + yStarts[q];
        const std::uint32_t* end = yOrder.data() + yStarts[q + 1];
        if (!whole) {
          if (run[0] >= i1) break;  // the runs are listed in the order of their first particle
          if (end[-1] < i0) continue;
          run = std::lower_bound(run, end, i0);
          end = std::lower_bound(run, end, i1);
          if (end == run) continue;
        }
        slideRun<KK>(in, out, end - run, w,
                     [run, i0](std::ptrdiff_t u) { return static_cast<std::ptrdiff_t>(run[u] - i0); });
      }
    });
  };
  // The x-runs of slice k within the particles [i0, i1) (each a range of consecutive particles),
  // one at a time through the run-sized buffer t.run: the gather's data is generated run by run
  // and summed along x into `out`; the scatter's rows of `in` are summed along x and handed to
  // the kernel's particle result run by run. No slice-sized buffer between the kernel and the
  // window passes.
  auto forXRuns = [&](std::size_t k, std::uint32_t i0, std::uint32_t i1, int K, auto&& body) {
    std::uint32_t q0 = sliceXRun_[k], q1 = sliceXRun_[k + 1];
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
  };
  auto xGather = [&](std::size_t k, double* out) {
    const std::uint32_t i0 = rowStart(k, yD0);
    forXRuns(k, i0, rowStart(k, yD1), Kg, [&](auto kc, std::uint32_t first, std::ptrdiff_t len) {
      constexpr int KK = decltype(kc)::value;
      kernel.particleData(first, first + static_cast<std::size_t>(len), t.run.data());
      slideRun<KK>(t.run.data(), out + static_cast<std::size_t>(first - i0) * KK, len, w,
                   [](std::ptrdiff_t u) { return u; });
    });
  };
  auto xScatter = [&](std::size_t k, const double* in) {
    const std::uint32_t n0 = rowStart(k, yN0);
    forXRuns(k, rowStart(k, yP0), rowStart(k, yP1), Ks, [&](auto kc, std::uint32_t first, std::ptrdiff_t len) {
      constexpr int KK = decltype(kc)::value;
      slideRun<KK>(in + static_cast<std::size_t>(first - n0) * KK, t.run.data(), len, w,
                   [](std::ptrdiff_t u) { return u; });
      kernel.particleResult(first, first + static_cast<std::size_t>(len), t.run.data());
    });
  };
  const std::size_t dataStride = maxData_ * static_cast<std::size_t>(Kg);
  auto ringRow = [&](std::ptrdiff_t k) { return t.ring.data() + (static_cast<std::size_t>(k) % ringSize) * dataStride; };
  // Region data of slice k, from row yN0 on: in the thread's ring of 2w + 2 slices (a particle
  // slice's z-window reads w slices either side and, when it slides, the one leaving), or for
  // the slices that a block left to drain() may read, in the shared regionOut_
  // (indexed by particle).
  auto shared = [&](std::size_t z) { return !sharedSlice_.empty() && sharedSlice_[z] != 0; };
  auto regionRow = [&](std::ptrdiff_t k) {
    const std::size_t z = static_cast<std::size_t>(k);
    if (!shared(z)) return t.regionRing.data() + (z % ringSize) * maxScatter_ * static_cast<std::size_t>(Ks);
    return regionOut_.data() + static_cast<std::size_t>(rowStart(z, yN0)) * Ks;
  };
  // gather: data of slice a, summed along x and y into the ring
  auto dataSlice = [&](std::ptrdiff_t a) {
    const std::size_t k = static_cast<std::size_t>(a);
    xGather(k, t.rowSum.data());
    yPass(k, rowStart(k, yD0), rowStart(k, yD1), Kg, t.rowSum.data(), ringRow(a));
  };
  // gather's z-window, then the kernel's region data for slice b; the region rows below the
  // band (left by the band below) and those the band above will need go between the ring and
  // the boundary store
  auto regionSlice = [&](std::ptrdiff_t b) {
    const std::size_t k = static_cast<std::size_t>(b);
    const std::uint32_t r0 = rowStart(k, yR0), r1 = rowStart(k, yR1);
    withChannels(Kg, [&](auto kc) {
      constexpr int KK = decltype(kc)::value;
      const double* ring = t.ring.data();
      auto src = [&](std::uint32_t p, std::ptrdiff_t z) {
        const std::size_t slot = static_cast<std::size_t>(z) % ringSize;
        return ring + slot * dataStride + static_cast<std::size_t>(p - rowStart(static_cast<std::size_t>(z), yD0)) * KK;
      };
      zWindowRows<KK>(k, r0, r1, k > 0 ? rowStart(k - 1, yR0) : 0, b % kBlock == 0, w, zOrder, zPos_.data(),
                      zLen_.data(), zBase_.data(), src, t.sumPrev.data(), t.sumCur.data());
    });
    double* regions = regionRow(b);
    const std::uint32_t n0 = rowStart(k, yN0);
    kernel.regionData(r0, r1, t.sumCur.data(), regions + static_cast<std::size_t>(r0 - n0) * Ks);
    if (!shared(k)) {
      const std::size_t perBand = static_cast<std::size_t>(slices);
      if (band > 0)  // rows [yR0 - 2w, yR0) = [yN0, yR0)
        std::memcpy(regions, boundaryStore_.data() + boundaryBase_[(band - 1) * perBand + k] * Ks,
                    sizeof(double) * (r0 - n0) * static_cast<std::size_t>(Ks));
      if (band + 1 < bands) {  // rows [yR1 - 2w, yR1)
        const std::uint32_t top = rowStart(k, yR1 - 2 * wr);
        std::memcpy(boundaryStore_.data() + boundaryBase_[band * perBand + k] * Ks,
                    regions + static_cast<std::size_t>(top - n0) * Ks, sizeof(double) * (r1 - top) * static_cast<std::size_t>(Ks));
      }
    }
    std::swap(t.sumPrev, t.sumCur);
  };
  // scatter's z-window over the region data, then y and x, then the kernel's particle result
  auto particleSlice = [&](std::ptrdiff_t c) {
    const std::size_t k = static_cast<std::size_t>(c);
    const std::uint32_t n0 = rowStart(k, yN0), n1 = rowStart(k, yR1);
    withChannels(Ks, [&](auto kc) {
      constexpr int KK = decltype(kc)::value;
      auto src = [&](std::uint32_t p, std::ptrdiff_t z) {
        return regionRow(z) + static_cast<std::size_t>(p - rowStart(static_cast<std::size_t>(z), yN0)) * KK;
      };
      zWindowRows<KK>(k, n0, n1, k > 0 ? rowStart(k - 1, yN0) : 0, c % kBlock == 0, w, zOrder, zPos_.data(),
                      zLen_.data(), zBase_.data(), src, t.zPrev.data(), t.zCur.data());
    });
    yPass(k, n0, n1, Ks, t.zCur.data(), t.colSum.data());
    xScatter(k, t.colSum.data());
    std::swap(t.zPrev, t.zCur);
  };
  // A block of particle slices [c, c + kBlock) reads region slices [c - w, c + kBlock - 1 + w]:
  // near another chunk it is left to drain() (ownsBlock(); listDeferred() lists the same blocks).
  auto ownBlock = [&](std::ptrdiff_t c) {
    const std::ptrdiff_t first = c - c % kBlock;
    return ownsBlock(first, std::min(first + kBlock, hi) - 1, lo, hi);
  };

  for (std::size_t b = 0; b < bands; ++b) {
    setBand(b);
    for (std::ptrdiff_t a = lo - w; a < hi + 2 * w; ++a) {
      if (a >= 0 && a < slices && a < hi + w) dataSlice(a);
      const std::ptrdiff_t r = a - w;
      if (r >= lo && r < hi) {
        regionSlice(r);
        published(b, static_cast<std::size_t>(r));
      }
      const std::ptrdiff_t c = r - w;
      if (c >= lo && c < hi && ownBlock(c)) particleSlice(c);
    }
    published(b, static_cast<std::size_t>(slices));
  }
  drain([&](std::size_t b, std::size_t c0, std::size_t c1) {
    setBand(b);
    for (std::size_t c = c0; c < c1; ++c) particleSlice(static_cast<std::ptrdiff_t>(c));
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
    applyChunk(kernel, Kg, Ks, 0, slices, sliceScratch_[0], unpublished, nothingLeft);
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
      if (th == 0) applyChunk(kernel, Kg, Ks, 0, slices, sliceScratch_[0], unpublished, nothingLeft);
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
      applyChunk(kernel, Kg, Ks, chunkStart_[me], chunkStart_[me + 1], sliceScratch_[me], publish, drain);
    }
  }
  rebalance();
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

NaiveSummer::NaiveSummer(const Lattice& lattice) : RegionSummer(lattice.size()) {
  const std::size_t n = lattice.size();
  offsets_.reserve(n + 1);
  offsets_.push_back(0);
  std::vector<std::uint32_t> m;
  for (std::size_t r = 0; r < n; ++r) {
    lattice.regionMembers(r, m);
    members_.insert(members_.end(), m.begin(), m.end());
    offsets_.push_back(static_cast<std::uint32_t>(members_.size()));
  }
}

void NaiveSummer::apply(RegionKernel& kernel) {
  const std::size_t Kg = static_cast<std::size_t>(kernel.gatherChannels());
  const std::size_t Ks = static_cast<std::size_t>(kernel.scatterChannels());
  data_.resize(particles_ * Kg);
  sums_.resize(particles_ * Kg);
  regionOut_.resize(particles_ * Ks);
  result_.resize(particles_ * Ks);
  kernel.particleData(0, particles_, data_.data());
  gather(data_.data(), static_cast<int>(Kg), sums_.data());
  kernel.regionData(0, particles_, sums_.data(), regionOut_.data());
  scatter(regionOut_.data(), static_cast<int>(Ks), result_.data());
  kernel.particleResult(0, particles_, result_.data());
}

void NaiveSummer::gather(const double* in, int K, double* out) {
  std::fill(out, out + particles_ * static_cast<std::size_t>(K), 0.0);
  for (std::size_t r = 0; r < particles_; ++r) {
    double* dst = out + r * K;
    for (std::uint32_t e = offsets_[r]; e < offsets_[r + 1]; ++e) {
      const double* src = in + static_cast<std::size_t>(members_[e]) * K;
      for (int c = 0; c < K; ++c) dst[c] += src[c];
    }
  }
}

void NaiveSummer::scatter(const double* in, int K, double* out) {
  std::fill(out, out + particles_ * static_cast<std::size_t>(K), 0.0);
  for (std::size_t r = 0; r < particles_; ++r) {
    const double* src = in + r * K;
    for (std::uint32_t e = offsets_[r]; e < offsets_[r + 1]; ++e) {
      double* dst = out + static_cast<std::size_t>(members_[e]) * K;
      for (int c = 0; c < K; ++c) dst[c] += src[c];
    }
  }
}

}  // namespace deformable_flsm
