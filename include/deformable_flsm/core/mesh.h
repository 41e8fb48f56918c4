/// @file mesh.h
/// Triangle meshes: loading (assimp), welding, validation and vertex normals.
#pragma once

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {

/// Where Debian's glmark2-data installs its models (bunny.obj, horse.3ds, jellyfish.jobj, ...).
constexpr const char* kGlmark2ModelDirectory = "/usr/share/glmark2/models";
/// The Stanford bunny of glmark2-data (about 2 units tall, Y up): the node's default mesh and
/// the tests' and benchmarks' fixture.
constexpr const char* kBunnyMeshPath = "/usr/share/glmark2/models/bunny.obj";

/// Thrown for a mesh that cannot be used; the message names the file and what to fix.
class MeshError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An indexed triangle mesh.
struct TriMesh {
  /// #V vertex positions (m)
  std::vector<Eigen::Vector3d> vertices;
  /// #T triangles, counter-clockwise seen from outside, indices into `vertices`
  std::vector<std::array<std::uint32_t, 3>> triangles;

  /// Axis-aligned bounds of the vertices; both zero for an empty mesh.
  Eigen::Vector3d boundsMin() const;
  Eigen::Vector3d boundsMax() const;
};

/// Loads any format assimp reads (OBJ, STL, PLY, DAE, 3DS, OFF, ...) and glmark2's ".jobj"
/// (vertex and index lines), triangulated, all meshes of
/// the scene merged with their node transforms applied, vertices welded by exact position (so
/// STL's per-face corners join), and uniformly scaled by `scale`.
/// @param[in] path   file to read
/// @param[in] scale  uniform scale applied to positions (> 0)
/// @throws MeshError on a missing or unreadable file, or a mesh that fails validateMesh().
TriMesh loadMesh(const std::string& path, double scale = 1.0);

/// Checks that a mesh is usable for simulation: at least one triangle, finite coordinates,
/// indices in range, non-zero extent.
/// @param[in] mesh  mesh to check
/// @param[in] name  how to name it in the message (e.g. the file path)
/// @throws MeshError naming `name` and the problem.
void validateMesh(const TriMesh& mesh, const std::string& name);

/// Merges vertices with identical positions and drops triangles that become degenerate
/// (two equal corners). Returns the number of vertices removed.
std::size_t weldVertices(TriMesh& mesh);

/// Number of edges not shared by exactly two triangles (0 for a closed, manifold mesh).
std::size_t countBoundaryEdges(const TriMesh& mesh);

/// Area-weighted vertex normals of a mesh with the given (possibly deformed) positions.
/// @param[in]  positions  #V by 3 vertex positions (m)
/// @param[in]  triangles  #T triangles
/// @param[out] normals    #V unit normals (zero vector for a vertex with no area around it)
void computeVertexNormals(const std::vector<Eigen::Vector3d>& positions,
                          const std::vector<std::array<std::uint32_t, 3>>& triangles,
                          std::vector<Eigen::Vector3d>& normals);

}  // namespace deformable_flsm
