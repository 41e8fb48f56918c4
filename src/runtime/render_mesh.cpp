#include "deformable_flsm/runtime/render_mesh.h"

#include <Eigen/Geometry>
#include <meshoptimizer.h>

#include <stdexcept>
#include <vector>

namespace deformable_flsm {

namespace {

/// Error bound handed to meshopt_simplify, relative to the mesh extent. The triangle budget is
/// what the user asked for, so the error may grow as far as needed to meet it.
constexpr float kUnboundedError = 1.0f;

}  // namespace

Eigen::Matrix3d rotationFromRpy(const Eigen::Vector3d& rpy) {
  return (Eigen::AngleAxisd(rpy.z(), Eigen::Vector3d::UnitZ()) *
          Eigen::AngleAxisd(rpy.y(), Eigen::Vector3d::UnitY()) *
          Eigen::AngleAxisd(rpy.x(), Eigen::Vector3d::UnitX()))
      .toRotationMatrix();
}

void rotateMesh(const Eigen::Vector3d& rpy, TriMesh& mesh) {
  if (rpy.isZero(0.0)) return;
  const Eigen::Matrix3d R = rotationFromRpy(rpy);
  for (Eigen::Vector3d& v : mesh.vertices) v = R * v;
}

SimplifyResult simplifyMesh(const TriMesh& mesh, std::size_t triangleBudget) {
  if (triangleBudget < 1) {
    throw std::invalid_argument("simplifyMesh: the triangle budget must be >= 1");
  }
  SimplifyResult result;
  if (mesh.triangles.size() <= triangleBudget) {
    result.mesh = mesh;
    return result;
  }
  // meshoptimizer works on float positions and a flat 32-bit index buffer.
  std::vector<float> positions;
  positions.reserve(3 * mesh.vertices.size());
  for (const Eigen::Vector3d& v : mesh.vertices) {
    positions.insert(positions.end(), {static_cast<float>(v.x()), static_cast<float>(v.y()),
                                       static_cast<float>(v.z())});
  }
  std::vector<unsigned int> indices;
  indices.reserve(3 * mesh.triangles.size());
  for (const auto& t : mesh.triangles) indices.insert(indices.end(), t.begin(), t.end());

  std::vector<unsigned int> simplified(indices.size());  // worst case: nothing collapses
  float error = 0.0f;
  const std::size_t count = meshopt_simplify(
      simplified.data(), indices.data(), indices.size(), positions.data(), mesh.vertices.size(),
      3 * sizeof(float), 3 * triangleBudget, kUnboundedError, 0, &error);
  simplified.resize(count);

  // Keep only the vertices the simplified triangles use (remap[old] = new, ~0u when unused).
  std::vector<unsigned int> remap(mesh.vertices.size());
  const std::size_t kept = meshopt_optimizeVertexFetchRemap(remap.data(), simplified.data(),
                                                            simplified.size(), remap.size());
  result.mesh.vertices.resize(kept);
  for (std::size_t v = 0; v < remap.size(); ++v) {
    if (remap[v] != ~0u) result.mesh.vertices[remap[v]] = mesh.vertices[v];
  }
  result.mesh.triangles.resize(count / 3);
  for (std::size_t t = 0; t < count / 3; ++t) {
    for (int c = 0; c < 3; ++c) result.mesh.triangles[t][c] = remap[simplified[3 * t + c]];
  }
  result.relativeError = error;
  return result;
}

}  // namespace deformable_flsm
