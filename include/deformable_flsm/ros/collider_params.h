/// @file collider_params.h
/// Colliders from the node's parameters (~ground, ~ground_clearance, ~colliders) and from
/// ~collider commands: plain core Colliders plus the tf frame a collider follows, validated with
/// messages that name the entry and the field to fix.
#pragma once

#include "deformable_flsm/runtime/collider_spec.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {

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

}  // namespace deformable_flsm
