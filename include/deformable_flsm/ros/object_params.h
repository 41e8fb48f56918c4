/// @file object_params.h
/// Several deformable objects from the node's parameters (~objects): each entry names an object
/// and overrides the node's top-level object parameters (mesh, pose, material, resolution,
/// regions), which stay the defaults of every object. Validated with messages that name the
/// entry and the key to fix, like ~colliders (collider_params.h).
#pragma once

#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/runtime/object_spec.h"

#include <xmlrpcpp/XmlRpcValue.h>

#include <string>
#include <vector>

namespace deformable_flsm {

/// Parses the ~objects parameter: a non-empty list of dictionaries (see README for the keys).
/// @param[in] value     the parameter as read from the server
/// @param[in] defaults  the node's validated top-level parameters
/// @throws ParamError naming the entry (index and name), the key, the value and what is
///         accepted: a missing or invalid name, a duplicate name, a name equal to ~frame_id,
///         an unknown key, a wrongly typed or out-of-range value.
std::vector<ObjectSpec> parseObjectList(XmlRpc::XmlRpcValue& value, const NodeParams& defaults);

/// Parses one entry of ~objects given on its own (~add_object's parameter), with the same keys
/// and checks as an entry of the list (a name already in the scene is the caller's to refuse).
/// @param[in] label  how messages name the entry ("parameter '~new_object'")
/// @throws ParamError as parseObjectList() does, naming `label`
ObjectSpec parseObjectEntry(XmlRpc::XmlRpcValue& entry, const NodeParams& defaults,
                            const std::string& label);

}  // namespace deformable_flsm
