#include "deformable_flsm/ros/object_params.h"

#include "xmlrpc_value.h"

#include <cctype>
#include <cmath>
#include <set>
#include <sstream>
#include <utility>

namespace deformable_flsm {

namespace {

/// Keys an entry of ~objects may have.
const char* const kKeys[] = {"name",           "mesh",          "mesh_scale",      "mesh_rpy",
                             "pose",           "youngs_modulus", "poissons_ratio", "density",
                             "damping",        "ambient_damping", "material",      "stiffness",
                             "spacing",        "resolution",    "particle_budget", "region_radius",
                             "region_half_width"};

/// Reads the keys of one ~objects entry; every error names the entry.
class ObjectReader {
 public:
  ObjectReader(XmlRpc::XmlRpcValue& entry, std::string label) : entry_(entry), label_(std::move(label)) {}

  [[noreturn]] void fail(const std::string& what) const {
    std::ostringstream out;
    out << label_;
    if (!name_.empty()) out << " ('" << name_ << "')";
    out << ": " << what;
    throw ParamError(out.str());
  }
  void setName(const std::string& name) { name_ = name; }

  bool has(const char* key) { return entry_.hasMember(key); }

  std::string string(const char* key, const std::string& fallback) {
    if (!has(key)) return fallback;
    XmlRpc::XmlRpcValue& v = entry_[key];
    if (v.getType() != XmlRpc::XmlRpcValue::TypeString)
      fail(std::string(key) + " is " + describe(v) + ": it must be a string");
    return static_cast<std::string&>(v);
  }

  double number(const char* key, double fallback) {
    if (!has(key)) return fallback;
    double out = 0.0;
    if (!toNumber(entry_[key], out) || !std::isfinite(out))
      fail(std::string(key) + " is " + describe(entry_[key]) + ": it must be a finite number");
    return out;
  }

  int integer(const char* key, int fallback) {
    if (!has(key)) return fallback;
    XmlRpc::XmlRpcValue& v = entry_[key];
    if (v.getType() != XmlRpc::XmlRpcValue::TypeInt)
      fail(std::string(key) + " is " + describe(v) + ": it must be an integer");
    return static_cast<int>(v);
  }

  /// A list of one of the `counts` lengths of finite numbers.
  Eigen::VectorXd numbers(const char* key, std::initializer_list<int> counts, const char* expected) {
    XmlRpc::XmlRpcValue& v = entry_[key];
    bool ok = v.getType() == XmlRpc::XmlRpcValue::TypeArray;
    bool lengthOk = false;
    for (int c : counts) lengthOk = lengthOk || (ok && v.size() == c);
    ok = ok && lengthOk;
    Eigen::VectorXd out(ok ? v.size() : 0);
    for (int k = 0; ok && k < v.size(); ++k) ok = toNumber(v[k], out[k]) && std::isfinite(out[k]);
    if (!ok) fail(std::string(key) + " is " + describe(v) + ": it must be " + expected);
    return out;
  }

  void checkKeys() {
    for (auto it = entry_.begin(); it != entry_.end(); ++it) {
      bool known = false;
      for (const char* k : kKeys) known = known || it->first == k;
      if (!known) {
        std::string all;
        for (const char* k : kKeys) all += std::string(all.empty() ? "" : ", ") + k;
        fail("unknown key '" + it->first + "' (misspelt?): the keys are " + all);
      }
    }
  }

 private:
  XmlRpc::XmlRpcValue& entry_;
  std::string label_;
  std::string name_;
};

Eigen::Isometry3d poseFrom(const Eigen::VectorXd& v) {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.translation() = v.head<3>();
  if (v.size() == 6) {
    // roll about x, then pitch about y, then yaw about z (fixed axes), as ~mesh_rpy and URDF
    pose.linear() = (Eigen::AngleAxisd(v[5], Eigen::Vector3d::UnitZ()) *
                     Eigen::AngleAxisd(v[4], Eigen::Vector3d::UnitY()) *
                     Eigen::AngleAxisd(v[3], Eigen::Vector3d::UnitX()))
                        .toRotationMatrix();
  }
  return pose;
}

}  // namespace

std::vector<ObjectSpec> parseObjectList(XmlRpc::XmlRpcValue& value, const NodeParams& defaults) {
  if (value.getType() != XmlRpc::XmlRpcValue::TypeArray || value.size() == 0)
    throw ParamError("~objects is " + describe(value) +
                     ": it must be a non-empty list of objects, each a dictionary with at least "
                     "a name (see README); leave it unset for the single object of ~mesh");
  if (static_cast<std::size_t>(value.size()) > ObjectLimits::kMaxObjects)
    throw ParamError("~objects has " + std::to_string(value.size()) + " entries: at most " +
                     std::to_string(ObjectLimits::kMaxObjects));
  std::vector<ObjectSpec> specs;
  std::set<std::string> names;
  for (int i = 0; i < value.size(); ++i) {
    const std::string label = "~objects entry " + std::to_string(i);
    specs.push_back(parseObjectEntry(value[i], defaults, label));
    if (!names.insert(specs.back().name).second)
      throw ParamError(label + " ('" + specs.back().name + "'): name '" + specs.back().name +
                       "' is used by an earlier entry");
  }
  return specs;
}

ObjectSpec parseObjectEntry(XmlRpc::XmlRpcValue& entry, const NodeParams& defaults,
                            const std::string& label) {
  ObjectReader r(entry, label);
  if (entry.getType() != XmlRpc::XmlRpcValue::TypeStruct)
    r.fail("it is " + describe(entry) + ": each entry must be a dictionary with at least a name");
  ObjectSpec spec;
  if (!r.has("name")) r.fail("it has no name: every object needs a unique name");
  spec.name = r.string("name", "");
  if (!validObjectName(spec.name))
    r.fail("name '" + spec.name + "' must be a letter followed by letters, digits or '_', at "
           "most " + std::to_string(ObjectLimits::kMaxNameLength) + " characters (it names a tf "
           "frame and the topics ~objects/<name>/...)");
  r.setName(spec.name);
  if (spec.name == defaults.frameId)
    r.fail("name '" + spec.name + "' is ~frame_id, the simulation frame: rename the object");
  r.checkKeys();

  NodeParams& p = spec.params;
  p = defaults;
  p.objectFrameId = spec.name;
  p.mesh = r.string("mesh", p.mesh);
  p.meshScale = r.number("mesh_scale", p.meshScale);
  if (r.has("mesh_rpy"))
    p.meshRpy = r.numbers("mesh_rpy", {3}, "a list of three finite angles [roll, pitch, yaw] (rad)")
                    .head<3>();
  if (r.has("pose"))
    spec.pose = poseFrom(r.numbers("pose", {3, 6},
                                   "[x, y, z] (m) or [x, y, z, roll, pitch, yaw] (m, rad)"));

  // The material: a key given here replaces the node's; the material kind stays the node's
  // unless the entry names it.
  const std::string material = r.string("material", toString(p.material));
  if (!parseMaterial(material, p.material))
    r.fail("material is '" + material + "': it must be 'youngs' (the stiffness from "
           "youngs_modulus) or 'classic' (alpha = stiffness per sub-step)");
  p.youngsModulus = r.number("youngs_modulus", p.youngsModulus);
  p.poissonsRatio = r.number("poissons_ratio", p.poissonsRatio);
  p.solver.density = r.number("density", p.solver.density);
  p.solver.damping = r.number("damping", p.solver.damping);
  p.solver.ambientDamping = r.number("ambient_damping", p.solver.ambientDamping);
  p.solver.stiffness = r.number("stiffness", p.solver.stiffness);

  // The lattice: one of spacing, resolution, particle_budget given here replaces the node's
  // choice as a whole (the node's ~spacing must not clash with the entry's resolution).
  if (r.has("spacing") || r.has("resolution") || r.has("particle_budget")) {
    p.spacing = r.number("spacing", 0.0);
    p.resolution = r.integer("resolution", 0);
    p.particleBudget = r.integer("particle_budget", NodeParams().particleBudget);
  }
  // The regions likewise: region_radius or region_half_width replaces the node's.
  if (r.has("region_radius") || r.has("region_half_width")) {
    p.regionRadius = r.number("region_radius", 0.0);
    p.regionHalfWidth = r.integer("region_half_width", 0);
  }
  try {
    p.validate();
  } catch (const ParamError& e) {
    // NodeParams speaks of the node's parameters (~spacing): here they are the entry's keys.
    std::string what = e.what();
    for (std::size_t at = what.find('~'); at != std::string::npos; at = what.find('~', at))
      what.erase(at, 1);
    r.fail(what);
  }
  p.applyMaterial();
  return spec;
}

}  // namespace deformable_flsm
