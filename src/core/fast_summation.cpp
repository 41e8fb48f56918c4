#include "deformable_flsm/core/fast_summation.h"

#include <algorithm>
#include <array>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

namespace {

/// One sliding-window pass for a compile-time channel count.
template <int K>
void windowPassK(const Lattice& lattice, int axis, const double* in, double* out, int threads) {
  const auto& order = lattice.runOrder(axis);
  const auto& starts = lattice.runStarts(axis);
  const std::ptrdiff_t w = lattice.regionHalfWidth();
  const std::size_t runs = starts.size() - 1;
#pragma omp parallel for schedule(static) num_threads(threads) if (threads > 1)
  for (std::size_t q = 0; q < runs; ++q) {
    std::array<double, K> acc;
    const std::uint32_t* run = order.data() + starts[q];
    const std::ptrdiff_t len = static_cast<std::ptrdiff_t>(starts[q + 1] - starts[q]);
    acc.fill(0.0);
    // window of element 0: [0, min(w, len-1)]
    const std::ptrdiff_t first = std::min(w, len - 1);
    for (std::ptrdiff_t u = 0; u <= first; ++u) {
      const double* src = in + static_cast<std::size_t>(run[u]) * K;
      for (int c = 0; c < K; ++c) acc[c] += src[c];
    }
    for (std::ptrdiff_t t = 0; t < len; ++t) {
      if (t > 0) {
        if (t + w < len) {
          const double* src = in + static_cast<std::size_t>(run[t + w]) * K;
          for (int c = 0; c < K; ++c) acc[c] += src[c];
        }
        if (t - w - 1 >= 0) {
          const double* src = in + static_cast<std::size_t>(run[t - w - 1]) * K;
          for (int c = 0; c < K; ++c) acc[c] -= src[c];
        }
      }
      double* dst = out + static_cast<std::size_t>(run[t]) * K;
      for (int c = 0; c < K; ++c) dst[c] = acc[c];
    }
  }
}

}  // namespace

void windowPass(const Lattice& lattice, int axis, const double* in, int K, double* out, int threads) {
  switch (K) {
    case 1: return windowPassK<1>(lattice, axis, in, out, threads);
    case 3: return windowPassK<3>(lattice, axis, in, out, threads);
    case 6: return windowPassK<6>(lattice, axis, in, out, threads);
    case 12: return windowPassK<12>(lattice, axis, in, out, threads);
    case 18: return windowPassK<18>(lattice, axis, in, out, threads);
    case 24: return windowPassK<24>(lattice, axis, in, out, threads);
    default: break;
  }
  throw std::invalid_argument("windowPass: unsupported channel count " + std::to_string(K));
}

void RegionSummer::gather(const std::vector<double>& in, int K, std::vector<double>& out) {
  out.resize(in.size());
  gather(in.data(), K, out.data());
}

void RegionSummer::scatter(const std::vector<double>& in, int K, std::vector<double>& out) {
  out.resize(in.size());
  scatter(in.data(), K, out.data());
}

BarSummer::BarSummer(const Lattice& lattice, int threads)
    : RegionSummer(lattice.size()), lattice_(lattice), threads_(std::max(1, threads)) {}

void BarSummer::reserveScratch(int K) {
  const std::size_t size = particles_ * static_cast<std::size_t>(K);
  if (tmpA_.size() < size) {
    tmpA_.resize(size);
    tmpB_.resize(size);
  }
}

void BarSummer::gather(const double* in, int K, double* out) {
  reserveScratch(K);
  windowPass(lattice_, 0, in, K, tmpA_.data(), threads_);
  windowPass(lattice_, 1, tmpA_.data(), K, tmpB_.data(), threads_);
  windowPass(lattice_, 2, tmpB_.data(), K, out, threads_);
}

void BarSummer::scatter(const double* in, int K, double* out) {
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
