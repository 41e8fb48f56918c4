/// @file region_summer.h
/// The region-sum interface: what a region pass computes (RegionKernel) and the summers that
/// run it (RegionSummer; SliceStreamSummer is FastLSM's, NaiveSummer the direct oracle).
#pragma once

#include <cstddef>
#include <vector>

namespace deformable_flsm {

/// What one region pass computes, in the three steps FastLSM's summation interleaves:
///  1. particleData:   K_g doubles per particle, summed over every region (gather);
///  2. regionData:     from region r's sums, K_s doubles per region, summed over the regions that
///                     contain each particle (scatter);
///  3. particleResult: what each particle does with its scatter sums.
/// Every range is a contiguous range of particle (= region) indices; data for index p sits at
/// (p - begin) * K in the buffer passed. regionData and particleResult visit each index exactly
/// once per pass; particleData may visit an index more than once (SliceStreamSummer: the halo slices of
/// threads, concurrently, and the halo rows of bands), so it must only read. Calls for disjoint ranges may run
/// concurrently, so an implementation must only write what belongs to the indices of its range;
/// SliceStreamSummer never runs particleData on particles whose particleResult of the same pass has run
/// or is running.
class RegionKernel {
 public:
  virtual ~RegionKernel() = default;
  /// K_g and K_s: 1, 3, 6, 12, 18 or 24
  virtual int gatherChannels() const = 0;
  virtual int scatterChannels() const = 0;
  /// @param[out] out  (end - begin) * K_g doubles, particle p's at (p - begin) * K_g
  virtual void particleData(std::size_t begin, std::size_t end, double* out) = 0;
  /// @param[in]  sums  region r's gathered sums at (r - begin) * K_g
  /// @param[out] out   region r's K_s doubles at (r - begin) * K_s
  virtual void regionData(std::size_t begin, std::size_t end, const double* sums, double* out) = 0;
  /// @param[in] sums  particle i's scatter sums at (i - begin) * K_s
  virtual void particleResult(std::size_t begin, std::size_t end, const double* sums) = 0;
};

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

  /// One region pass: gather of kernel.particleData, kernel.regionData on the sums, scatter of
  /// its output, kernel.particleResult on those. Allocates only the first time (scratch grows).
  virtual void apply(RegionKernel& kernel) = 0;

  /// Conveniences on vectors of #P*K values; `out` is resized.
  void gather(const std::vector<double>& in, int K, std::vector<double>& out);
  void scatter(const std::vector<double>& in, int K, std::vector<double>& out);

 protected:
  std::size_t particles_;
};

}  // namespace deformable_flsm
