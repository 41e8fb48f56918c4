/// @file spatial_hash.h
/// A uniform grid of cubic cells hashed into a table of buckets, for finding the points near a
/// point among many (Teschner et al. 2003, "Optimized Spatial Hashing for Collision Detection
/// of Deformable Objects"): built by a counting sort into buffers kept between builds, so that
/// rebuilding it every sub-step allocates nothing once they have grown.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

class SpatialHash {
 public:
  /// Sorts the first `count` points into cells of edge `cellSize` (m): point p is in cell
  /// floor(p / cellSize). Any two points closer than cellSize are in the same or adjacent
  /// cells, so forEachNear() finds them.
  /// @param[in] points    at least `count` points (m); finite
  /// @param[in] count     how many of them to sort
  /// @param[in] cellSize  > 0 (m)
  void build(const std::vector<Eigen::Vector3d>& points, std::size_t count, double cellSize);
  /// Grows the buffers for builds of up to `count` points, so that those allocate nothing.
  void reserve(std::size_t count);

  /// Calls f(j) for every point j sorted into the 27 cells around the cell of p, each bucket
  /// once, in a fixed order (the buckets' in increasing number, the points of a bucket in
  /// increasing index). Cells of other places that share a bucket add points that are far:
  /// the caller checks the distance.
  template <class F>
  void forEachNear(const Eigen::Vector3d& p, F&& f) const {
    if (count_ == 0) return;
    const Eigen::Vector3i c = cellOf(p);
    std::array<std::uint32_t, 27> buckets;
    int n = 0;
    for (int dz = -1; dz <= 1; ++dz)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
          const std::uint32_t b = bucketOf(Eigen::Vector3i(c.x() + dx, c.y() + dy, c.z() + dz));
          // insertion into the sorted list: a bucket two cells share is visited once
          int k = n;
          while (k > 0 && buckets[k - 1] > b) --k;
          if (k > 0 && buckets[k - 1] == b) continue;
          for (int m = n; m > k; --m) buckets[m] = buckets[m - 1];
          buckets[k] = b;
          ++n;
        }
    for (int k = 0; k < n; ++k)
      for (std::uint32_t e = start_[buckets[k]]; e < start_[buckets[k] + 1]; ++e) f(entries_[e]);
  }

  /// Calls f(j) for every point j sorted into the cells that the cube of half-edge `radius`
  /// around p meets (27 cells or fewer when radius <= cellSize()), each bucket once, in the
  /// order of forEachNear(). Finds every point closer to p than `radius`, and some farther.
  /// @param[in,out] scratch  the buckets' list, kept by the caller (no allocation once grown)
  template <class F>
  void forEachWithin(const Eigen::Vector3d& p, double radius, std::vector<std::uint32_t>& scratch, F&& f) const {
    if (count_ == 0) return;
    const Eigen::Vector3i lo = cellOf(p.array() - radius), hi = cellOf(p.array() + radius);
    scratch.clear();
    for (int z = lo.z(); z <= hi.z(); ++z)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int x = lo.x(); x <= hi.x(); ++x) scratch.push_back(bucketOf(Eigen::Vector3i(x, y, z)));
    std::sort(scratch.begin(), scratch.end());
    scratch.erase(std::unique(scratch.begin(), scratch.end()), scratch.end());
    for (std::uint32_t b : scratch)
      for (std::uint32_t e = start_[b]; e < start_[b + 1]; ++e) f(entries_[e]);
  }

  double cellSize() const { return cellSize_; }
  /// buckets of the last build (a power of two, at least twice its points)
  std::size_t bucketCount() const { return static_cast<std::size_t>(mask_) + 1; }

 private:
  Eigen::Vector3i cellOf(const Eigen::Vector3d& p) const {
    return Eigen::Vector3i(static_cast<int>(std::floor(p.x() * invCell_)), static_cast<int>(std::floor(p.y() * invCell_)),
                           static_cast<int>(std::floor(p.z() * invCell_)));
  }
  /// The three large primes of Teschner et al. 2003, xor-ed, masked to the table's size (a power of two).
  std::uint32_t bucketOf(const Eigen::Vector3i& c) const {
    const std::uint32_t h = (static_cast<std::uint32_t>(c.x()) * 73856093u) ^
                            (static_cast<std::uint32_t>(c.y()) * 19349663u) ^
                            (static_cast<std::uint32_t>(c.z()) * 83492791u);
    return h & mask_;
  }

  double cellSize_ = 1.0, invCell_ = 1.0;
  std::size_t count_ = 0;
  std::uint32_t mask_ = 0;
  std::vector<std::uint32_t> start_;     // per bucket b, its points are entries_[start_[b], start_[b + 1])
  std::vector<std::uint32_t> entries_;   // point indices, bucket by bucket
  std::vector<std::uint32_t> pointBucket_;  // per point, its bucket
};

}  // namespace deformable_flsm
