/// @file embedding.h
/// The render mesh embedded in the deforming lattice by trilinear interpolation.
#pragma once

#include "deformable_flsm/core/lattice.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

/// Each render vertex is a trilinear combination of the 8 lattice nodes around it: the particles
/// at the centres of the 8 cells whose centres bound the vertex (Rivers & James 2007, sec. 3).
/// Near the surface some of those cells are empty; such a node is a "ghost" that follows its
/// nearest particle p rigidly: x_ghost = x_p + R_p (x0_ghost - x0_p), R_p the rotation of p's
/// region. Trilinear interpolation reproduces any affine map exactly, so the rest mesh is
/// reproduced exactly and every rigid motion of the lattice moves the mesh rigidly.
class Embedding {
 public:
  /// @param[in] lattice        the particle lattice
  /// @param[in] restVertices   #V render-mesh vertices at rest (m), in the lattice's frame
  Embedding(const Lattice& lattice, const std::vector<Eigen::Vector3d>& restVertices);

  std::size_t vertexCount() const { return corners_.size(); }
  std::size_t ghostCount() const { return ghostAnchor_.size(); }

  /// Deformed vertex positions; any number of threads at once.
  /// @param[in]  positions  #P particle positions (m)
  /// @param[in]  rotations  #P region rotations (Solver::regionRotations())
  /// @param[out] vertices   #V deformed vertices (m), resized
  void deform(const std::vector<Eigen::Vector3d>& positions,
              const std::vector<Eigen::Quaterniond>& rotations,
              std::vector<Eigen::Vector3d>& vertices) const;

 private:
  // node index < P: a particle; >= P: ghost (index - P)
  std::vector<std::array<std::uint32_t, 8>> corners_;
  std::vector<std::array<double, 8>> weights_;
  std::vector<std::uint32_t> ghostAnchor_;
  std::vector<Eigen::Vector3d> ghostOffset_;  // x0_ghost - x0_anchor
  std::size_t particleCount_ = 0;
};

}  // namespace deformable_flsm
