/// @file voxelizer.cpp
/// Voxelization of a triangle mesh into the occupied cells of a regular lattice.
///
/// Outline (closed mesh):
///  1. Surface cells: every cell whose closed box overlaps a triangle (separating-axis test,
///     Akenine-Moeller 2001), testing only the cells of each triangle's bounding box.
///  2. Inside/outside by ray parity along +x. Triangles are binned by the (j, k) rows their y-z
///     projection covers; each ray collects the x of its crossings, sorts them, and a point is
///     inside when an odd number of crossings lies before it. Each surface cell is sampled on a
///     kSubSamples^3 grid (sub-cell centres) whose inside share is its fill fraction; every other
///     cell lies wholly inside or outside, so one sample point decides it.
///  3. Occupied: surface cells with fraction > 0, and the other cells found inside.
///
/// Open mesh: surface cells plus the cells a 6-connected flood fill from outside cannot reach.
#include "deformable_flsm/core/voxelizer.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

namespace deformable_flsm {
namespace {

/// Sub-cell samples per axis for the fill fraction of a surface cell (64 samples per cell).
constexpr int kSubSamples = 4;
/// Slack in dims = ceil(extent / h - kDimsSlack), in cells: a mesh n cells long gets n cells even
/// when extent / h is a little above n, by 1 ulp in double (0.1 / 0.025) or by single precision's
/// rounding of the mesh file's vertices (0.1f / 0.025 = 4 + 6e-8). A sliver of at most 1e-6 of a
/// cell beyond the lattice is lost from the cells' fill fractions.
constexpr double kDimsSlack = 1e-6;
/// Largest lattice (all cells, occupied or not) voxelize() will allocate, about 134 MB of flags.
constexpr double kMaxLatticeCells = double(1 << 27);
/// Largest number of cells along one axis; Lattice packs a cell index into 21 bits per axis.
constexpr double kMaxCellsPerAxis = double(1 << 20);

/// Slack, in cells, when finding the cells an interval touches: an interval ending exactly on a
/// cell boundary touches the cells on both sides, whichever way (a - origin) / h rounds.
constexpr double kTouchSlack = 1e-9;
/// Slack when flooring an estimated resolution, which is verified afterwards anyway.
constexpr double kGuessSlack = 1e-9;
/// Cell flag in the lattice-sized grid: the cell's box overlaps a triangle.
constexpr std::uint8_t kSurface = 1;

struct Grid {
  Eigen::Vector3d origin;
  double h = 0.0;
  Eigen::Vector3i dims;

  std::size_t cellCount() const {
    return static_cast<std::size_t>(dims.x()) * static_cast<std::size_t>(dims.y()) *
           static_cast<std::size_t>(dims.z());
  }
  std::size_t index(int i, int j, int k) const {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(dims.x()) *
               (static_cast<std::size_t>(j) + static_cast<std::size_t>(dims.y()) *
                                                  static_cast<std::size_t>(k));
  }
  /// Cell index range [lo, hi] along `axis` of the cells touching the interval [a, b], clamped.
  void cellRange(int axis, double a, double b, int& lo, int& hi) const {
    const double n = static_cast<double>(dims[axis]);
    const double fa = std::floor((a - origin[axis]) / h - kTouchSlack);
    const double fb = std::floor((b - origin[axis]) / h + kTouchSlack);
    lo = static_cast<int>(std::clamp(fa, 0.0, n - 1.0));
    hi = static_cast<int>(std::clamp(fb, 0.0, n - 1.0));
  }
};

/// Lattice of spacing h centred on the bounding box [lo, hi]. Returns false (without building it)
/// when it would exceed kMaxLatticeCells or kMaxCellsPerAxis; `cells` receives its size.
bool makeGrid(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, double h, Grid& grid,
              double& cells) {
  const Eigen::Vector3d extent = hi - lo;
  Eigen::Vector3d dims;
  for (int a = 0; a < 3; ++a) dims[a] = std::max(1.0, std::ceil(extent[a] / h - kDimsSlack));
  cells = dims.prod();
  if (!(cells <= kMaxLatticeCells) || !(dims.maxCoeff() <= kMaxCellsPerAxis)) return false;
  grid.h = h;
  grid.dims = dims.cast<int>();
  grid.origin = lo - (dims * h - extent) / 2.0;
  return true;
}

/// 2D orientation of s relative to the directed edge p -> q in the (y, z) plane, evaluated with
/// the edge's endpoints in a canonical (lexicographic) order and negated if needed. Two triangles
/// sharing an edge thus see exactly opposite values, whatever rounding occurs, so a ray near
/// their common edge is counted by exactly one of them.
double edgeFunction(const Eigen::Vector2d& p, const Eigen::Vector2d& q, const Eigen::Vector2d& s) {
  const bool forward = p.x() < q.x() || (p.x() == q.x() && p.y() < q.y());
  const Eigen::Vector2d& u = forward ? p : q;
  const Eigen::Vector2d& v = forward ? q : p;
  const double w = (v.x() - u.x()) * (s.y() - u.y()) - (v.y() - u.y()) * (s.x() - u.x());
  return forward ? w : -w;
}

/// Top-left fill rule for the edge p -> q of a counter-clockwise triangle: a point exactly on the
/// edge belongs to the triangle iff the edge is a "left" edge (going down) or a "top" edge
/// (horizontal, going left). Of two triangles on either side of an edge exactly one claims its
/// points, and of a fan around a vertex exactly one claims the vertex.
bool isTopLeft(const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
  return q.y() < p.y() || (q.y() == p.y() && q.x() < p.x());
}

bool claims(double w, const Eigen::Vector2d& p, const Eigen::Vector2d& q) {
  return w > 0.0 || (w == 0.0 && isTopLeft(p, q));
}

/// Triangles binned by the rows (j, k) of rays their y-z projection may cross, in CSR form.
struct RowBins {
  std::vector<std::size_t> start;      // ny * nz + 1 offsets into `triangles`
  std::vector<std::uint32_t> triangles;

  RowBins(const TriMesh& mesh, const Grid& grid) {
    const std::size_t rows =
        static_cast<std::size_t>(grid.dims.y()) * static_cast<std::size_t>(grid.dims.z());
    std::vector<std::array<int, 4>> ranges(mesh.triangles.size());
    start.assign(rows + 1, 0);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& tri = mesh.triangles[t];
      const Eigen::Vector3d& a = mesh.vertices[tri[0]];
      const Eigen::Vector3d& b = mesh.vertices[tri[1]];
      const Eigen::Vector3d& c = mesh.vertices[tri[2]];
      auto& r = ranges[t];
      grid.cellRange(1, std::min({a.y(), b.y(), c.y()}), std::max({a.y(), b.y(), c.y()}), r[0],
                     r[1]);
      grid.cellRange(2, std::min({a.z(), b.z(), c.z()}), std::max({a.z(), b.z(), c.z()}), r[2],
                     r[3]);
      for (int k = r[2]; k <= r[3]; ++k) {
        for (int j = r[0]; j <= r[1]; ++j) ++start[rowIndex(grid, j, k) + 1];
      }
    }
    for (std::size_t r = 0; r < rows; ++r) start[r + 1] += start[r];
    triangles.resize(start[rows]);
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      const auto& r = ranges[t];
      for (int k = r[2]; k <= r[3]; ++k) {
        for (int j = r[0]; j <= r[1]; ++j) {
          triangles[fill[rowIndex(grid, j, k)]++] = static_cast<std::uint32_t>(t);
        }
      }
    }
  }

  static std::size_t rowIndex(const Grid& grid, int j, int k) {
    return static_cast<std::size_t>(j) +
           static_cast<std::size_t>(grid.dims.y()) * static_cast<std::size_t>(k);
  }
};

/// Appends to `crossings` the x of every crossing of the ray {(x, s.x(), s.y())} with the
/// candidate triangles, and sorts them.
void rayCrossings(const TriMesh& mesh, const std::uint32_t* candidates, std::size_t count,
                  const Eigen::Vector2d& s, std::vector<double>& crossings) {
  crossings.clear();
  for (std::size_t n = 0; n < count; ++n) {
    const auto& tri = mesh.triangles[candidates[n]];
    const Eigen::Vector3d* p[3] = {&mesh.vertices[tri[0]], &mesh.vertices[tri[1]],
                                   &mesh.vertices[tri[2]]};
    Eigen::Vector2d q[3] = {p[0]->tail<2>(), p[1]->tail<2>(), p[2]->tail<2>()};
    // Early reject on the projected bounding box (most candidates of a row miss a given ray).
    if (s.x() < std::min({q[0].x(), q[1].x(), q[2].x()}) ||
        s.x() > std::max({q[0].x(), q[1].x(), q[2].x()}) ||
        s.y() < std::min({q[0].y(), q[1].y(), q[2].y()}) ||
        s.y() > std::max({q[0].y(), q[1].y(), q[2].y()})) {
      continue;
    }
    const double area = (q[1].x() - q[0].x()) * (q[2].y() - q[0].y()) -
                        (q[1].y() - q[0].y()) * (q[2].x() - q[0].x());
    // A triangle parallel to x projects to a segment; the ray meets its neighbours instead.
    if (area == 0.0) continue;
    if (area < 0.0) {
      std::swap(p[1], p[2]);
      std::swap(q[1], q[2]);
    }
    const double w0 = edgeFunction(q[1], q[2], s);
    const double w1 = edgeFunction(q[2], q[0], s);
    const double w2 = edgeFunction(q[0], q[1], s);
    if (!claims(w0, q[1], q[2]) || !claims(w1, q[2], q[0]) || !claims(w2, q[0], q[1])) continue;
    const double sum = w0 + w1 + w2;
    if (!(sum > 0.0)) continue;
    crossings.push_back((w0 * p[0]->x() + w1 * p[1]->x() + w2 * p[2]->x()) / sum);
  }
  std::sort(crossings.begin(), crossings.end());
}

/// Marks kSurface on every cell whose box overlaps a triangle.
void markSurfaceCells(const TriMesh& mesh, const Grid& grid, std::vector<std::uint8_t>& flags) {
  const Eigen::Vector3d half = Eigen::Vector3d::Constant(grid.h / 2.0);
  for (const auto& tri : mesh.triangles) {
    const Eigen::Vector3d& a = mesh.vertices[tri[0]];
    const Eigen::Vector3d& b = mesh.vertices[tri[1]];
    const Eigen::Vector3d& c = mesh.vertices[tri[2]];
    const Eigen::Vector3d lo = a.cwiseMin(b).cwiseMin(c);
    const Eigen::Vector3d hi = a.cwiseMax(b).cwiseMax(c);
    int i0, i1, j0, j1, k0, k1;
    grid.cellRange(0, lo.x(), hi.x(), i0, i1);
    grid.cellRange(1, lo.y(), hi.y(), j0, j1);
    grid.cellRange(2, lo.z(), hi.z(), k0, k1);
    for (int k = k0; k <= k1; ++k) {
      for (int j = j0; j <= j1; ++j) {
        for (int i = i0; i <= i1; ++i) {
          std::uint8_t& flag = flags[grid.index(i, j, k)];
          if (flag & kSurface) continue;
          const Eigen::Vector3d centre =
              grid.origin + grid.h * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
          if (detail::triangleBoxOverlap(centre, half, a, b, c)) flag |= kSurface;
        }
      }
    }
  }
}

/// Closed mesh: fill fractions by ray parity. Appends occupied cells in (k, j, i) order.
void fillByParity(const TriMesh& mesh, const Grid& grid, const std::vector<std::uint8_t>& flags,
                  Voxelization& out) {
  const RowBins bins(mesh, grid);
  const int nx = grid.dims.x();
  // Sub-sample s of a cell sits at fraction (s + 1/2) / kSubSamples of the cell along each axis.
  auto subOffset = [](int s) { return (s + 0.5) / kSubSamples; };
  // Non-surface cells lie wholly inside or outside, so any point of theirs decides them; the
  // sample ray (kCentreRay, kCentreRay) at the cell's mid x is used.
  constexpr int kCentreRay = kSubSamples / 2;
  std::vector<int> insideCount(static_cast<std::size_t>(nx));
  std::vector<std::uint8_t> centreInside(static_cast<std::size_t>(nx));
  std::vector<double> crossings;
  std::size_t rays = 0;
  std::size_t oddRays = 0;

  for (int k = 0; k < grid.dims.z(); ++k) {
    for (int j = 0; j < grid.dims.y(); ++j) {
      const std::size_t row = RowBins::rowIndex(grid, j, k);
      const std::size_t candidates = bins.start[row + 1] - bins.start[row];
      if (candidates == 0) continue;  // no surface in this row: every cell is outside
      bool rowHasSurface = false;
      for (int i = 0; i < nx; ++i) rowHasSurface |= (flags[grid.index(i, j, k)] & kSurface) != 0;
      std::fill(insideCount.begin(), insideCount.end(), 0);
      std::fill(centreInside.begin(), centreInside.end(), 0);

      for (int sz = 0; sz < kSubSamples; ++sz) {
        for (int sy = 0; sy < kSubSamples; ++sy) {
          const bool centreRay = sy == kCentreRay && sz == kCentreRay;
          if (!rowHasSurface && !centreRay) continue;
          const Eigen::Vector2d s(grid.origin.y() + grid.h * (j + subOffset(sy)),
                                  grid.origin.z() + grid.h * (k + subOffset(sz)));
          rayCrossings(mesh, bins.triangles.data() + bins.start[row], candidates, s, crossings);
          ++rays;
          if (crossings.size() % 2 != 0) ++oddRays;
          std::size_t before = 0;  // crossings with x below the current sample
          auto insideAt = [&](double x) {
            while (before < crossings.size() && crossings[before] < x) ++before;
            return before % 2 == 1;
          };
          for (int i = 0; i < nx; ++i) {
            const std::size_t c = static_cast<std::size_t>(i);
            if (flags[grid.index(i, j, k)] & kSurface) {
              for (int sx = 0; sx < kSubSamples; ++sx) {
                insideCount[c] += insideAt(grid.origin.x() + grid.h * (i + subOffset(sx)));
              }
            } else if (centreRay) {
              centreInside[c] = insideAt(grid.origin.x() + grid.h * (i + 0.5));
            }
          }
        }
      }

      constexpr double kSamplesPerCell = kSubSamples * kSubSamples * kSubSamples;
      for (int i = 0; i < nx; ++i) {
        const std::size_t c = static_cast<std::size_t>(i);
        const bool surface = (flags[grid.index(i, j, k)] & kSurface) != 0;
        if (surface && insideCount[c] > 0) {
          out.cells.emplace_back(i, j, k);
          out.fillFraction.push_back(insideCount[c] / kSamplesPerCell);
        } else if (!surface && centreInside[c]) {
          out.cells.emplace_back(i, j, k);
          out.fillFraction.push_back(1.0);
        }
      }
    }
  }
  if (oddRays > 0) {
    std::ostringstream warning;
    warning << oddRays << " of " << rays
            << " rays crossed the surface an odd number of times although the mesh has no "
               "boundary edges (self-intersecting or duplicated faces?); cells near them may be "
               "misclassified as inside or outside";
    out.warnings.push_back(warning.str());
  }
}

/// Open mesh: surface cells plus whatever a 6-connected flood fill from outside cannot reach.
void fillByFlood(const Grid& grid, const std::vector<std::uint8_t>& flags, std::size_t boundaryEdges,
                 Voxelization& out) {
  // Flood over the grid padded by one cell on each side, so that the outside is connected.
  const int px = grid.dims.x() + 2, py = grid.dims.y() + 2, pz = grid.dims.z() + 2;
  auto padded = [&](int i, int j, int k) {
    return static_cast<std::size_t>(i) +
           static_cast<std::size_t>(px) *
               (static_cast<std::size_t>(j) + static_cast<std::size_t>(py) *
                                                  static_cast<std::size_t>(k));
  };
  auto blocked = [&](int i, int j, int k) {
    const bool inLattice = i > 0 && j > 0 && k > 0 && i < px - 1 && j < py - 1 && k < pz - 1;
    return inLattice && (flags[grid.index(i - 1, j - 1, k - 1)] & kSurface) != 0;
  };
  std::vector<std::uint8_t> reached(static_cast<std::size_t>(px) * py * pz, 0);
  std::vector<Eigen::Vector3i> stack = {Eigen::Vector3i::Zero()};
  reached[0] = 1;
  const Eigen::Vector3i steps[6] = {{1, 0, 0},  {-1, 0, 0}, {0, 1, 0},
                                    {0, -1, 0}, {0, 0, 1},  {0, 0, -1}};
  while (!stack.empty()) {
    const Eigen::Vector3i c = stack.back();
    stack.pop_back();
    for (const Eigen::Vector3i& step : steps) {
      const Eigen::Vector3i n = c + step;
      if (n.x() < 0 || n.y() < 0 || n.z() < 0 || n.x() >= px || n.y() >= py || n.z() >= pz) {
        continue;
      }
      std::uint8_t& r = reached[padded(n.x(), n.y(), n.z())];
      if (r || blocked(n.x(), n.y(), n.z())) continue;
      r = 1;
      stack.push_back(n);
    }
  }

  std::size_t enclosed = 0;
  for (int k = 0; k < grid.dims.z(); ++k) {
    for (int j = 0; j < grid.dims.y(); ++j) {
      for (int i = 0; i < grid.dims.x(); ++i) {
        const bool surface = (flags[grid.index(i, j, k)] & kSurface) != 0;
        if (surface || !reached[padded(i + 1, j + 1, k + 1)]) {
          out.cells.emplace_back(i, j, k);
          out.fillFraction.push_back(1.0);
          if (!surface) ++enclosed;
        }
      }
    }
  }
  std::ostringstream warning;
  warning << "mesh is open (" << boundaryEdges
          << " boundary edges, i.e. edges not shared by exactly two triangles): interior filled "
             "by flood fill from outside, every cell with fill fraction 1";
  out.warnings.push_back(warning.str());
  if (enclosed == 0) {
    out.warnings.push_back(
        "the flood fill from outside reached every cell off the surface, so only a shell of "
        "surface cells was produced: close the mesh's holes (or make them smaller than a cell) to "
        "get a solid");
  }
}

/// Voxelizes on a given lattice, without the particle budget.
Voxelization voxelizeOnGrid(const TriMesh& mesh, const Grid& grid, std::size_t boundaryEdges) {
  Voxelization out;
  out.origin = grid.origin;
  out.spacing = grid.h;
  out.dims = grid.dims;
  out.closed = boundaryEdges == 0;
  std::vector<std::uint8_t> flags(grid.cellCount(), 0);
  markSurfaceCells(mesh, grid, flags);
  if (out.closed) {
    fillByParity(mesh, grid, flags, out);
  } else {
    fillByFlood(grid, flags, boundaryEdges, out);
  }
  return out;
}

/// Finds a resolution (cells along the longest axis) at most `below` - 1 whose voxelization fits
/// `budget`, starting from the guess `resolution` and verifying each candidate.
/// `count` receives its number of occupied cells.
int fittingResolution(const TriMesh& mesh, std::size_t boundaryEdges, double longest,
                      double resolution, double below, std::size_t budget, std::size_t& count) {
  const Eigen::Vector3d lo = mesh.boundsMin(), hi = mesh.boundsMax();
  int r = static_cast<int>(
      std::max(1.0, std::min(std::floor(resolution + kGuessSlack), std::ceil(below) - 1)));
  for (;;) {
    Grid grid;
    double cells = 0.0;  // occupied cells, or lattice cells when the lattice is too large
    if (makeGrid(lo, hi, longest / r, grid, cells)) {
      count = voxelizeOnGrid(mesh, grid, boundaryEdges).cells.size();
      // At resolution 1 the lattice is a single cell, which always fits a budget >= 1.
      if (count <= budget || r == 1) return r;
      cells = static_cast<double>(count);
    }
    // Occupied cells scale with the cube of the resolution; always make progress. The slack
    // keeps an exact ratio such as 20 * cbrt(1/8) = 9.999... from losing a whole step.
    const double guess =
        std::floor(r * std::cbrt(static_cast<double>(budget) / cells) + kGuessSlack);
    r = static_cast<int>(std::max(1.0, std::min(guess, r - 1.0)));
  }
}

/// A cell count held in a double, printed without an exponent when it fits in 64 bits.
std::string wholeNumber(double cells) {
  if (cells < 9e18) return std::to_string(static_cast<long long>(cells));
  std::ostringstream os;
  os << cells;
  return os.str();
}

}  // namespace

void VoxelizeOptions::validate() const {
  if (!std::isfinite(spacing) || spacing < 0.0) {
    std::ostringstream message;
    message << "VoxelizeOptions::spacing must be a finite number >= 0 (0 selects resolution), got "
            << spacing;
    throw VoxelizationError(message.str());
  }
  if (resolution < 0) {
    throw VoxelizationError("VoxelizeOptions::resolution must be >= 0 (0 selects spacing), got " +
                            std::to_string(resolution));
  }
  if ((spacing > 0.0) == (resolution > 0)) {
    std::ostringstream message;
    message << "set exactly one of VoxelizeOptions::spacing and VoxelizeOptions::resolution; got "
            << "spacing = " << spacing << " and resolution = " << resolution;
    throw VoxelizationError(message.str());
  }
  if (maxParticles < 1) {
    throw VoxelizationError("VoxelizeOptions::maxParticles must be >= 1, got 0");
  }
}

Voxelization voxelize(const TriMesh& mesh, const VoxelizeOptions& options) {
  options.validate();
  validateMesh(mesh, "mesh passed to voxelize");
  const Eigen::Vector3d lo = mesh.boundsMin(), hi = mesh.boundsMax();
  const double longest = (hi - lo).maxCoeff();
  const double h = options.spacing > 0.0 ? options.spacing : longest / options.resolution;
  const double resolution = longest / h;  // equivalent resolution, when spacing is given
  const std::size_t budget = options.maxParticles;
  const std::size_t boundaryEdges = countBoundaryEdges(mesh);

  auto describe = [&](std::ostream& os, double res, double spacing) {
    os << "resolution " << res << " (spacing " << spacing << " m)";
  };

  Grid grid;
  double latticeCells = 0.0;
  if (!makeGrid(lo, hi, h, grid, latticeCells)) {
    // Start from the resolution at which even a full lattice fits the budget, then, knowing the
    // occupied count there, try once more from the resolution that scaling predicts.
    const double guess = resolution * std::cbrt(static_cast<double>(budget) / latticeCells);
    std::size_t count = 0;
    int fit = fittingResolution(mesh, boundaryEdges, longest, guess, resolution, budget, count);
    if (count > 0) {
      std::size_t refinedCount = 0;
      const int refined = fittingResolution(
          mesh, boundaryEdges, longest, fit * std::cbrt(static_cast<double>(budget) / count),
          resolution, budget, refinedCount);
      if (refined > fit) {
        fit = refined;
        count = refinedCount;
      }
    }
    std::ostringstream message;
    message << "voxelization at ";
    describe(message, resolution, h);
    message << " needs a lattice of " << wholeNumber(latticeCells) << " cells, more than the "
            << wholeNumber(kMaxLatticeCells) << " cells (or " << wholeNumber(kMaxCellsPerAxis)
            << " along one axis) that can be allocated; use ";
    describe(message, fit, longest / fit);
    message << ", which occupies " << count
            << " cells, within VoxelizeOptions::maxParticles = " << budget;
    throw VoxelizationError(message.str());
  }

  Voxelization result = voxelizeOnGrid(mesh, grid, boundaryEdges);
  if (result.cells.size() > budget) {
    const double guess =
        resolution * std::cbrt(static_cast<double>(budget) / result.cells.size());
    std::size_t count = 0;
    const int fit =
        fittingResolution(mesh, boundaryEdges, longest, guess, resolution, budget, count);
    std::ostringstream message;
    message << "voxelization at ";
    describe(message, resolution, h);
    message << " would occupy " << result.cells.size()
            << " cells, more than VoxelizeOptions::maxParticles = " << budget << "; use ";
    describe(message, fit, longest / fit);
    message << ", which occupies " << count << " cells, or raise maxParticles";
    throw VoxelizationError(message.str());
  }
  return result;
}

namespace detail {

bool triangleBoxOverlap(const Eigen::Vector3d& boxCenter, const Eigen::Vector3d& boxHalfSize,
                        const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                        const Eigen::Vector3d& c) {
  // Work in the box's frame, where the box is [-e, e].
  const Eigen::Vector3d v[3] = {a - boxCenter, b - boxCenter, c - boxCenter};
  const Eigen::Vector3d& e = boxHalfSize;

  // Box normals: the triangle's bounding box against the box.
  const Eigen::Vector3d lo = v[0].cwiseMin(v[1]).cwiseMin(v[2]);
  const Eigen::Vector3d hi = v[0].cwiseMax(v[1]).cwiseMax(v[2]);
  if ((lo.array() > e.array()).any() || (hi.array() < -e.array()).any()) return false;

  // Projections of triangle and box on an axis L: the box covers [-r, r] with r = e . |L|.
  auto separatedOn = [&](const Eigen::Vector3d& axis) {
    const double p0 = axis.dot(v[0]), p1 = axis.dot(v[1]), p2 = axis.dot(v[2]);
    const double r = e.dot(axis.cwiseAbs());
    return std::min({p0, p1, p2}) > r || std::max({p0, p1, p2}) < -r;
  };

  // Triangle normal (plane against box). Zero for a degenerate triangle, which never separates.
  const Eigen::Vector3d edges[3] = {v[1] - v[0], v[2] - v[1], v[0] - v[2]};
  if (separatedOn(edges[0].cross(edges[1]))) return false;

  // Cross products of the box normals with the triangle edges.
  for (const Eigen::Vector3d& edge : edges) {
    for (int axis = 0; axis < 3; ++axis) {
      if (separatedOn(Eigen::Vector3d::Unit(axis).cross(edge))) return false;
    }
  }
  return true;
}

}  // namespace detail
Voxelization boxVoxels(const Eigen::Vector3i& dims, double spacing, const Eigen::Vector3d& origin) {
  Voxelization v;
  v.origin = origin;
  v.spacing = spacing;
  v.dims = dims;
  v.closed = true;
  for (int k = 0; k < dims.z(); ++k)
    for (int j = 0; j < dims.y(); ++j)
      for (int i = 0; i < dims.x(); ++i) v.cells.emplace_back(i, j, k);
  v.fillFraction.assign(v.cells.size(), 1.0);
  return v;
}

}  // namespace deformable_flsm
