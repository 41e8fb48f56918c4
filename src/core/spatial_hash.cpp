#include "deformable_flsm/core/spatial_hash.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace deformable_flsm {

void SpatialHash::reserve(std::size_t count) {
  std::size_t buckets = 64;
  while (buckets < 2 * count) buckets *= 2;
  if (start_.size() < buckets + 1) start_.resize(buckets + 1);
  if (entries_.size() < count) entries_.resize(count);
  if (pointBucket_.size() < count) pointBucket_.resize(count);
}

void SpatialHash::build(const std::vector<Eigen::Vector3d>& points, std::size_t count, double cellSize) {
  if (!(cellSize > 0.0) || !std::isfinite(cellSize))
    throw std::invalid_argument("spatial hash: the cell size must be positive and finite");
  if (count > points.size()) throw std::invalid_argument("spatial hash: more points asked for than given");
  cellSize_ = cellSize;
  invCell_ = 1.0 / cellSize;
  count_ = count;
  // at least twice as many buckets as points (a power of two): few cells share a bucket
  std::size_t buckets = 64;
  while (buckets < 2 * count) buckets *= 2;
  mask_ = static_cast<std::uint32_t>(buckets - 1);
  // the table in use is start_[0 .. buckets], even when start_ grew larger for a bigger build
  if (start_.size() < buckets + 1) start_.resize(buckets + 1);
  if (entries_.size() < count) entries_.resize(count);
  if (pointBucket_.size() < count) pointBucket_.resize(count);
  std::fill(start_.begin(), start_.begin() + static_cast<std::ptrdiff_t>(buckets + 1), 0u);
  // counting sort: counts, prefix sums, then each point at its bucket's next place (stable)
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint32_t b = bucketOf(cellOf(points[i]));
    pointBucket_[i] = b;
    ++start_[b + 1];
  }
  for (std::size_t b = 0; b < buckets; ++b) start_[b + 1] += start_[b];
  // start_[b] is used as the fill cursor, then restored from start_[b + 1] - size
  for (std::size_t i = 0; i < count; ++i) entries_[start_[pointBucket_[i]]++] = static_cast<std::uint32_t>(i);
  for (std::size_t b = buckets; b > 0; --b) start_[b] = start_[b - 1];
  start_[0] = 0;
}

}  // namespace deformable_flsm
