#include "deformable_flsm/core/naive_summer.h"

#include <algorithm>

namespace deformable_flsm {

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
