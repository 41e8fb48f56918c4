/// @file fast_summation.h
/// Region sums: FastLSM's separable bar summation and the direct (naive) summation.
#pragma once

#include "deformable_flsm/core/lattice.h"

#include <cstdint>
#include <vector>

namespace deformable_flsm {

/// One sliding-window pass along `axis`: out_p = sum of in_q over the particles q of p's run with
/// |q - p| <= w along the axis (w = lattice.regionHalfWidth()). O(1) per particle and channel.
/// @param[in]  in   #P*K particle-major data
/// @param[in]  K    channels per particle (1, 3, 6, 12, 18 or 24)
/// @param[out] out  #P*K window sums (must not alias `in`)
/// @param[in]  threads  OpenMP threads splitting the runs (the result does not depend on it)
void windowPass(const Lattice& lattice, int axis, const double* in, int K, double* out, int threads = 1);

/// Sums K doubles per particle over regions, both ways:
///  - gather:  S_r = sum_{j in R_r} f_j        (region sums of particle data)
///  - scatter: G_i = sum_{r : i in R_r} h_r    (per-particle sums of region data)
/// Data is laid out particle-major: element (p, c) at data[p * K + c].
class RegionSummer {
 public:
  /// @param[in] particles  #P, the lattice's particle count
  explicit RegionSummer(std::size_t particles) : particles_(particles) {}
  virtual ~RegionSummer() = default;
  /// @param[in]  in   #P*K particle data
  /// @param[out] out  #P*K region sums (must not alias `in`)
  virtual void gather(const double* in, int K, double* out) = 0;
  /// @param[in]  in   #P*K region data
  /// @param[out] out  #P*K particle sums (must not alias `in`)
  virtual void scatter(const double* in, int K, double* out) = 0;

  /// Conveniences on vectors of #P*K values; `out` is resized.
  void gather(const std::vector<double>& in, int K, std::vector<double>& out);
  void scatter(const std::vector<double>& in, int K, std::vector<double>& out);

 protected:
  std::size_t particles_;
};

/// FastLSM (Rivers & James 2007, sec. 4): sums along x-runs, then y-runs, then z-runs, each a
/// sliding window of half-width w over the run, O(1) per particle and channel whatever w.
/// Scatter applies the same windows in reverse order (z, y, x): the windows are symmetric, so
/// this is the transpose of gather.
class BarSummer : public RegionSummer {
 public:
  /// @param[in] threads  OpenMP threads per pass (>= 1); results are identical for any count
  explicit BarSummer(const Lattice& lattice, int threads = 1);
  using RegionSummer::gather;
  using RegionSummer::scatter;
  void gather(const double* in, int K, double* out) override;
  void scatter(const double* in, int K, double* out) override;

 private:
  /// Grows the two scratch buffers to #P*K; never shrinks them (no refill between passes).
  void reserveScratch(int K);
  const Lattice& lattice_;
  int threads_;
  std::vector<double> tmpA_, tmpB_;
};

/// Direct summation over explicit member lists: O(w^3) per particle. The oracle.
class NaiveSummer : public RegionSummer {
 public:
  explicit NaiveSummer(const Lattice& lattice);
  using RegionSummer::gather;
  using RegionSummer::scatter;
  void gather(const double* in, int K, double* out) override;
  void scatter(const double* in, int K, double* out) override;
  /// Total number of (region, member) pairs.
  std::size_t memberCount() const { return members_.size(); }

 private:
  std::vector<std::uint32_t> offsets_;  // CSR: region r's members in [offsets_[r], offsets_[r+1])
  std::vector<std::uint32_t> members_;
};

}  // namespace deformable_flsm
