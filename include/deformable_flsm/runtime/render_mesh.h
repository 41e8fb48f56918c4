/// @file render_mesh.h
/// Preparing the render mesh at load: orientation, and simplification to a triangle budget.
/// Plain geometry on TriMesh (no ROS), used by the node at start-up.
#pragma once

#include "deformable_flsm/core/mesh.h"

#include <Eigen/Core>

#include <cstddef>

namespace deformable_flsm {

/// Rotation from roll, pitch, yaw (rad) as in ROS (tf2::Quaternion::setRPY): fixed axes x, then
/// y, then z, i.e. R = Rz(yaw) Ry(pitch) Rx(roll).
Eigen::Matrix3d rotationFromRpy(const Eigen::Vector3d& rpy);

/// Rotates every vertex about the origin by rotationFromRpy(rpy).
/// @param[in]     rpy   roll, pitch, yaw (rad)
/// @param[in,out] mesh  #V vertices rotated in place; triangles unchanged
void rotateMesh(const Eigen::Vector3d& rpy, TriMesh& mesh);

/// What simplifyMesh() achieved.
struct SimplifyResult {
  TriMesh mesh;
  /// Hausdorff-like error that meshoptimizer reports, relative to the mesh extent (0.01 = 1 %)
  double relativeError = 0.0;
};

/// Simplifies a mesh to at most `triangleBudget` triangles with meshoptimizer's edge-collapse
/// simplifier (meshopt_simplify, quadric error metric; topology preserving), then drops the
/// vertices no triangle uses. A mesh already within budget is returned unchanged (error 0).
/// The simplifier may stop above the budget where collapses would change the topology; the
/// result then has more triangles than asked (the caller reports the count).
/// @param[in] mesh            #V vertices, #T triangles
/// @param[in] triangleBudget  wanted triangle count (>= 1)
/// @throws std::invalid_argument for a budget of 0.
SimplifyResult simplifyMesh(const TriMesh& mesh, std::size_t triangleBudget);

}  // namespace deformable_flsm
