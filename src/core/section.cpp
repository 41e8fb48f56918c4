#include "deformable_flsm/core/section.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

namespace {

/// A dense grid over the occupied cells' bounding box with one empty cell of padding on every
/// side, so that the outside of the object is empty and every line starts and ends empty.
struct Grid {
  Eigen::Vector3i lo = Eigen::Vector3i::Zero();  // lattice coordinates of grid cell (1, 1, 1)
  Eigen::Vector3i n = Eigen::Vector3i::Zero();   // grid cells along x, y, z (padding included)
  std::size_t stride[3] = {0, 0, 0};

  std::size_t index(const Eigen::Vector3i& cell) const {
    const Eigen::Vector3i g = cell - lo + Eigen::Vector3i::Ones();
    return static_cast<std::size_t>(g.x()) + stride[1] * static_cast<std::size_t>(g.y()) +
           stride[2] * static_cast<std::size_t>(g.z());
  }
  std::size_t size() const { return stride[2] * static_cast<std::size_t>(n.z()); }
};

/// Calls f(first, count) for every grid line along `axis`: the indices first + s * stride[axis].
template <typename F>
void forEachLine(const Grid& g, int axis, F f) {
  const int a = (axis + 1) % 3, b = (axis + 2) % 3;
  for (int v = 0; v < g.n[b]; ++v)
    for (int u = 0; u < g.n[a]; ++u) f(g.stride[a] * static_cast<std::size_t>(u) + g.stride[b] * static_cast<std::size_t>(v));
}

/// 1-D squared distance transform of f (Felzenszwalb & Huttenlocher 2012): d[q] = min_p (q - p)^2
/// + f[p], the lower envelope of parabolas rooted at every p with f[p] finite. f is `count`
/// contiguous values, d a line of `count` values `step` apart (it may be where f was copied
/// from); v and z are scratch of count and count + 1 entries.
void distanceTransform1d(const float* f, float* d, std::size_t count, std::size_t step, int* v,
                         double* z) {
  constexpr float kInfF = std::numeric_limits<float>::infinity();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  int k = -1;
  for (int q = 0; q < static_cast<int>(count); ++q) {
    const double fq = f[q];
    if (fq == kInfF) continue;
    while (k >= 0) {
      const int p = v[k];
      const double fp = f[p];
      const double s = ((fq + q * q) - (fp + p * p)) / (2.0 * (q - p));
      if (s > z[k]) {
        ++k;
        v[k] = q;
        z[k] = s;
        break;
      }
      --k;
    }
    if (k < 0) {
      k = 0;
      v[0] = q;
      z[0] = -kInf;
    }
    z[k + 1] = kInf;
  }
  if (k < 0) {  // no finite value on the line
    for (std::size_t q = 0; q < count; ++q) d[step * q] = kInfF;
    return;
  }
  int j = 0;
  for (int q = 0; q < static_cast<int>(count); ++q) {
    while (z[j + 1] < q) ++j;
    const double dq = q - v[j];
    d[step * static_cast<std::size_t>(q)] = static_cast<float>(dq * dq + f[v[j]]);
  }
}

/// out = the cells of `in` dilated by `reach` along `axis`, without crossing empty cells: cell i
/// of a run of occupied cells is set when a set cell of the same run lies within `reach` of it.
void dilateAlongRuns(const Grid& g, const std::vector<char>& occupied, const std::vector<char>& in,
                     int axis, int reach, std::vector<char>& out) {
  const std::size_t step = g.stride[axis];
  const int count = g.n[axis];
  constexpr int kFar = std::numeric_limits<int>::max() / 2;
  forEachLine(g, axis, [&](std::size_t first) {
    // distance to the last set cell behind, within the run; then the same ahead
    int last = kFar;
    for (int s = 0; s < count; ++s) {
      const std::size_t i = first + step * static_cast<std::size_t>(s);
      if (!occupied[i]) {
        last = kFar;
        out[i] = 0;
        continue;
      }
      last = in[i] ? 0 : std::min(kFar, last + 1);
      out[i] = last <= reach ? 1 : 0;
    }
    last = kFar;
    for (int s = count - 1; s >= 0; --s) {
      const std::size_t i = first + step * static_cast<std::size_t>(s);
      if (!occupied[i]) {
        last = kFar;
        continue;
      }
      last = in[i] ? 0 : std::min(kFar, last + 1);
      if (last <= reach) out[i] = 1;
    }
  });
}

/// Stage 1 of measureSectionThickness(): the squared distance to the nearest empty cell centre
/// on `fine`, the half-cell grid of g (set here).
std::vector<float> squaredDistanceToEmpty(const Grid& g, const std::vector<char>& occupied, Grid& fine) {
  // 1. Squared distance to the nearest empty cell centre from every point of the half-cell grid
  // (cell centres, face centres, edge midpoints and corners: point r along an axis is at r / 2
  // in cell units, cell g's centre at r = 2 g + 1), three 1-D passes, in half cells.
  constexpr float kInf = std::numeric_limits<float>::infinity();
  fine.n = 2 * g.n + Eigen::Vector3i::Ones();
  fine.stride[0] = 1;
  fine.stride[1] = static_cast<std::size_t>(fine.n.x());
  fine.stride[2] = fine.stride[1] * static_cast<std::size_t>(fine.n.y());
  std::vector<float> d2(fine.size(), kInf);
  for (int k = 0; k < g.n.z(); ++k)
    for (int j = 0; j < g.n.y(); ++j)
      for (int i = 0; i < g.n.x(); ++i) {
        const std::size_t c = static_cast<std::size_t>(i) + g.stride[1] * static_cast<std::size_t>(j) +
                              g.stride[2] * static_cast<std::size_t>(k);
        if (!occupied[c])
          d2[static_cast<std::size_t>(2 * i + 1) + fine.stride[1] * static_cast<std::size_t>(2 * j + 1) +
             fine.stride[2] * static_cast<std::size_t>(2 * k + 1)] = 0.0f;
      }
  const int longest = fine.n.maxCoeff();
  std::vector<int> v(static_cast<std::size_t>(longest));
  std::vector<double> z(static_cast<std::size_t>(longest) + 1);
  std::vector<float> line(static_cast<std::size_t>(longest));
  for (int axis = 0; axis < 3; ++axis) {
    const std::size_t step = fine.stride[axis];
    const std::size_t count = static_cast<std::size_t>(fine.n[axis]);
    forEachLine(fine, axis, [&](std::size_t first) {
      for (std::size_t q = 0; q < count; ++q) line[q] = d2[first + step * q];
      distanceTransform1d(line.data(), d2.data() + first, count, step, v.data(), z.data());
    });
  }
  return d2;
}

/// Stage 2: each cell's section, the largest ball whose fitting region reaches it.
std::vector<int> coverage(const Grid& g, const std::vector<char>& occupied, const std::vector<int>& ball,
                          const std::vector<std::size_t>& at, int thickest) {
  const std::size_t size = g.size();
  const std::size_t P = at.size();
  // 2. Coverage: a cell reads the largest ball whose fitting region reaches it. Region of
  // half-width k around the cells of balls >= t: dilation along z, then y, then x within runs.
  std::vector<int> section(size, 0);
  for (std::size_t p = 0; p < P; ++p) section[at[p]] = ball[at[p]];
  std::vector<char> seeds(size), a(size), b(size);
  for (int t = 3; t <= thickest; ++t) {
    const int reach = (t - 1) / 2;
    for (std::size_t i = 0; i < size; ++i) seeds[i] = ball[i] >= t ? 1 : 0;
    dilateAlongRuns(g, occupied, seeds, 2, reach, a);
    dilateAlongRuns(g, occupied, a, 1, reach, b);
    dilateAlongRuns(g, occupied, b, 0, reach, a);
    for (std::size_t p = 0; p < P; ++p)
      if (a[at[p]]) section[at[p]] = std::max(section[at[p]], t);
  }
  return section;
}

}  // namespace

SectionThickness measureSectionThickness(const Voxelization& voxels, double thinFraction) {
  if (voxels.cells.empty()) throw std::invalid_argument("section thickness: the voxelization has no cells");
  if (!(thinFraction >= 0.0 && thinFraction < 1.0))
    throw std::invalid_argument("section thickness: the thin fraction must be in [0, 1), not " +
                                std::to_string(thinFraction));
  Grid g;
  Eigen::Vector3i hi = voxels.cells.front();
  g.lo = hi;
  for (const Eigen::Vector3i& c : voxels.cells) {
    g.lo = g.lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
  }
  g.n = hi - g.lo + Eigen::Vector3i::Constant(3);
  g.stride[0] = 1;
  g.stride[1] = static_cast<std::size_t>(g.n.x());
  g.stride[2] = g.stride[1] * static_cast<std::size_t>(g.n.y());
  const std::size_t size = g.size();
  const std::size_t P = voxels.cells.size();
  if (static_cast<double>(g.n.x()) * g.n.y() * g.n.z() > kMaxSectionGridCells)
    throw std::invalid_argument(
        "section thickness: the occupied cells' bounding box spans " + std::to_string(g.n.x()) + " x " +
        std::to_string(g.n.y()) + " x " + std::to_string(g.n.z()) + " cells, more than the " +
        std::to_string(kMaxSectionGridCells) + " the measurement takes (it needs ~45 bytes per cell)");

  std::vector<char> occupied(size, 0);
  std::vector<std::size_t> at(P);
  for (std::size_t p = 0; p < P; ++p) {
    at[p] = g.index(voxels.cells[p]);
    occupied[at[p]] = 1;
  }

  Grid fine;
  const std::vector<float> d2 = squaredDistanceToEmpty(g, occupied, fine);

  // Ball diameter at every occupied cell: the largest ball centred on a point of the cell (its
  // centre, a face, an edge or a corner) clear of every empty cell. At distance d (cells) from
  // the nearest empty cell centre a point is d - 1/2 from that cell's faces (exact across a flat
  // axis-aligned section): diameter 2 d - 1, i.e. sqrt(d2) - 1 with d2 in half cells. Centres
  // on faces and corners let a section of an even number of cells read its width.
  std::vector<int> ball(size, 0);
  int thickest = 0;
  for (std::size_t p = 0; p < P; ++p) {
    const Eigen::Vector3i cell = voxels.cells[p] - g.lo + Eigen::Vector3i::Ones();
    float best = 0.0f;
    for (int dz = 0; dz < 3; ++dz)
      for (int dy = 0; dy < 3; ++dy)
        for (int dx = 0; dx < 3; ++dx)
          best = std::max(best, d2[static_cast<std::size_t>(2 * cell.x() + dx) +
                                   fine.stride[1] * static_cast<std::size_t>(2 * cell.y() + dy) +
                                   fine.stride[2] * static_cast<std::size_t>(2 * cell.z() + dz)]);
    // floor with a margin for the round-off of sqrt (d2 is a whole number)
    const int t = static_cast<int>(std::floor(std::sqrt(static_cast<double>(best)) - 1.0 + 1e-9));
    ball[at[p]] = std::clamp(t, 1, kMaxSectionThickness);
    thickest = std::max(thickest, ball[at[p]]);
  }

  const std::vector<int> section = coverage(g, occupied, ball, at, thickest);

  SectionThickness out;
  out.thinFraction = thinFraction;
  out.cells.resize(P);
  for (std::size_t p = 0; p < P; ++p) out.cells[p] = section[at[p]];
  std::vector<int> sorted = out.cells;
  // at most thinFraction P particles lie strictly below sorted[k]
  const std::size_t k = std::min(P - 1, static_cast<std::size_t>(std::floor(thinFraction * static_cast<double>(P))));
  std::nth_element(sorted.begin(), sorted.begin() + static_cast<std::ptrdiff_t>(k), sorted.end());
  out.thinnest = sorted[k];
  return out;
}

int regionHalfWidthForSection(int sectionCells, int askedHalfWidth) {
  if (sectionCells < 1)
    throw std::invalid_argument("region for a section: the section must be >= 1 cell, not " +
                                std::to_string(sectionCells));
  if (askedHalfWidth < 1 || askedHalfWidth > kMaxRegionHalfWidth)
    throw std::invalid_argument("region for a section: the asked half-width " + std::to_string(askedHalfWidth) +
                                " is outside [1, " + std::to_string(kMaxRegionHalfWidth) + "]");
  // 2w + 1 <= t
  return std::clamp((sectionCells - 1) / 2, 1, askedHalfWidth);
}

double bendingStiffeningEstimate(int regionHalfWidth, int sectionCells) {
  if (sectionCells < 1 || regionHalfWidth < 1)
    throw std::invalid_argument("bending stiffening: the section and the half-width must be >= 1");
  // (w / t, 1 / (settled tip deflection / FEM oracle's)), bench_material --quick --nu 0:
  // cantilever L/t 8 at 4 cells across, w 1 / 2 / 3, and at 2 cells across, w 2 / 3.
  static const double kRatio[][2] = {{0.25, 0.96}, {0.5, 1.12}, {0.75, 1.40}, {1.0, 1.61}, {1.5, 2.15}};
  constexpr int kPoints = sizeof kRatio / sizeof kRatio[0];
  const double r = static_cast<double>(regionHalfWidth) / sectionCells;
  if (r <= kRatio[0][0]) return kRatio[0][1];
  for (int i = 1; i < kPoints; ++i)
    if (r <= kRatio[i][0]) {
      const double s = (r - kRatio[i - 1][0]) / (kRatio[i][0] - kRatio[i - 1][0]);
      return kRatio[i - 1][1] + s * (kRatio[i][1] - kRatio[i - 1][1]);
    }
  return kRatio[kPoints - 1][1];
}

}  // namespace deformable_flsm
