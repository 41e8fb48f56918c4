#include "deformable_flsm/ros/collider_params.h"

#include "entry_reader.h"
#include "xmlrpc_value.h"

#include "deformable_flsm/core/mesh_distance_field.h"

#include "deformable_flsm/runtime/commands.h"
#include "deformable_flsm/ros/param_loader.h"

#include <Eigen/Geometry>

#include <cctype>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <tuple>

namespace deformable_flsm {

namespace {

/// A collider mesh as loaded from a file, with its distance field.
struct LoadedMesh {
  std::shared_ptr<const TriMesh> mesh;
  std::shared_ptr<const MeshDistanceField> distanceField;
};


/// Fields an entry of ~colliders may have.
const std::vector<std::string> kFields = {"id",          "type",  "frame_id", "position",
                                          "orientation", "size",  "radius",   "length",
                                          "mesh",        "mesh_scale", "static_friction",
                                          "kinetic_friction"};

}  // namespace

void loadColliderMesh(const std::string& url, double scale, ColliderShape& shape) {
  if (!std::isfinite(scale) || scale <= 0.0)
    throw std::invalid_argument("mesh_scale " + std::to_string(scale) +
                                " must be a finite factor > 0");
  loadColliderMesh(url, Eigen::Vector3d::Constant(scale), shape);
}

void loadColliderMesh(const std::string& url, const Eigen::Vector3d& scale, ColliderShape& shape) {
  if (url.empty()) throw std::invalid_argument("mesh is empty: give a mesh file or package:// URL");
  if (!scale.allFinite() || (scale.array() <= 0.0).any())
    throw std::invalid_argument("mesh scale [" + std::to_string(scale.x()) + ", " +
                                std::to_string(scale.y()) + ", " + std::to_string(scale.z()) +
                                "] must be finite factors > 0");
  std::string path;
  try {
    path = resolveMeshPath(url);
  } catch (const ParamError& e) {
    throw std::invalid_argument(std::string("mesh ") + e.what());
  }
  // Colliders of the same file at the same scale share one mesh and one distance field while
  // any of them (or a command carrying one, waiting in the simulation's queue) holds it: a flood
  // of mesh colliders then holds one field per mesh, not one per queued command.
  static std::mutex cacheMutex;
  using Key = std::tuple<std::string, double, double, double>;
  static std::map<Key, std::weak_ptr<const LoadedMesh>> cache;
  const Key key(path, scale.x(), scale.y(), scale.z());
  std::shared_ptr<const LoadedMesh> loaded;
  {
    std::lock_guard<std::mutex> lock(cacheMutex);
    auto it = cache.find(key);
    if (it != cache.end()) loaded = it->second.lock();
  }
  try {
    if (!loaded) {
      auto fresh = std::make_shared<LoadedMesh>();
      const bool uniform = scale.x() == scale.y() && scale.y() == scale.z();
      TriMesh read = loadMesh(path, uniform ? scale.x() : 1.0);
      if (!uniform) {
        for (Eigen::Vector3d& v : read.vertices) v = v.cwiseProduct(scale);
      }
      auto mesh = std::make_shared<const TriMesh>(std::move(read));
      fresh->distanceField = std::make_shared<const MeshDistanceField>(*mesh);
      fresh->mesh = std::move(mesh);
      loaded = fresh;
      std::lock_guard<std::mutex> lock(cacheMutex);
      for (auto it = cache.begin(); it != cache.end();)  // forget meshes nobody holds
        it = it->second.expired() ? cache.erase(it) : std::next(it);
      cache[key] = loaded;
    }
    // aliasing: the mesh and the field keep the whole entry alive
    shape.mesh = std::shared_ptr<const TriMesh>(loaded, loaded->mesh.get());
    shape.distanceField = std::shared_ptr<const MeshDistanceField>(loaded, loaded->distanceField.get());
  } catch (const MeshError& e) {
    throw std::invalid_argument("mesh '" + url + "' (file '" + path + "') cannot be used: " +
                                e.what());
  }
}

namespace {

/// An entry's shape: the sizes its type needs (each checked), a mesh loaded.
void readShape(EntryReader& r, ColliderSpec& spec) {
  ColliderShape& shape = spec.collider.shape;
  const auto needs = [&](const char* field) {
    if (!r.has(field)) r.fail(std::string("a ") + toString(shape.type) + " needs " + field);
  };
  switch (shape.type) {
    case ColliderType::HalfSpace:
      break;
    case ColliderType::Box: {
      needs("size");
      const Eigen::Vector3d size = r.numbers("size", 3, Eigen::Vector3d::Zero());
      if ((size.array() <= 0.0).any())
        r.fail("size is [" + std::to_string(size.x()) + ", " + std::to_string(size.y()) + ", " +
               std::to_string(size.z()) + "]: a box's full edge lengths must be > 0 (m)");
      shape.halfExtents = 0.5 * size;
      break;
    }
    case ColliderType::Cylinder:
      needs("length");
      needs("radius");
      shape.halfLength = 0.5 * r.number("length", 0.0);
      shape.radius = r.number("radius", 0.0);
      if (shape.halfLength <= 0.0)
        r.fail("length is " + std::to_string(2 * shape.halfLength) + ": it must be > 0 (m)");
      if (shape.radius <= 0.0)
        r.fail("radius is " + std::to_string(shape.radius) + ": it must be > 0 (m)");
      break;
    case ColliderType::Capsule:
      needs("length");
      shape.halfLength = 0.5 * r.number("length", 0.0);
      if (shape.halfLength < 0.0)
        r.fail("length is " + std::to_string(2 * shape.halfLength) + ": it must be >= 0 (m)");
      [[fallthrough]];
    case ColliderType::Sphere:
      needs("radius");
      shape.radius = r.number("radius", 0.0);
      if (shape.radius <= 0.0)
        r.fail("radius is " + std::to_string(shape.radius) + ": it must be > 0 (m)");
      break;
    case ColliderType::Mesh: {
      needs("mesh");
      spec.meshUrl = r.string("mesh", "");
      const double scale = r.number("mesh_scale", 1.0);
      if (scale <= 0.0)
        r.fail("mesh_scale is " + std::to_string(scale) + ": it must be > 0");
      try {
        loadColliderMesh(spec.meshUrl, scale, shape);
      } catch (const std::invalid_argument& e) {
        r.fail(e.what());
      }
      break;
    }
  }
}

}  // namespace

std::vector<ColliderSpec> parseColliderList(XmlRpc::XmlRpcValue& value,
                                            const std::string& simFrame) {
  if (value.getType() != XmlRpc::XmlRpcValue::TypeArray)
    throw ParamError("~colliders is " + describe(value) +
                     ": it must be a list of colliders, each a dictionary with at least id and "
                     "type (see README)");
  if (static_cast<std::size_t>(value.size()) > ColliderLimits::kMaxColliders)
    throw ParamError("~colliders has " + std::to_string(value.size()) + " entries: at most " +
                     std::to_string(ColliderLimits::kMaxColliders));
  std::vector<ColliderSpec> specs;
  std::set<std::string> ids;
  for (int i = 0; i < value.size(); ++i) {
    XmlRpc::XmlRpcValue& entry = value[i];
    EntryReader r(entry, "~colliders", i, kFields);
    if (entry.getType() != XmlRpc::XmlRpcValue::TypeStruct)
      r.fail("it is " + describe(entry) + ": each entry must be a dictionary with at least id "
             "and type");
    ColliderSpec spec;
    spec.id = r.string("id", "");
    if (!validColliderId(spec.id))
      r.fail("id '" + spec.id + "' must be 1 to " + std::to_string(CommandLimits::kMaxIdLength) +
             " printable characters");
    r.setId(spec.id);
    if (!ids.insert(spec.id).second) r.fail("id '" + spec.id + "' is used by an earlier entry");
    r.checkFields();

    ColliderShape& shape = spec.collider.shape;
    const std::string type = r.string("type", "");
    try {
      shape.type = parseColliderType(type);
    } catch (const std::invalid_argument&) {
      r.fail("type is '" + type + "': it must be plane, box, sphere, capsule, cylinder or mesh");
    }
    spec.followFrame = r.string("frame_id", "");
    if (spec.followFrame == simFrame) spec.followFrame.clear();

    const Eigen::Vector3d position = r.numbers("position", 3, Eigen::Vector3d::Zero());
    const Eigen::Vector4d q = r.numbers("orientation", 4, Eigen::Vector4d(0, 0, 0, 1));
    if (q.norm() < 1e-6)
      r.fail("orientation [x, y, z, w] is zero: give a unit quaternion, e.g. [0, 0, 0, 1]");
    const Eigen::Quaterniond rotation(q[3], q[0], q[1], q[2]);
    spec.collider.pose = Eigen::Translation3d(position) * rotation.normalized();

    readShape(r, spec);
    spec.collider.staticFriction = r.number("static_friction", spec.collider.staticFriction);
    spec.collider.kineticFriction = r.number("kinetic_friction", spec.collider.kineticFriction);
    if (spec.collider.kineticFriction < 0.0 ||
        spec.collider.staticFriction < spec.collider.kineticFriction)
      r.fail("static_friction " + std::to_string(spec.collider.staticFriction) +
             ", kinetic_friction " + std::to_string(spec.collider.kineticFriction) +
             ": they must satisfy 0 <= kinetic_friction <= static_friction");
    try {
      spec.collider.validate();
    } catch (const std::invalid_argument& e) {
      r.fail(e.what());
    }
    specs.push_back(std::move(spec));
  }
  return specs;
}

}  // namespace deformable_flsm
