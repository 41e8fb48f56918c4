/// @file section.h
/// How thick the sections of a voxelized object are, and the region half-width that fits them.
///
/// Why it matters: shape matching fits each region with one rotation, so a region that spans a
/// bent section keeps the curvature inside it as well as the strain, an extra bending energy
/// ~ E kappa^2 R^2 that does not depend on the section. Bending then comes out stiffer than the
/// material's E by a factor that grows with (R / t)^2 (R the region radius, t the section), and
/// stays close to E when the region (2w + 1 cells wide) is no wider than the section (the
/// cantilevers against linear FEM on the same voxels: docs/method.md, "Accuracy against the
/// oracle"). Axial loads (a column, a stretched bar) do not care.
#pragma once

#include "deformable_flsm/core/solver_params.h"
#include "deformable_flsm/core/voxelizer.h"

#include <vector>

namespace deformable_flsm {

/// Thickest section measured (cells): the widest region the solver accepts, 2 kMaxRegionHalfWidth
/// + 1 cells. Thicker sections read this value; no choice of w depends on more.
constexpr int kMaxSectionThickness = 2 * kMaxRegionHalfWidth + 1;
/// Fraction of the particles that may lie in sections thinner than the "thinnest section", so
/// that a few thin cells (a voxel spike on the surface, a box's edges) do not decide.
constexpr double kThinSectionFraction = 0.05;

/// Largest bounding box (cells, one of padding on every side included) measureSectionThickness()
/// takes: it needs ~45 bytes per cell of the box (a distance transform on the half-cell grid),
/// ~380 MB at this bound.
constexpr int kMaxSectionGridCells = 1 << 23;

/// Section thickness of every cell of a voxelization and the object's thinnest section.
struct SectionThickness {
  /// #P thickness (cells) of the section at each cell of the voxelization, in its order,
  /// 1 to kMaxSectionThickness: the diameter of the largest ball inside the object whose centre
  /// reaches the cell with a region that fits the ball (see measureSectionThickness())
  std::vector<int> cells;
  /// the thinnest section (cells): at most `thinFraction` of the particles lie in thinner ones
  int thinnest = 0;
  /// the fraction the thinnest section was taken at
  double thinFraction = kThinSectionFraction;
};

/// Measures the section thickness of a voxelized object, in cells.
///
/// 1. Distance transform: the Euclidean distance d (cells) from every point of the half-cell
///    grid (cell centres, face centres, edge midpoints, corners) to the nearest empty cell centre
///    (outside the lattice is empty), exact (Felzenszwalb & Huttenlocher 2012, separable). A ball
///    centred there of diameter 2 d - 1 clears the empty cells' faces (exactly so across a flat
///    axis-aligned section); a cell's ball is the largest centred on one of its 27 points, so that
///    a section of n whole cells reads n for even n (centre on a face or corner) as for odd n.
/// 2. Coverage: cell p reads the largest ball diameter t_c of a cell c whose region of
///    half-width floor((t_c - 1) / 2), the widest region that fits across that ball, contains p
///    (regions as in lattice.h: straight runs of occupied cells along z, then y, then x, so that
///    no thickness leaks across a gap). Every cell of a bar then reads the bar's section, corners
///    included, and every cell of a ball its diameter.
///
/// Exact (every cell) for axis-aligned boxes, bars and plates of whole cells; within about a cell
/// for oblique and curved sections. Cost: O(dims) per thickness up to kMaxSectionThickness on a
/// dense grid of the occupied cells' bounding box (like voxelize()), and a distance transform
/// on the half-cell grid (8 times the cells, 4 bytes each): ~45 bytes per cell of the box.
///
/// @param[in] voxels        the occupied cells (voxelize(); the spacing is not used)
/// @param[in] thinFraction  in [0, 1): the fraction of particles allowed below `thinnest`
/// @throws std::invalid_argument for no cells, a thinFraction outside [0, 1), or a bounding box
///         of more than kMaxSectionGridCells cells (the message gives its size)
SectionThickness measureSectionThickness(const Voxelization& voxels,
                                         double thinFraction = kThinSectionFraction);

/// The largest region half-width w in [1, askedHalfWidth] whose regions, 2w + 1 cells wide, are
/// no wider than a section of `sectionCells` cells (1 when even w = 1 is wider: no smaller
/// region exists). In radius terms R = w + 1/2 cells (the region's reach to its outer cell
/// faces) <= t / 2.
///
/// Cost of a smaller w at the same Young's modulus: the asked alpha grows like 1 / (w (w + 1))
/// while the cap on alpha grows less (docs/method.md gives the caps), so a modulus near the cap
/// needs more sub-steps, ~sqrt of the ratio of the two growths; the cost of a sub-step does not
/// depend on w.
/// @throws std::invalid_argument for sectionCells < 1 or askedHalfWidth outside
///         [1, kMaxRegionHalfWidth]
int regionHalfWidthForSection(int sectionCells, int askedHalfWidth);

/// How much stiffer than E bending comes out with regions of half-width w on a section of t
/// cells: the inverse of the settled deflection over the FEM oracle's for slender cantilevers
/// (L/t = 8, nu = 0, bench_material --quick --nu 0), interpolated linearly in w / t between the
/// points of that table (section.cpp) and held constant beyond them. An estimate for the
/// start-up warning, not a correction: stubbier members and other loads bend less.
/// @throws std::invalid_argument for sectionCells < 1 or regionHalfWidth < 1
double bendingStiffeningEstimate(int regionHalfWidth, int sectionCells);

}  // namespace deformable_flsm
