/// @file object_spec.h
/// One deformable object of the scene as the node's parameters describe it: its name, its
/// parameters (the node's with its own keys applied) and its rest pose; the limits on objects.
/// Parsing ~objects is ros/object_params.h.
#pragma once

#include "deformable_flsm/runtime/node_params.h"

#include <Eigen/Geometry>

#include <cstddef>
#include <string>

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

/// The one object of a node without ~objects: named ~object_frame_id, at the mesh's own place.
ObjectSpec singleObject(const NodeParams& params);

}  // namespace deformable_flsm
