// SliceStreamSummer's layout of the lattice: slices (z), their x- and y-runs, rows (y), the
// z-runs per particle, and the bands of rows.
#include "deformable_flsm/core/slice_stream_summer.h"

#include <algorithm>
#include <stdexcept>

namespace deformable_flsm {

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
  initSchedule();
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

}  // namespace deformable_flsm
