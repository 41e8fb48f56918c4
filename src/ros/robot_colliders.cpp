#include "deformable_flsm/ros/robot_colliders.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/runtime/commands.h"
#include "deformable_flsm/ros/param_loader.h"

#include <urdf/model.h>

#include <regex>
#include <sstream>
#include <stdexcept>

namespace deformable_flsm {

namespace {


struct Pattern {
  std::string text;
  std::regex re;
  bool matched = false;
};

std::vector<Pattern> compile(const std::vector<std::string>& patterns, const char* param) {
  std::vector<Pattern> out;
  for (const std::string& p : patterns) {
    try {
      out.push_back({p, std::regex(p, std::regex::ECMAScript), false});
    } catch (const std::regex_error& e) {
      throw ParamError(std::string("~") + param + " pattern '" + p +
                       "' is not a regular expression (" + e.what() +
                       "): use e.g. 'finger_.*' for every link whose name starts with finger_");
    }
  }
  return out;
}

bool anyMatch(std::vector<Pattern>& patterns, const std::string& name) {
  bool any = false;
  for (Pattern& p : patterns) {
    if (std::regex_match(name, p.re)) {
      p.matched = true;
      any = true;
    }
  }
  return any;
}

Eigen::Isometry3d toEigen(const urdf::Pose& p) {
  const Eigen::Quaterniond q(p.rotation.w, p.rotation.x, p.rotation.y, p.rotation.z);
  return Eigen::Translation3d(p.position.x, p.position.y, p.position.z) * q.normalized();
}

/// The element's shape; throws ParamError naming the link and the element.
ColliderShape shapeOf(const urdf::Geometry& geometry, const std::string& where, std::string& meshUrl) {
  ColliderShape shape;
  switch (geometry.type) {
    case urdf::Geometry::BOX: {
      const auto& box = static_cast<const urdf::Box&>(geometry);
      shape.type = ColliderType::Box;
      shape.halfExtents = 0.5 * Eigen::Vector3d(box.dim.x, box.dim.y, box.dim.z);
      break;
    }
    case urdf::Geometry::SPHERE:
      shape.type = ColliderType::Sphere;
      shape.radius = static_cast<const urdf::Sphere&>(geometry).radius;
      break;
    case urdf::Geometry::CYLINDER: {
      const auto& cylinder = static_cast<const urdf::Cylinder&>(geometry);
      shape.type = ColliderType::Cylinder;
      shape.radius = cylinder.radius;
      shape.halfLength = 0.5 * cylinder.length;
      break;
    }
    case urdf::Geometry::MESH: {
      const auto& mesh = static_cast<const urdf::Mesh&>(geometry);
      shape.type = ColliderType::Mesh;
      meshUrl = mesh.filename;
      try {
        loadColliderMesh(mesh.filename, Eigen::Vector3d(mesh.scale.x, mesh.scale.y, mesh.scale.z),
                         shape);
      } catch (const std::invalid_argument& e) {
        throw ParamError(where + ": " + e.what() +
                         "; fix the URDF or leave the link out with ~robot_exclude_links");
      }
      break;
    }
  }
  try {
    shape.validate();
  } catch (const std::invalid_argument& e) {
    throw ParamError(where + ": " + e.what());
  }
  return shape;
}

std::string join(const std::vector<std::string>& names) {
  std::ostringstream out;
  for (std::size_t i = 0; i < names.size(); ++i) out << (i ? ", " : "") << names[i];
  return out.str();
}

}  // namespace

RobotColliders parseRobotColliders(const std::string& urdfXml, const RobotColliderOptions& options) {
  RobotColliders out;
  out.options = options;
  const std::string source = "~robot_description ('" + options.descriptionParam + "')";
  urdf::Model model;
  // urdfdom logs the parser's own reason (line, element) before returning false.
  if (urdfXml.empty() || !model.initString(urdfXml))
    throw ParamError(source + ": the URDF does not parse (the parser's reason is logged above); "
                     "fix the robot description, or set ~robot_description to '' for no robot");
  out.robotName = model.getName();
  std::vector<Pattern> include = compile(options.includeLinks, "robot_links");
  std::vector<Pattern> exclude = compile(options.excludeLinks, "robot_exclude_links");

  std::vector<urdf::LinkSharedPtr> links;
  model.getLinks(links);
  std::vector<std::string> names;
  std::vector<std::string> excluded;
  for (const urdf::LinkSharedPtr& link : links) {
    names.push_back(link->name);
    // Every pattern is tried on every link, so that one matching nothing can be named.
    const bool in = anyMatch(include, link->name);
    const bool out_ = anyMatch(exclude, link->name);
    if (link->collision_array.empty() || !in) continue;
    if (out_) {
      excluded.push_back(link->name);
      continue;
    }
    for (std::size_t k = 0; k < link->collision_array.size(); ++k) {
      const urdf::CollisionSharedPtr& c = link->collision_array[k];
      if (!c || !c->geometry) continue;
      const std::string where =
          "robot link '" + link->name + "' <collision> " + std::to_string(k);
      RobotCollider rc;
      rc.link = link->name;
      rc.spec.id = robotLinkWrenchId(link->name) + "/" + std::to_string(k);
      if (!validColliderId(rc.spec.id))
        throw ParamError(where + ": its collider id '" + rc.spec.id + "' is longer than " +
                         std::to_string(CommandLimits::kMaxIdLength) +
                         " characters; leave the link out with ~robot_exclude_links");
      rc.spec.followFrame = link->name;
      rc.spec.collider.shape = shapeOf(*c->geometry, where, rc.spec.meshUrl);
      rc.spec.collider.pose = toEigen(c->origin);
      rc.spec.collider.staticFriction = options.staticFriction;
      rc.spec.collider.kineticFriction = options.kineticFriction;
      try {
        rc.spec.collider.validate();
      } catch (const std::invalid_argument& e) {
        throw ParamError(where + ": " + e.what());
      }
      out.colliders.push_back(std::move(rc));
    }
  }
  for (const Pattern& p : include)
    if (!p.matched)
      out.warnings.push_back("~robot_links pattern '" + p.text + "' matches no link of robot '" +
                             out.robotName + "' (its links: " + join(names) + ")");
  for (const Pattern& p : exclude)
    if (!p.matched)
      out.warnings.push_back("~robot_exclude_links pattern '" + p.text +
                             "' matches no link of robot '" + out.robotName + "' (its links: " +
                             join(names) + ")");
  if (!excluded.empty())
    out.warnings.push_back("robot links left out by ~robot_exclude_links: " + join(excluded));
  return out;
}

}  // namespace deformable_flsm
