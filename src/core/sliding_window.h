/// @file sliding_window.h
/// The sliding-window primitives of the region sums (private to the core): the channel-count
/// dispatch, SIMD running sums, the window along one run and the z-window of a slice's rows.
#pragma once

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <stdexcept>
#include <string>
#include <type_traits>

namespace deformable_flsm {
namespace detail {

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

/// The accumulators' vector width for this build's own code: 4 where the target has AVX, else 2
/// (GCC/Clang vector types wider than the target's registers are lowered poorly). Code run at a
/// level with AVX (withSimdWidth()) takes 4.
#ifdef __AVX__
constexpr int kBuiltWide = 4;
#else
constexpr int kBuiltWide = 2;
#endif

/// K running sums held in SIMD registers: K / W vectors of W doubles (W 2 or 4), then a two-wide
/// vector and a scalar for the rest. Rows are loaded and stored unaligned.
template <int K, int W = kBuiltWide>
struct Accumulator {
  static_assert(W == 2 || W == 4, "two or four lanes");
  static constexpr int kWide = W;
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
template <int K, int W = kBuiltWide, typename Index>
inline void slideRun(const double* in, double* out, std::ptrdiff_t len, std::ptrdiff_t w, Index idx) {
  Accumulator<K, W> acc;
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

/// The sliding z-window for the particles [p0, p1) of slice s (some rows of it), element (p,
/// slice k) of the source at src(p, k): out row of p = sum over p's z-run within |dz| <= w, at
/// out + (p - p0) * K. A restart (or a run's first element) sums the window directly; otherwise
/// the row of p's lower neighbour q in `prev` (the same rows of slice s - 1, q at prev + (q -
/// prevBase) * K) is updated by the element entering and the one leaving, as in slideRun().
template <int K, int W = kBuiltWide, typename Source>
inline void zWindowRows(std::size_t s, std::uint32_t p0, std::uint32_t p1, std::uint32_t prevBase, bool restart,
                        std::ptrdiff_t w, const std::uint32_t* order, const std::uint32_t* zPos,
                        const std::uint32_t* zLen, const std::uint32_t* zBase, Source src, const double* prev,
                        double* out) {
  const std::ptrdiff_t k = static_cast<std::ptrdiff_t>(s);
  for (std::uint32_t p = p0; p < p1; ++p) {
    const std::ptrdiff_t t = zPos[p], len = zLen[p];
    const std::uint32_t* run = order + zBase[p];
    Accumulator<K, W> acc;
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

}  // namespace detail
}  // namespace deformable_flsm
