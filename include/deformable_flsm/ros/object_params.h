/// @file object_params.h
/// Several deformable objects from the node's parameters (~objects): each entry names an object
/// and overrides the node's top-level object parameters (mesh, pose, material, resolution,
/// regions), which stay the defaults of every object. Validated with messages that name the
/// entry and the key to fix, like ~colliders (collider_params.h).
#pragma once

#include "deformable_flsm/ros/param_loader.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <Eigen/Geometry>

#include <cstddef>
#include <string>
#include <vector>

namespace deformable_flsm {

/// One object as ~objects describes it.
struct ObjectSpec {
  /// unique; a tf frame and a topic namespace (~objects/<name>/...)
  std::string name;
  /// the node's parameters with the entry's keys applied: mesh, mesh_scale, mesh_rpy, material
  /// (solver.density, damping, ambient damping, stiffness, youngs_modulus, poissons_ratio),
  /// lattice (spacing, resolution, particle_budget) and regions; validated
  NodeParams params;
  /// rest placement in ~frame_id: the loaded mesh (scaled, turned by mesh_rpy) is moved by it
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

struct ObjectLimits {
  /// Objects in one scene; more are refused at start-up.
  static constexpr std::size_t kMaxObjects = 256;
  /// Longest object name (characters).
  static constexpr std::size_t kMaxNameLength = 64;
};

/// true when `name` can be a tf frame and a topic namespace: a letter, then letters, digits or
/// '_', at most ObjectLimits::kMaxNameLength characters.
bool validObjectName(const std::string& name);

/// Parses the ~objects parameter: a non-empty list of dictionaries (see README for the keys).
/// @param[in] value     the parameter as read from the server
/// @param[in] defaults  the node's validated top-level parameters
/// @throws ParamError naming the entry (index and name), the key, the value and what is
///         accepted: a missing or invalid name, a duplicate name, a name equal to ~frame_id,
///         an unknown key, a wrongly typed or out-of-range value.
std::vector<ObjectSpec> parseObjectList(XmlRpc::XmlRpcValue& value, const NodeParams& defaults);

/// The one object of a node without ~objects: named ~object_frame_id, at the mesh's own place.
ObjectSpec singleObject(const NodeParams& params);

}  // namespace deformable_flsm
