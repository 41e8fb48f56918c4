#include "deformable_flsm/ros/param_loader.h"

#include <ros/package.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <cmath>
#include <sstream>

namespace deformable_flsm {

namespace {

constexpr const char kPackageScheme[] = "package://";
constexpr const char kFileScheme[] = "file://";

bool startsWith(const std::string& s, const char* prefix) {
  return s.rfind(prefix, 0) == 0;
}

/// What was found on the parameter server, for error messages: "'fast' (a string)".
std::string describe(XmlRpc::XmlRpcValue value) {
  std::ostringstream out;
  switch (value.getType()) {
    case XmlRpc::XmlRpcValue::TypeString:
      out << "'" << static_cast<std::string&>(value) << "' (a string)";
      break;
    case XmlRpc::XmlRpcValue::TypeBoolean:
      out << (static_cast<bool&>(value) ? "true" : "false") << " (a boolean)";
      break;
    case XmlRpc::XmlRpcValue::TypeArray:
      out << "a list";
      break;
    case XmlRpc::XmlRpcValue::TypeStruct:
      out << "a dictionary";
      break;
    default:
      value.write(out);
  }
  return out.str();
}

[[noreturn]] void throwWrongType(const ros::NodeHandle& pnh, const std::string& name,
                                 const char* expected) {
  XmlRpc::XmlRpcValue found;
  pnh.getParam(name, found);
  throw ParamError("~" + name + " (" + pnh.resolveName(name) + ") must be " + expected +
                   ", got " + describe(found));
}

}  // namespace

void NodeParams::validate() const {
  std::ostringstream why;
  if (mesh.empty()) {
    why << "~mesh is empty: set it to a mesh file (e.g. " << kDefaultMesh
        << ") or a package:// URL";
  } else if (!std::isfinite(meshScale) || meshScale <= 0.0) {
    why << "~mesh_scale is " << meshScale
        << ": it must be a finite number > 0 (the factor from file units to metres)";
  } else if (frameId.empty()) {
    why << "~frame_id is empty: set it to the frame the mesh lives in (e.g. world)";
  } else if (!std::isfinite(publishRate) || publishRate <= 0.0) {
    why << "~publish_rate is " << publishRate << ": it must be a finite rate > 0 (Hz)";
  } else {
    return;
  }
  throw ParamError(why.str());
}

NodeParams ParamLoader::loadNodeParams() const {
  NodeParams p;
  p.mesh = getString("mesh", p.mesh);
  p.meshScale = getDouble("mesh_scale", p.meshScale);
  p.frameId = getString("frame_id", p.frameId);
  p.publishRate = getDouble("publish_rate", p.publishRate);
  p.validate();
  return p;
}

double ParamLoader::getDouble(const std::string& name, double fallback) const {
  if (!pnh_.hasParam(name)) {
    return fallback;
  }
  double value = 0.0;  // roscpp converts an int parameter to double
  if (!pnh_.getParam(name, value)) {
    throwWrongType(pnh_, name, "a number");
  }
  return value;
}

std::string ParamLoader::getString(const std::string& name, const std::string& fallback) const {
  if (!pnh_.hasParam(name)) {
    return fallback;
  }
  std::string value;
  if (!pnh_.getParam(name, value)) {
    throwWrongType(pnh_, name, "a string");
  }
  return value;
}

std::string resolveMeshPath(const std::string& url) {
  if (startsWith(url, kFileScheme)) {
    return url.substr(sizeof(kFileScheme) - 1);
  }
  if (startsWith(url, kPackageScheme)) {
    const std::string rest = url.substr(sizeof(kPackageScheme) - 1);
    const std::size_t slash = rest.find('/');
    const std::string package = rest.substr(0, slash);
    const std::string pkgPath = package.empty() ? std::string() : ros::package::getPath(package);
    if (pkgPath.empty()) {
      throw ParamError("~mesh '" + url + "': package '" + package +
                       "' not found (is its workspace sourced? ROS_PACKAGE_PATH)");
    }
    return slash == std::string::npos ? pkgPath : pkgPath + rest.substr(slash);
  }
  if (url.find("://") != std::string::npos) {
    throw ParamError("~mesh '" + url + "': only file paths, file:// and package:// URLs are "
                     "supported");
  }
  return url;
}

TriMesh loadMeshParam(const NodeParams& params) {
  const std::string path = resolveMeshPath(params.mesh);
  try {
    return loadMesh(path, params.meshScale);
  } catch (const MeshError& e) {
    throw ParamError("~mesh '" + params.mesh + "' (file '" + path + "') cannot be used: " +
                     e.what() + ". Set ~mesh to a readable, closed triangle mesh.");
  }
}

}  // namespace deformable_flsm
