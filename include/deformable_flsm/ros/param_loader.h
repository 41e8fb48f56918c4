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
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {

struct ObjectSpec;

/// Reads `~` parameters with their defaults. A parameter that is set with the wrong type is an
/// error, never silently replaced by its default. The parameters come from the parameter server
/// (the node) or from a tree of the same names (the Python bindings, which read the node's YAML
/// without a master): one set of names, defaults and checks for both.
class ParamLoader {
 public:
  /// @param[in] pnh  the node's private handle ("~")
  explicit ParamLoader(const ros::NodeHandle& pnh) : pnh_(pnh) {}
  /// @param[in] tree    the private parameters as a dictionary (TypeStruct), as a YAML file
  ///                    loaded with rosparam would put them under the node; ~robot_description
  ///                    names a key of it holding the URDF text
  /// @param[in] source  where the tree came from, for error messages (e.g. the file name)
  /// @throws ParamError when `tree` is not a dictionary
  ParamLoader(const XmlRpc::XmlRpcValue& tree, const std::string& source);

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
  /// The material (modulus, Poisson's ratio, damping, density), the step (time step, sub-steps,
  /// threads, summation, integrator and scheme) and the contact radius into p.
  void readMaterialAndSolver(NodeParams& p) const;

  /// whether ~name is set, and its value (from the server or the tree)
  bool has(const std::string& name) const;
  XmlRpc::XmlRpcValue fetch(const std::string& name) const;
  /// ~name where it is looked up, for messages: its resolved name, or the tree's source
  std::string where(const std::string& name) const;
  [[noreturn]] void throwWrongType(const std::string& name, const char* expected) const;

  /// the server's parameters (the node), unset when reading a tree
  std::optional<ros::NodeHandle> pnh_;
  XmlRpc::XmlRpcValue tree_;
  std::string source_;
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
