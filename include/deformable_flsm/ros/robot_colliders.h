/// @file robot_colliders.h
/// The robot in the scene: every <collision> element of a URDF (parsed with urdf::Model) as a
/// collider that follows its link's tf frame at the element's origin; links chosen by name
/// patterns; and the test that keeps out links that start inside the object.
#pragma once

#include "deformable_flsm/ros/collider_params.h"
#include "deformable_flsm/runtime/robot_spec.h"

#include <string>
#include <vector>

namespace deformable_flsm {

/// Reads a URDF: one collider per <collision> element of every chosen link (box, sphere,
/// cylinder; mesh from a file path, file:// or package:// URL with its scale), friction from
/// the options.
/// @param[in] urdfXml  the URDF text
/// @param[in] options  which links, friction (descriptionParam only names the source)
/// @throws ParamError naming the parameter and what to fix: a URDF that does not parse, a
///         pattern that is not a regular expression, a mesh that cannot be loaded (which link,
///         which file), a link name too long for a collider id.
RobotColliders parseRobotColliders(const std::string& urdfXml, const RobotColliderOptions& options);

}  // namespace deformable_flsm
