/// @file param_loader.h
/// Reads the node's private parameters into plain structs and validates them.
#pragma once

#include "deformable_flsm/core/mesh.h"

#include <ros/node_handle.h>

#include <stdexcept>
#include <string>

namespace deformable_flsm {

/// Thrown for a parameter that is missing its type or out of range; the message names the
/// parameter, the value found and what would be accepted.
class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// What the node needs besides the solver: where the mesh comes from and how it is published.
struct NodeParams {
  /// Default render mesh: the Stanford bunny shipped by Debian's glmark2-data.
  static constexpr const char* kDefaultMesh = "/usr/share/glmark2/models/bunny.obj";

  /// ~mesh: a file path or a package://<pkg>/<path> or file:// URL
  std::string mesh = kDefaultMesh;
  /// ~mesh_scale: uniform scale applied to the file's coordinates to get metres (> 0)
  double meshScale = 0.1;
  /// ~frame_id: frame of every published message
  std::string frameId = "world";
  /// ~publish_rate: rate of ~mesh and ~surface (Hz, > 0)
  double publishRate = 30.0;

  /// @throws ParamError naming the first field that is out of range.
  void validate() const;
};

/// Reads `~` parameters with their defaults. A parameter that is set with the wrong type is an
/// error, never silently replaced by its default.
class ParamLoader {
 public:
  /// @param[in] pnh  the node's private handle ("~")
  explicit ParamLoader(const ros::NodeHandle& pnh) : pnh_(pnh) {}

  /// @throws ParamError on a wrongly typed or invalid parameter.
  NodeParams loadNodeParams() const;

 private:
  double getDouble(const std::string& name, double fallback) const;
  std::string getString(const std::string& name, const std::string& fallback) const;

  ros::NodeHandle pnh_;
};

/// Turns ~mesh into a file path: package://<pkg>/<rest> is resolved with rospack, file://<path>
/// loses its scheme, anything else is returned unchanged.
/// @throws ParamError when the package is unknown or another URL scheme is used.
std::string resolveMeshPath(const std::string& url);

/// Loads the render mesh named by params.mesh, scaled by params.meshScale.
/// @throws ParamError naming ~mesh, the resolved file and why it cannot be used.
TriMesh loadMeshParam(const NodeParams& params);

}  // namespace deformable_flsm
