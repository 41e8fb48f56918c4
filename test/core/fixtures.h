/// @file fixtures.h
/// Small lattices built directly, without meshes, for the core tests.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/region_summer.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"

#include <Eigen/Core>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <random>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace deformable_flsm {
namespace test {

/// Steps the solver `steps` times and returns, after each step, the mean height (z) of the
/// particles whose rest x is beyond `beyondX`: a cantilever's tip.
inline std::vector<double> tipHeights(Solver& solver, double beyondX, int steps) {
  std::vector<std::uint32_t> tip;
  for (std::uint32_t i = 0; i < solver.lattice().size(); ++i)
    if (solver.lattice().restPositions()[i].x() > beyondX) tip.push_back(i);
  std::vector<double> z(static_cast<std::size_t>(steps));
  for (int k = 0; k < steps; ++k) {
    solver.step();
    double sum = 0.0;
    for (std::uint32_t i : tip) sum += solver.positions()[i].z();
    z[static_cast<std::size_t>(k)] = sum / static_cast<double>(tip.size());
  }
  return z;
}

/// The extremes of a sampled swing z: (index, value) of each sample that is the largest or the
/// smallest within `window` samples either side, so that faint higher modes cannot make
/// extremes of their own (a quarter of the period is a good window).
inline std::vector<std::pair<int, double>> swingExtremes(const std::vector<double>& z, int window) {
  std::vector<std::pair<int, double>> extremes;
  const int n = static_cast<int>(z.size());
  for (int k = window; k + window < n; ++k) {
    bool isMax = true, isMin = true;
    for (int j = k - window; j <= k + window; ++j) {
      isMax = isMax && z[static_cast<std::size_t>(j)] <= z[static_cast<std::size_t>(k)];
      isMin = isMin && z[static_cast<std::size_t>(j)] >= z[static_cast<std::size_t>(k)];
    }
    if (isMax || isMin) extremes.emplace_back(k, z[static_cast<std::size_t>(k)]);
  }
  return extremes;
}

/// Voxelization holding the cells of a dims-sized lattice for which `keep(i, j, k)` is true,
/// sorted by (k, j, i) as voxelize() produces them, every cell full.
inline Voxelization makeVoxels(const Eigen::Vector3i& dims, double spacing,
                               const std::function<bool(int, int, int)>& keep) {
  Voxelization v;
  v.origin = Eigen::Vector3d::Zero();
  v.spacing = spacing;
  v.dims = dims;
  v.closed = true;
  for (int k = 0; k < dims.z(); ++k)
    for (int j = 0; j < dims.y(); ++j)
      for (int i = 0; i < dims.x(); ++i)
        if (keep(i, j, k)) {
          v.cells.emplace_back(i, j, k);
          v.fillFraction.push_back(1.0);
        }
  return v;
}

/// Rest data of a lattice as the solver keeps it (rest positions about the rest centre of mass).
struct Rest {
  std::vector<Eigen::Vector3d> q, c0;
  std::vector<double> regionMass;
  Rest(const Lattice& L, RegionSummer& summer) {
    const std::size_t n = L.size();
    Eigen::Vector3d com = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) com += L.masses()[i] * L.restPositions()[i];
    com /= L.totalMass();
    q.resize(n);
    for (std::size_t i = 0; i < n; ++i) q[i] = L.restPositions()[i] - com;
    std::vector<double> m = L.regionMassFractions(), mq(3 * n), Ms, mqs;
    for (std::size_t i = 0; i < n; ++i)
      for (int a = 0; a < 3; ++a) mq[3 * i + a] = m[i] * q[i][a];
    summer.gather(m, 1, Ms);
    summer.gather(mq, 3, mqs);
    regionMass = Ms;
    c0.resize(n);
    for (std::size_t r = 0; r < n; ++r) c0[r] = Eigen::Vector3d(mqs[3 * r], mqs[3 * r + 1], mqs[3 * r + 2]) / Ms[r];
  }
};

/// A full box of nx x ny x nz cells.
inline Voxelization makeBox(int nx, int ny, int nz, double spacing) {
  return boxVoxels(Eigen::Vector3i(nx, ny, nz), spacing);
}

/// Axis-aligned box [lo, hi] as 12 counter-clockwise (outward-facing) triangles on 8 vertices;
/// the first two triangles form the x = hi.x face (tests remove them to open the mesh).
inline TriMesh boxMesh(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
  TriMesh mesh;
  for (int v = 0; v < 8; ++v)
    mesh.vertices.emplace_back((v & 1) ? hi.x() : lo.x(), (v & 2) ? hi.y() : lo.y(), (v & 4) ? hi.z() : lo.z());
  const std::uint32_t quads[6][4] = {{1, 3, 7, 5}, {0, 4, 6, 2}, {0, 1, 5, 4},
                                     {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};
  for (const auto& q : quads) {
    mesh.triangles.push_back({q[0], q[1], q[2]});
    mesh.triangles.push_back({q[0], q[2], q[3]});
  }
  return mesh;
}

/// Axis-aligned box [0, size].
inline TriMesh boxMesh(const Eigen::Vector3d& size) { return boxMesh(Eigen::Vector3d::Zero(), size); }

/// Signed volume by the divergence theorem, sum over triangles of a . (b x c) / 6: the exact
/// enclosed volume of a closed mesh, positive when the triangles are counter-clockwise seen from
/// outside.
inline double signedVolume(const TriMesh& mesh) {
  double volume = 0.0;
  for (const auto& t : mesh.triangles) {
    volume += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]])) / 6.0;
  }
  return volume;
}


/// Yardsticks of a momentum test's round-off: sum m |v| and sum m |x| |v| of a state.
struct MomentumScale {
  double linear = 0.0, angular = 0.0;
};

/// Gives `solver` a deformed, moving state: every position jittered by up to 2 mm, velocities a
/// drift of 0.2 m/s along y, the spin `spin` (rad/s) about the origin and up to 0.3 m/s of noise
/// (std::mt19937 seeded with `seed`). Returns the state's momentum yardsticks.
inline MomentumScale deformAndSpin(Solver& solver, const Eigen::Vector3d& spin, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<Eigen::Vector3d> x = solver.positions(), v(x.size());
  for (std::size_t i = 0; i < x.size(); ++i) {
    x[i] += 0.002 * Eigen::Vector3d(u(rng), u(rng), u(rng));
    v[i] = Eigen::Vector3d(0.0, 0.2, 0.0) + spin.cross(x[i]) + 0.3 * Eigen::Vector3d(u(rng), u(rng), u(rng));
  }
  solver.setPositions(x);
  solver.setVelocities(v);
  MomentumScale scale;
  for (std::size_t i = 0; i < x.size(); ++i) {
    scale.linear += solver.lattice().masses()[i] * v[i].norm();
    scale.angular += solver.lattice().masses()[i] * x[i].norm() * v[i].norm();
  }
  return scale;
}

/// Moves every particle of `solver` to the degenerate start `name`: "point" (all on one point),
/// "plane" (flattened onto z = 0), "scrambled" (anywhere within the object's size about the
/// origin, std::mt19937 seeded with 21) or "stretched" (ten times as far from the origin).
inline void degenerateStart(Solver& solver, const std::string& name) {
  const double size = solver.lattice().objectSize();
  std::vector<Eigen::Vector3d> x = solver.positions();
  std::mt19937 rng(21);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for (auto& xi : x) {
    if (name == "point") xi = Eigen::Vector3d(0.3, 0.3, 0.3);
    if (name == "plane") xi.z() = 0.0;
    if (name == "scrambled") xi = size * Eigen::Vector3d(u(rng), u(rng), u(rng));
    if (name == "stretched") xi *= 10.0;
  }
  solver.setPositions(x);
}

}  // namespace test
}  // namespace deformable_flsm
