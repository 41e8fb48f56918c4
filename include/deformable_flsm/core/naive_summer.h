/// @file naive_summer.h
/// Direct region sums over explicit member lists: the oracle the fast summation is tested against.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/region_summer.h"

#include <cstdint>
#include <vector>

namespace deformable_flsm {

/// Direct summation over explicit member lists: O(w^3) per particle. The oracle.
class NaiveSummer : public RegionSummer {
 public:
  explicit NaiveSummer(const Lattice& lattice);
  using RegionSummer::gather;
  using RegionSummer::scatter;
  void gather(const double* in, int K, double* out) override;
  void scatter(const double* in, int K, double* out) override;
  void apply(RegionKernel& kernel) override;
  /// Total number of (region, member) pairs.
  std::size_t memberCount() const { return members_.size(); }

 private:
  std::vector<std::uint32_t> offsets_;  // CSR: region r's members in [offsets_[r], offsets_[r+1])
  std::vector<std::uint32_t> members_;
  std::vector<double> data_, sums_, regionOut_, result_;  // apply() scratch
};

}  // namespace deformable_flsm
