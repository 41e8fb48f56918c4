#include "deformable_flsm/ros/param_loader.h"

#include "xmlrpc_value.h"

#include "deformable_flsm/ros/camera_params.h"
#include "deformable_flsm/ros/object_params.h"
#include "deformable_flsm/ros/tactile_topics.h"
#include "deformable_flsm/runtime/render_mesh.h"

#include <ros/package.h>
#include <ros/param.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <algorithm>
#include <cmath>
#include <sstream>

namespace deformable_flsm {

namespace {

constexpr const char kPackageScheme[] = "package://";
constexpr const char kFileScheme[] = "file://";

bool startsWith(const std::string& s, const char* prefix) {
  return s.rfind(prefix, 0) == 0;
}

}  // namespace

ParamLoader::ParamLoader(const XmlRpc::XmlRpcValue& tree, const std::string& source)
    : tree_(tree), source_(source) {
  if (tree_.getType() != XmlRpc::XmlRpcValue::TypeStruct) {
    throw ParamError(source_ + " must hold a dictionary of the node's parameters, got " +
                     describe(tree_));
  }
}

bool ParamLoader::has(const std::string& name) const {
  return pnh_ ? pnh_->hasParam(name) : tree_.hasMember(name);
}

XmlRpc::XmlRpcValue ParamLoader::fetch(const std::string& name) const {
  XmlRpc::XmlRpcValue value;
  if (pnh_)
    pnh_->getParam(name, value);
  else if (tree_.hasMember(name))
    value = const_cast<XmlRpc::XmlRpcValue&>(tree_)[name];  // operator[] is not const
  return value;
}

std::string ParamLoader::where(const std::string& name) const {
  return pnh_ ? pnh_->resolveName(name) : "in " + source_;
}

void ParamLoader::throwWrongType(const std::string& name, const char* expected) const {
  XmlRpc::XmlRpcValue found = fetch(name);
  std::string hint;
  if (pnh_ && found.getType() == XmlRpc::XmlRpcValue::TypeString &&
      static_cast<std::string&>(found).find('[') != std::string::npos) {
    // rosrun's _name:=[...] arrives as a string: roscpp does not parse lists there.
    hint = " (a list given as _" + name + ":=[...] on the command line arrives as a string: "
           "set it in a YAML file, or with rosparam set " + where(name) + " \"[...]\")";
  }
  throw ParamError("~" + name + " (" + where(name) + ") must be " + expected + ", got " +
                   describe(found) + hint);
}

void ParamLoader::readMaterialAndSolver(NodeParams& p) const {
  SolverParams& s = p.solver;
  s.stiffness = getDouble("stiffness", s.stiffness);
  p.youngsModulus = getDouble("youngs_modulus", p.youngsModulus);
  p.poissonsRatio = getDouble("poissons_ratio", p.poissonsRatio);
  const std::string material = getString("material", toString(p.material));
  if (!parseMaterial(material, p.material)) {
    throw ParamError("~material is '" + material + "': it must be 'youngs' (the stiffness from "
                     "~youngs_modulus) or 'classic' (alpha = ~stiffness per sub-step)");
  }
  s.damping = getDouble("damping", s.damping);
  s.ambientDamping = getDouble("ambient_damping", s.ambientDamping);
  s.gravity = getVector3("gravity", s.gravity);
  s.timeStep = getDouble("time_step", s.timeStep);
  s.substeps = getInt("substeps", s.substeps);
  s.density = getDouble("density", s.density);
  s.threads = getInt("threads", s.threads);
  s.contactRadius = getDouble("contact_radius", s.contactRadius);
  const std::string kind = getString("solver", toString(s.kind));
  try {
    s.kind = parseSolverKind(kind);
  } catch (const std::invalid_argument&) {
    throw ParamError("~solver is '" + kind + "': it must be 'fast' (FastLSM summation) or "
                     "'naive' (direct summation, for comparison)");
  }
  const std::string integrator = getString("integrator", toString(s.integrator));
  try {
    p.integratorAuto = integrator == "auto";
    s.integrator = p.integratorAuto ? Integrator::Explicit : parseIntegrator(integrator);
  } catch (const std::invalid_argument&) {
    throw ParamError("~integrator is '" + integrator + "': it must be 'explicit' (symplectic Euler, the "
                     "modulus capped by the sub-step), 'implicit' (backward Euler, any modulus at one "
                     "sub-step) or 'auto' (explicit where ~substeps give the modulus, else implicit)");
  }
  const std::string scheme = getString("implicit_scheme", toString(s.implicitScheme));
  try {
    s.implicitScheme = parseImplicitScheme(scheme);
  } catch (const std::invalid_argument&) {
    throw ParamError("~implicit_scheme is '" + scheme + "': it must be 'backward_euler' (first order, damps "
                     "the object's own vibration) or 'bdf2' (second order, keeps it; one object alone)");
  }
}

NodeParams ParamLoader::loadNodeParams() const {
  NodeParams p;
  p.mesh = getString("mesh", p.mesh);
  p.meshScale = getDouble("mesh_scale", p.meshScale);
  p.meshRpy = getVector3("mesh_rpy", p.meshRpy);
  p.frameId = getString("frame_id", p.frameId);
  p.objectFrameId = getString("object_frame_id", p.objectFrameId);

  p.spacing = getDouble("spacing", p.spacing);
  p.resolution = getInt("resolution", p.resolution);
  p.particleBudget = getInt("particle_budget", p.particleBudget);
  p.maxParticles = getInt("max_particles", p.maxParticles);

  p.regionRadius = getDouble("region_radius", p.regionRadius);
  p.regionHalfWidth = getInt("region_half_width", p.regionHalfWidth);
  p.regionFromSection = getBool("region_from_section", p.regionFromSection);
  readMaterialAndSolver(p);

  p.publishRate = getDouble("publish_rate", p.publishRate);
  p.republishAtRest = getBool("republish_at_rest", p.republishAtRest);
  p.realTimeFactor = getDouble("real_time_factor", p.realTimeFactor);
  const std::string clock = getString("clock", toString(p.clock));
  if (!parseClock(clock, p.clock)) {
    throw ParamError("~clock is '" + clock + "': it must be 'wall' (paced by the wall clock, "
                     "stamped with it), 'sim' (this node serves /clock) or 'follow' (another node "
                     "serves /clock, e.g. Gazebo or rosbag play --clock)");
  }
  p.startPaused = getBool("start_paused", p.startPaused);
  p.pinned = getBoxes("pinned");
  p.renderTriangleBudget = getInt("render_triangle_budget", p.renderTriangleBudget);
  p.ground = getBool("ground", p.ground);
  p.groundClearance = getDouble("ground_clearance", p.groundClearance);
  p.colliders = getColliders("colliders", p.frameId);
  p.robot = getRobot();
  read_.push_back("tactile");
  if (has("tactile")) {
    XmlRpc::XmlRpcValue tactile = fetch("tactile");
    p.tactile = parseTactileList(tactile, p);
  }
  read_.push_back("cameras");
  if (has("cameras")) {
    XmlRpc::XmlRpcValue cameras = fetch("cameras");
    p.cameras = parseCameraList(cameras);
  }
  ObjectContactParams& oc = p.objectContact;
  oc.enabled = getBool("object_contact", oc.enabled);
  oc.selfContact = getBool("self_contact", oc.selfContact);
  oc.staticFriction = getDouble("object_static_friction", oc.staticFriction);
  oc.kineticFriction = getDouble("object_kinetic_friction", oc.kineticFriction);
  p.objectSleep = getBool("object_sleep", p.objectSleep);
  p.validate();
  p.applyMaterial();
  return p;
}

std::vector<ObjectSpec> ParamLoader::loadObjects(const NodeParams& params) const {
  read_.push_back("objects");
  if (!has("objects")) return {};
  XmlRpc::XmlRpcValue value = fetch("objects");
  return parseObjectList(value, params);
}

std::vector<std::string> ParamLoader::unknownParams() const {
  // What dynamic_reconfigure keeps next to the parameters (cfg/Flsm.cfg): the rest of its names
  // are parameters the node reads.
  static const char* const kReconfigureOnly[] = {"gravity_x", "gravity_y", "gravity_z"};
  std::vector<std::string> known(read_.begin(), read_.end());
  known.insert(known.end(), std::begin(kReconfigureOnly), std::end(kReconfigureOnly));
  std::vector<std::string> all, unknown;
  std::string prefix;
  if (pnh_) {
    ros::param::getParamNames(all);
    prefix = pnh_->getNamespace() + "/";
  } else {
    for (const auto& entry : tree_) all.push_back(entry.first);
  }
  for (const std::string& name : all) {
    if (name.rfind(prefix, 0) != 0) continue;
    const std::string rest = name.substr(prefix.size());
    const std::string first = rest.substr(0, rest.find('/'));
    if (std::find(known.begin(), known.end(), first) == known.end() &&
        std::find(unknown.begin(), unknown.end(), first) == unknown.end()) {
      unknown.push_back(first);
    }
  }
  return unknown;
}

double ParamLoader::getDouble(const std::string& name, double fallback) const {
  read_.push_back(name);
  if (!has(name)) {
    return fallback;
  }
  double value = 0.0;  // an int parameter is a number too
  XmlRpc::XmlRpcValue found = fetch(name);
  if (!toNumber(found, value)) {
    throwWrongType(name, "a number");
  }
  return value;
}

bool ParamLoader::getOfType(const std::string& name, XmlRpc::XmlRpcValue::Type type, const char* expected,
                            XmlRpc::XmlRpcValue& value) const {
  read_.push_back(name);
  if (!has(name)) {
    return false;
  }
  value = fetch(name);
  if (value.getType() != type) {
    throwWrongType(name, expected);
  }
  return true;
}

int ParamLoader::getInt(const std::string& name, int fallback) const {
  // Checked on the XML-RPC type: roscpp's getParam(int) would round a double.
  XmlRpc::XmlRpcValue value;
  return getOfType(name, XmlRpc::XmlRpcValue::TypeInt, "an integer", value) ? static_cast<int>(value) : fallback;
}

bool ParamLoader::getBool(const std::string& name, bool fallback) const {
  XmlRpc::XmlRpcValue value;
  return getOfType(name, XmlRpc::XmlRpcValue::TypeBoolean, "true or false", value) ? static_cast<bool>(value)
                                                                                     : fallback;
}

std::string ParamLoader::getString(const std::string& name, const std::string& fallback) const {
  XmlRpc::XmlRpcValue value;
  return getOfType(name, XmlRpc::XmlRpcValue::TypeString, "a string", value)
             ? static_cast<std::string&>(value)
             : fallback;
}

Eigen::Vector3d ParamLoader::getVector3(const std::string& name,
                                        const Eigen::Vector3d& fallback) const {
  read_.push_back(name);
  if (!has(name)) {
    return fallback;
  }
  XmlRpc::XmlRpcValue value = fetch(name);
  Eigen::Vector3d out;
  if (value.getType() != XmlRpc::XmlRpcValue::TypeArray || value.size() != 3 ||
      !toNumber(value[0], out.x()) || !toNumber(value[1], out.y()) ||
      !toNumber(value[2], out.z())) {
    throwWrongType(name, "a list of three numbers");
  }
  return out;
}

std::vector<Box> ParamLoader::getBoxes(const std::string& name) const {
  read_.push_back(name);
  std::vector<Box> boxes;
  if (!has(name)) {
    return boxes;
  }
  XmlRpc::XmlRpcValue value = fetch(name);
  constexpr const char* kExpected =
      "a list of boxes, each a list of six numbers [xmin, ymin, zmin, xmax, ymax, zmax] (m)";
  if (value.getType() != XmlRpc::XmlRpcValue::TypeArray) {
    throwWrongType(name, kExpected);
  }
  for (int b = 0; b < value.size(); ++b) {
    XmlRpc::XmlRpcValue& entry = value[b];
    Box box;
    bool ok = entry.getType() == XmlRpc::XmlRpcValue::TypeArray && entry.size() == 6;
    for (int k = 0; ok && k < 3; ++k) {
      ok = toNumber(entry[k], box.lo[k]) && toNumber(entry[k + 3], box.hi[k]);
    }
    if (!ok) {
      throw ParamError("~" + name + " entry " + std::to_string(b) + " is " + describe(entry) +
                       ": ~" + name + " must be " + kExpected);
    }
    boxes.push_back(box);
  }
  return boxes;
}

std::vector<ColliderSpec> ParamLoader::getColliders(const std::string& name,
                                                    const std::string& simFrame) const {
  read_.push_back(name);
  if (!has(name)) {
    return {};
  }
  XmlRpc::XmlRpcValue value = fetch(name);
  return parseColliderList(value, simFrame);
}

std::vector<std::string> ParamLoader::getStrings(const std::string& name,
                                                 const std::vector<std::string>& fallback) const {
  read_.push_back(name);
  if (!has(name)) {
    return fallback;
  }
  XmlRpc::XmlRpcValue value = fetch(name);
  std::vector<std::string> out;
  bool ok = value.getType() == XmlRpc::XmlRpcValue::TypeArray;
  for (int i = 0; ok && i < value.size(); ++i) {
    ok = value[i].getType() == XmlRpc::XmlRpcValue::TypeString;
    if (ok) out.push_back(static_cast<std::string&>(value[i]));
  }
  if (!ok) {
    throwWrongType(name, "a list of strings");
  }
  return out;
}

RobotColliders ParamLoader::getRobot() const {
  RobotColliderOptions o;
  o.descriptionParam = getString("robot_description", o.descriptionParam);
  o.includeLinks = getStrings("robot_links", o.includeLinks);
  o.excludeLinks = getStrings("robot_exclude_links", o.excludeLinks);
  o.excludeOverlapping = getBool("robot_exclude_overlapping", o.excludeOverlapping);
  o.staticFriction = getDouble("robot_static_friction", o.staticFriction);
  o.kineticFriction = getDouble("robot_kinetic_friction", o.kineticFriction);
  if (o.descriptionParam.empty()) {
    RobotColliders none;
    none.options = o;
    return none;
  }
  if (!pnh_) {
    // A tree: the URDF text under the key ~robot_description names.
    XmlRpc::XmlRpcValue xml = fetch(o.descriptionParam);
    if (o.descriptionParam == "robot_description") {
      // the node's files name the global parameter robot_description, which a tree has not
      throw ParamError("~robot_description names '" + o.descriptionParam + "', itself " + where(o.descriptionParam) +
                       ": put the URDF text under another key and name that key, or set "
                       "~robot_description to '' for no robot");
    }
    if (xml.getType() != XmlRpc::XmlRpcValue::TypeString) {
      throw ParamError("~robot_description names '" + o.descriptionParam + "', which " + where(o.descriptionParam) +
                       " is " + (has(o.descriptionParam) ? "not a string" : "not set") +
                       ": put the URDF text there, or set ~robot_description to '' for no robot");
    }
    read_.push_back(o.descriptionParam);
    return parseRobotColliders(static_cast<std::string&>(xml), o);
  }
  // Resolved as robot_state_publisher resolves it: in the node's namespace.
  const ros::NodeHandle nh;
  const std::string resolved = nh.resolveName(o.descriptionParam);
  std::string xml;
  if (!nh.hasParam(o.descriptionParam)) {
    throw ParamError("~robot_description names parameter '" + resolved + "', which is not set: "
                     "load the URDF there (e.g. <param name=\"robot_description\" textfile=...>), "
                     "or set ~robot_description to '' for no robot");
  }
  if (!nh.getParam(o.descriptionParam, xml)) {
    throw ParamError("~robot_description names parameter '" + resolved +
                     "', which is not a string: it must hold the URDF text");
  }
  o.descriptionParam = resolved;
  return parseRobotColliders(xml, o);
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
    TriMesh mesh = loadMesh(path, params.meshScale);
    rotateMesh(params.meshRpy, mesh);
    return mesh;
  } catch (const MeshError& e) {
    throw ParamError("~mesh '" + params.mesh + "' (file '" + path + "') cannot be used: " +
                     e.what() + ". Set ~mesh to a readable, closed triangle mesh.");
  }
}

}  // namespace deformable_flsm
