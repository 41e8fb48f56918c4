/// @file collider_spec.h
/// A collider as the node's parameters or a command describe it (a core Collider plus the tf
/// frame it follows), the limits on colliders, their ids and frames, and the ground below the
/// object. Plain C++: parsing them from parameters is ros/collider_params.h.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"

#include <Eigen/Core>

#include <cstddef>
#include <string>

namespace deformable_flsm {

/// A collider as the parameters or a command describe it.
struct ColliderSpec {
  /// 1 to kMaxIdLength printable characters, unique
  std::string id;
  /// shape and friction; `collider.pose` is the pose in the simulation frame when
  /// followFrame is empty, else the collider's offset in followFrame
  Collider collider;
  /// tf frame the collider follows every step; "" = fixed in the simulation frame
  std::string followFrame;
  /// mesh colliders: the URL the mesh came from (for messages)
  std::string meshUrl;
};

/// Limits on colliders.
struct ColliderLimits {
  /// Colliders at once (parameters and ~collider together); more are refused.
  static constexpr std::size_t kMaxColliders = 64;
  /// The ground's id.
  static constexpr const char* kGroundId = "ground";
};

/// The tf frame the node broadcasts for collider `id` (its pose in the simulation frame); the
/// collider's contact wrench is expressed in it.
std::string colliderFrameId(const std::string& id);

/// true when `id` is 1 to CommandLimits::kMaxIdLength printable characters.
bool validColliderId(const std::string& id);

/// The ground: a half-space whose outward normal opposes gravity (+z without gravity), its
/// surface `clearance` below the object's lowest rest point along that normal (the lowest of
/// the mesh's vertices and of the particles' contact spheres).
/// @param[in] lattice        the rest lattice (m)
/// @param[in] mesh           the object's mesh in the simulation frame (m)
/// @param[in] gravity        m/s^2 in the simulation frame
/// @param[in] contactRadius  radius of the particles' contact spheres (m)
/// @param[in] clearance      gap between the object and the ground (m, >= 0)
/// Friction is Collider's default.
Collider groundCollider(const Lattice& lattice, const TriMesh& mesh, const Eigen::Vector3d& gravity,
                        double contactRadius, double clearance);

}  // namespace deformable_flsm
