#include "deformable_flsm/core/mesh_distance_field.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

namespace {

/// Empty cells around the mesh's bounds, so that the field holds the outside distances a
/// particle sphere meets before it touches the mesh.
constexpr int kPaddingCells = 3;
/// Nodes within this many cells of a triangle get its exact distance before the sweeps.
constexpr int kExactBandCells = 1;

/// Closest point to p on triangle (a, b, c) (Ericson, Real-Time Collision Detection, 5.1.5).
Eigen::Vector3d closestPointOnTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                       const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a, ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0.0 && d2 <= 0.0) return a;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0.0 && d4 <= d3) return b;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) return a + d1 / (d1 - d3) * ab;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0.0 && d5 <= d6) return c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) return a + d2 / (d2 - d6) * ac;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0)
    return b + (d4 - d3) / ((d4 - d3) + (d5 - d6)) * (c - b);
  const double denom = 1.0 / (va + vb + vc);
  return a + ab * (vb * denom) + ac * (vc * denom);
}

/// Sign of twice the signed area of (0, 0), (x1, y1), (x2, y2), with Bridson's tie-break for
/// zero area, so that a ray through an edge shared by two triangles hits exactly one of them.
int orientation(double x1, double y1, double x2, double y2, double& twiceSignedArea) {
  twiceSignedArea = y1 * x2 - x1 * y2;
  if (twiceSignedArea > 0) return 1;
  if (twiceSignedArea < 0) return -1;
  if (y2 > y1) return 1;
  if (y2 < y1) return -1;
  if (x1 > x2) return 1;
  if (x1 < x2) return -1;
  return 0;
}

/// Whether (x0, y0) lies in the 2-D triangle (x1, y1), (x2, y2), (x3, y3); if so its
/// barycentric coordinates a, b, c.
bool pointInTriangle2d(double x0, double y0, double x1, double y1, double x2, double y2, double x3,
                       double y3, double& a, double& b, double& c) {
  x1 -= x0; x2 -= x0; x3 -= x0;
  y1 -= y0; y2 -= y0; y3 -= y0;
  const int signA = orientation(x2, y2, x3, y3, a);
  if (signA == 0) return false;
  const int signB = orientation(x3, y3, x1, y1, b);
  if (signB != signA) return false;
  const int signC = orientation(x1, y1, x2, y2, c);
  if (signC != signA) return false;
  const double sum = a + b + c;
  if (sum == 0.0) return false;
  a /= sum;
  b /= sum;
  c /= sum;
  return true;
}

/// Distance from p to triangle t of the mesh.
double triangleDistance(const TriMesh& mesh, const Eigen::Vector3d& p, std::int32_t t) {
  const auto& tri = mesh.triangles[static_cast<std::size_t>(t)];
  return (p - closestPointOnTriangle(p, mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]])).norm();
}

}  // namespace

MeshDistanceField::MeshDistanceField(const TriMesh& mesh, int resolution) {
  validateMesh(mesh, "mesh collider");
  if (countBoundaryEdges(mesh) != 0)
    throw MeshError("mesh collider: the mesh has " + std::to_string(countBoundaryEdges(mesh)) +
                    " open edges; a collider needs a closed mesh to tell inside from outside");
  if (resolution < 4)
    throw std::invalid_argument("mesh collider: distance field resolution " + std::to_string(resolution) +
                                " is below 4 cells");
  meshMin_ = mesh.boundsMin();
  meshMax_ = mesh.boundsMax();
  dx_ = (meshMax_ - meshMin_).maxCoeff() / resolution;
  origin_ = meshMin_ - Eigen::Vector3d::Constant(kPaddingCells * dx_);
  for (int a = 0; a < 3; ++a)
    n_[a] = static_cast<int>(std::ceil((meshMax_[a] - meshMin_[a]) / dx_)) + 2 * kPaddingCells + 1;
  const std::size_t nodes = static_cast<std::size_t>(n_.x()) * n_.y() * n_.z();
  const double far = (n_.cast<double>() * dx_).norm();
  phi_.assign(nodes, far);
  std::vector<std::int32_t> closest(nodes, -1);
  std::vector<std::int32_t> crossings(nodes, 0);
  exactBand(mesh, closest, crossings);
  sweep(mesh, closest);
  applySign(crossings);
}

void MeshDistanceField::exactBand(const TriMesh& mesh, std::vector<std::int32_t>& closest,
                                  std::vector<std::int32_t>& crossings) {
  // 1. Exact distances near each triangle; crossing counts of the rows along x.
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    Eigen::Vector3d g[3];
    for (int c = 0; c < 3; ++c) g[c] = (mesh.vertices[tri[c]] - origin_) / dx_;
    Eigen::Vector3i lo, hi;
    for (int a = 0; a < 3; ++a) {
      const double mn = std::min({g[0][a], g[1][a], g[2][a]}), mx = std::max({g[0][a], g[1][a], g[2][a]});
      lo[a] = std::clamp(static_cast<int>(std::floor(mn)) - kExactBandCells, 0, n_[a] - 1);
      hi[a] = std::clamp(static_cast<int>(std::ceil(mx)) + kExactBandCells, 0, n_[a] - 1);
    }
    for (int k = lo.z(); k <= hi.z(); ++k)
      for (int j = lo.y(); j <= hi.y(); ++j)
        for (int i = lo.x(); i <= hi.x(); ++i) {
          const double d = triangleDistance(mesh, nodeAt(i, j, k), static_cast<std::int32_t>(t));
          const std::size_t id = nodeIndex(i, j, k);
          if (d < phi_[id]) {
            phi_[id] = d;
            closest[id] = static_cast<std::int32_t>(t);
          }
        }
    // Rows of nodes along x through (j, k) that the triangle crosses: crossing i* counts for
    // the first node past it, ceil(i*).
    const int j0 = std::max(0, static_cast<int>(std::ceil(std::min({g[0].y(), g[1].y(), g[2].y()}))));
    const int j1 = std::min(n_.y() - 1, static_cast<int>(std::floor(std::max({g[0].y(), g[1].y(), g[2].y()}))));
    const int k0 = std::max(0, static_cast<int>(std::ceil(std::min({g[0].z(), g[1].z(), g[2].z()}))));
    const int k1 = std::min(n_.z() - 1, static_cast<int>(std::floor(std::max({g[0].z(), g[1].z(), g[2].z()}))));
    for (int k = k0; k <= k1; ++k)
      for (int j = j0; j <= j1; ++j) {
        double a, b, c;
        if (!pointInTriangle2d(j, k, g[0].y(), g[0].z(), g[1].y(), g[1].z(), g[2].y(), g[2].z(), a, b, c)) continue;
        const double ix = a * g[0].x() + b * g[1].x() + c * g[2].x();
        const int first = static_cast<int>(std::ceil(ix));
        if (first < 0)
          ++crossings[nodeIndex(0, j, k)];
        else if (first < n_.x())
          ++crossings[nodeIndex(first, j, k)];
      }
  }
}

void MeshDistanceField::sweep(const TriMesh& mesh, std::vector<std::int32_t>& closest) {
  // 2. Fast sweeping: a node takes a neighbour's closest triangle when it is closer.
  auto check = [&](std::size_t id, const Eigen::Vector3d& p, int i, int j, int k) {
    const std::int32_t t = closest[nodeIndex(i, j, k)];
    if (t < 0 || t == closest[id]) return;
    const double d = triangleDistance(mesh, p, t);
    if (d < phi_[id]) {
      phi_[id] = d;
      closest[id] = t;
    }
  };
  auto sweepOnce = [&](int di, int dj, int dk) {
    const int i0 = di > 0 ? 1 : n_.x() - 2, i1 = di > 0 ? n_.x() : -1;
    const int j0 = dj > 0 ? 1 : n_.y() - 2, j1 = dj > 0 ? n_.y() : -1;
    const int k0 = dk > 0 ? 1 : n_.z() - 2, k1 = dk > 0 ? n_.z() : -1;
    for (int k = k0; k != k1; k += dk)
      for (int j = j0; j != j1; j += dj)
        for (int i = i0; i != i1; i += di) {
          const std::size_t id = nodeIndex(i, j, k);
          const Eigen::Vector3d p = nodeAt(i, j, k);
          check(id, p, i - di, j, k);
          check(id, p, i, j - dj, k);
          check(id, p, i - di, j - dj, k);
          check(id, p, i, j, k - dk);
          check(id, p, i - di, j, k - dk);
          check(id, p, i, j - dj, k - dk);
          check(id, p, i - di, j - dj, k - dk);
        }
  };
  for (int pass = 0; pass < 2; ++pass) {
    sweepOnce(+1, +1, +1);
    sweepOnce(-1, -1, -1);
    sweepOnce(+1, +1, -1);
    sweepOnce(-1, -1, +1);
    sweepOnce(+1, -1, +1);
    sweepOnce(-1, +1, -1);
    sweepOnce(+1, -1, -1);
    sweepOnce(-1, +1, +1);
  }
}

void MeshDistanceField::applySign(const std::vector<std::int32_t>& crossings) {
  // 3. Sign: inside where an odd number of crossings precede the node along its row.
  for (int k = 0; k < n_.z(); ++k)
    for (int j = 0; j < n_.y(); ++j) {
      int total = 0;
      for (int i = 0; i < n_.x(); ++i) {
        const std::size_t id = nodeIndex(i, j, k);
        total += crossings[id];
        if (total % 2 == 1) phi_[id] = -phi_[id];
      }
    }
}

double MeshDistanceField::distance(const Eigen::Vector3d& p, Eigen::Vector3d& normal) const {
  // Grid coordinates, clamped into the last cell so that the cell (i, i+1) always exists.
  const Eigen::Vector3d g = (p - origin_) / dx_;
  Eigen::Vector3d c;
  int base[3];
  double f[3];
  for (int a = 0; a < 3; ++a) {
    c[a] = std::clamp(g[a], 0.0, static_cast<double>(n_[a] - 1));
    base[a] = std::min(static_cast<int>(c[a]), n_[a] - 2);
    f[a] = c[a] - base[a];
  }
  const int i = base[0], j = base[1], k = base[2];
  const double v000 = at(i, j, k), v100 = at(i + 1, j, k), v010 = at(i, j + 1, k), v110 = at(i + 1, j + 1, k);
  const double v001 = at(i, j, k + 1), v101 = at(i + 1, j, k + 1), v011 = at(i, j + 1, k + 1),
               v111 = at(i + 1, j + 1, k + 1);
  const double fx = f[0], fy = f[1], fz = f[2];
  // trilinear interpolation and its gradient
  const double x00 = v000 + fx * (v100 - v000), x10 = v010 + fx * (v110 - v010);
  const double x01 = v001 + fx * (v101 - v001), x11 = v011 + fx * (v111 - v011);
  const double y0 = x00 + fy * (x10 - x00), y1 = x01 + fy * (x11 - x01);
  const double value = y0 + fz * (y1 - y0);
  const double dxz0 = (1 - fy) * (v100 - v000) + fy * (v110 - v010);
  const double dxz1 = (1 - fy) * (v101 - v001) + fy * (v111 - v011);
  Eigen::Vector3d grad((1 - fz) * dxz0 + fz * dxz1, (1 - fz) * (x10 - x00) + fz * (x11 - x01), y1 - y0);
  const Eigen::Vector3d outside = (g - c) * dx_;
  const double gap = outside.norm();
  if (gap > 0.0) {
    normal = outside / gap;
    return value + gap;
  }
  const double len = grad.norm();
  normal = len > 0.0 ? Eigen::Vector3d(grad / len) : Eigen::Vector3d::UnitZ();
  return value;
}

}  // namespace deformable_flsm
