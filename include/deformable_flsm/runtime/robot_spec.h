/// @file robot_spec.h
/// The robot in the scene as colliders: the ~robot_* options, one collider per <collision>
/// element of a link (following the link's tf frame), and the test that keeps out links that
/// start inside the object. Plain C++: reading them from a URDF is ros/robot_colliders.h.
#pragma once

#include "deformable_flsm/runtime/collider_spec.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace deformable_flsm {

/// ~robot_* parameters.
struct RobotColliderOptions {
  /// ~robot_description: the name of the parameter that holds the URDF (as robot_state_publisher
  /// reads it, e.g. "robot_description", resolved in the node's namespace); "" = no robot
  std::string descriptionParam;
  /// ~robot_links: regular expressions (ECMAScript), each matched against whole link names; a
  /// link with collision geometry joins when one matches
  std::vector<std::string> includeLinks{".*"};
  /// ~robot_exclude_links: regular expressions; a link that one matches stays out
  std::vector<std::string> excludeLinks;
  /// ~robot_exclude_overlapping: leave out a link whose collision geometry overlaps any object's
  /// rest shape when its frame first appears (a link the object is placed on or around)
  bool excludeOverlapping = true;
  /// ~robot_static_friction, ~robot_kinetic_friction: Coulomb friction of every robot collider
  /// (a URDF has none), 0 <= kinetic <= static
  double staticFriction = 0.6;
  double kineticFriction = 0.5;
};

/// One collision element of a link.
struct RobotCollider {
  /// id "robot/<link>/<k>" (k: the element's index in the link), followFrame the link, pose the
  /// element's origin in the link frame
  ColliderSpec spec;
  std::string link;
};

/// The robot's colliders as read from its URDF.
struct RobotColliders {
  RobotColliderOptions options;
  /// the URDF's robot name
  std::string robotName;
  std::vector<RobotCollider> colliders;
  /// for the start-up log: patterns that match no link, links left out and why
  std::vector<std::string> warnings;
};

/// "robot/<link>": the ~contact_wrenches id of a link's summed wrench.
std::string robotLinkWrenchId(const std::string& link);

/// Whether any particle's contact sphere (radius `radius` around a point of `positions`) reaches
/// into the collider `shape` at `pose` (simulation frame): the start-up overlap test.
/// @param[in] shape      a valid shape; a mesh with its distance field
/// @param[in] pose       collider frame in the simulation frame
/// @param[in] positions  #P by 3 particle positions (m)
/// @param[in] radius     contact radius (m, >= 0)
bool overlapsParticles(const ColliderShape& shape, const Eigen::Isometry3d& pose,
                       const std::vector<Eigen::Vector3d>& positions, double radius);

}  // namespace deformable_flsm
