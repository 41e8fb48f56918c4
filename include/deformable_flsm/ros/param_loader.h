/// @file param_loader.h
/// Reads the node's private parameters into NodeParams (runtime/node_params.h), which validates
/// them.
#pragma once

#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/ros/collider_params.h"
#include "deformable_flsm/ros/robot_colliders.h"
#include "deformable_flsm/runtime/node_params.h"

#include <ros/node_handle.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <Eigen/Core>

#include <cstddef>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {

struct ObjectSpec;

/// Reads `~` parameters with their defaults. A parameter that is set with the wrong type is an
/// error, never silently replaced by its default.
class ParamLoader {
 public:
  /// @param[in] pnh  the node's private handle ("~")
  explicit ParamLoader(const ros::NodeHandle& pnh) : pnh_(pnh) {}

  /// @throws ParamError on a wrongly typed or invalid parameter.
  NodeParams loadNodeParams() const;
  /// The objects of ~objects (object_params.h), each with `params` as its defaults; empty when
  /// ~objects is unset (the node's single object).
  /// @throws ParamError naming the entry and the key.
  std::vector<ObjectSpec> loadObjects(const NodeParams& params) const;

  /// Names (without "~") of the private parameters set on the server that loadNodeParams(),
  /// called before on this loader, did not read: most likely misspelt. Each name is written once,
  /// where it is read.
  std::vector<std::string> unknownParams() const;

 private:
  /// true with ~name in `value` when it is set, false when unset.
  /// @throws ParamError when it is set with another XML-RPC type (`expected` names the right one).
  bool getOfType(const std::string& name, XmlRpc::XmlRpcValue::Type type, const char* expected,
                 XmlRpc::XmlRpcValue& value) const;
  double getDouble(const std::string& name, double fallback) const;
  int getInt(const std::string& name, int fallback) const;
  bool getBool(const std::string& name, bool fallback) const;
  std::string getString(const std::string& name, const std::string& fallback) const;
  Eigen::Vector3d getVector3(const std::string& name, const Eigen::Vector3d& fallback) const;
  std::vector<Box> getBoxes(const std::string& name) const;
  std::vector<ColliderSpec> getColliders(const std::string& name, const std::string& simFrame) const;
  std::vector<std::string> getStrings(const std::string& name,
                                      const std::vector<std::string>& fallback) const;
  /// ~robot_description (the URDF read from the parameter it names) and ~robot_*.
  RobotColliders getRobot() const;

  ros::NodeHandle pnh_;
  /// the names the getters were asked for, set or not (unknownParams())
  mutable std::vector<std::string> read_;
};

/// Turns ~mesh into a file path: package://<pkg>/<rest> is resolved with rospack, file://<path>
/// loses its scheme, anything else is returned unchanged.
/// @throws ParamError when the package is unknown or another URL scheme is used.
std::string resolveMeshPath(const std::string& url);

/// Loads the render mesh named by params.mesh, scaled by params.meshScale, then rotated by
/// params.meshRpy.
/// @throws ParamError naming ~mesh, the resolved file and why it cannot be used.
TriMesh loadMeshParam(const NodeParams& params);

}  // namespace deformable_flsm
