/// @file collider_params.h
/// Colliders from the node's parameters (~ground, ~ground_clearance, ~colliders) and from
/// ~collider commands: plain core Colliders plus the tf frame a collider follows, validated with
/// messages that name the entry and the field to fix.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

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

/// Loads a mesh collider's mesh into `shape` (mesh and its distance field, built here rather
/// than by the simulation thread): `url` a file path or package:// / file:// URL. Loads of the
/// same file at the same scale share one mesh and field while any of them is held.
/// @throws std::invalid_argument saying which file and why it cannot be used (unreadable, not a
///         closed triangle mesh, bad scale).
void loadColliderMesh(const std::string& url, double scale, ColliderShape& shape);
/// The same with a scale per axis (a URDF <mesh scale="x y z">), each a finite factor > 0.
void loadColliderMesh(const std::string& url, const Eigen::Vector3d& scale, ColliderShape& shape);

/// Parses the ~colliders parameter: a list of dictionaries (see README for the fields).
/// @param[in] value     the parameter as read from the server
/// @param[in] simFrame  ~frame_id: a frame_id equal to it means "fixed in the simulation frame"
/// @throws ParamError naming the entry (index and id), the field, the value and what is
///         accepted: unknown type, NaN or negative sizes, zero quaternion, missing mesh file,
///         duplicate id, unknown field.
std::vector<ColliderSpec> parseColliderList(XmlRpc::XmlRpcValue& value,
                                            const std::string& simFrame);

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
