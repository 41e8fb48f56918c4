#include "deformable_flsm/ros/collider_messages.h"

#include "deformable_flsm/ros/collider_params.h"

#include <tf2_eigen/tf2_eigen.h>

#include <Eigen/Geometry>

namespace deformable_flsm {

namespace {

/// The ground and other planes: light grey, slightly transparent so that the object's underside
/// shows through.
constexpr float kPlaneColor[4] = {0.8f, 0.8f, 0.78f, 0.75f};
/// Solid colliders: steel blue, slightly transparent.
constexpr float kSolidColor[4] = {0.35f, 0.5f, 0.75f, 0.8f};
/// A plane's slab is this fraction of its width thick.
constexpr double kPlaneThickness = 0.01;

visualization_msgs::Marker makeMarker(const std::string& ns, int id, int type,
                                      const std::string& frameId, const ros::Time& stamp,
                                      const Eigen::Isometry3d& pose, const float (&color)[4]) {
  visualization_msgs::Marker m;
  m.header.frame_id = frameId;
  m.header.stamp = stamp;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.action = visualization_msgs::Marker::ADD;
  m.pose = tf2::toMsg(pose);
  m.scale.x = m.scale.y = m.scale.z = 1.0;
  m.color.r = color[0];
  m.color.g = color[1];
  m.color.b = color[2];
  m.color.a = color[3];
  return m;
}

void setScale(visualization_msgs::Marker& m, double x, double y, double z) {
  m.scale.x = x;
  m.scale.y = y;
  m.scale.z = z;
}

/// Appends entry `id` to `out`: its force and torque in `frame`, stamped `stamp`, its contacts.
void appendEntry(ContactWrenches& out, const std::string& id, const std::string& frame, const ros::Time& stamp,
                 const Eigen::Vector3d& force, const Eigen::Vector3d& torque, std::size_t contacts) {
  geometry_msgs::WrenchStamped ws;
  ws.header.stamp = stamp;
  ws.header.frame_id = frame;
  tf2::toMsg(force, ws.wrench.force);
  tf2::toMsg(torque, ws.wrench.torque);
  out.ids.push_back(id);
  out.wrenches.push_back(ws);
  out.contacts.push_back(static_cast<std::uint32_t>(contacts));
}

}  // namespace

void fillColliderMarkers(const std::map<std::string, Collider>& colliders,
                         const std::string& frameId, double planeSize, const ros::Time& stamp,
                         visualization_msgs::MarkerArray& markers) {
  using visualization_msgs::Marker;
  markers.markers.clear();
  Marker clear;
  clear.header.frame_id = frameId;
  clear.header.stamp = stamp;
  clear.action = Marker::DELETEALL;
  clear.pose.orientation.w = 1.0;  // RViz warns about a zero quaternion even here
  markers.markers.push_back(clear);
  for (const auto& entry : colliders) {
    const std::string& ns = entry.first;
    const Collider& c = entry.second;
    const ColliderShape& s = c.shape;
    switch (s.type) {
      case ColliderType::HalfSpace: {
        const double thickness = kPlaneThickness * planeSize;
        const Eigen::Isometry3d slab = c.pose * Eigen::Translation3d(0.0, 0.0, -0.5 * thickness);
        Marker m = makeMarker(ns, 0, Marker::CUBE, frameId, stamp, slab, kPlaneColor);
        setScale(m, planeSize, planeSize, thickness);
        markers.markers.push_back(m);
        break;
      }
      case ColliderType::Box: {
        Marker m = makeMarker(ns, 0, Marker::CUBE, frameId, stamp, c.pose, kSolidColor);
        setScale(m, 2 * s.halfExtents.x(), 2 * s.halfExtents.y(), 2 * s.halfExtents.z());
        markers.markers.push_back(m);
        break;
      }
      case ColliderType::Sphere: {
        Marker m = makeMarker(ns, 0, Marker::SPHERE, frameId, stamp, c.pose, kSolidColor);
        setScale(m, 2 * s.radius, 2 * s.radius, 2 * s.radius);
        markers.markers.push_back(m);
        break;
      }
      case ColliderType::Cylinder: {
        const double d = 2 * s.radius;
        Marker m = makeMarker(ns, 0, Marker::CYLINDER, frameId, stamp, c.pose, kSolidColor);
        setScale(m, d, d, 2 * s.halfLength);
        markers.markers.push_back(m);
        break;
      }
      case ColliderType::Capsule: {
        const double d = 2 * s.radius;
        Marker body = makeMarker(ns, 0, Marker::CYLINDER, frameId, stamp, c.pose, kSolidColor);
        setScale(body, d, d, 2 * s.halfLength);
        markers.markers.push_back(body);
        for (int end = 0; end < 2; ++end) {
          const double z = end == 0 ? -s.halfLength : s.halfLength;
          Marker cap = makeMarker(ns, 1 + end, Marker::SPHERE, frameId, stamp,
                                  c.pose * Eigen::Translation3d(0.0, 0.0, z), kSolidColor);
          setScale(cap, d, d, d);
          markers.markers.push_back(cap);
        }
        break;
      }
      case ColliderType::Mesh: {
        Marker m = makeMarker(ns, 0, Marker::TRIANGLE_LIST, frameId, stamp, c.pose, kSolidColor);
        if (s.mesh) {
          m.points.reserve(3 * s.mesh->triangles.size());
          for (const auto& t : s.mesh->triangles) {
            for (const std::uint32_t v : t) m.points.push_back(tf2::toMsg(s.mesh->vertices[v]));
          }
        }
        markers.markers.push_back(m);
        break;
      }
    }
  }
}

void fillContactWrenches(const std::map<std::string, Collider>& colliders,
                         const std::map<std::string, ContactWrench>& wrenches,
                         const ros::Time& stamp, ContactWrenches& out) {
  fillContactWrenches(colliders, wrenches, {}, stamp, out);
}

void fillContactWrenches(const std::map<std::string, Collider>& colliders,
                         const std::map<std::string, ContactWrench>& wrenches,
                         const std::map<std::string, WrenchGroup>& groups, const ros::Time& stamp,
                         ContactWrenches& out) {
  out.header.stamp = stamp;
  out.ids.clear();
  out.wrenches.clear();
  out.contacts.clear();
  struct Body {
    const WrenchGroup* group = nullptr;
    Eigen::Vector3d force = Eigen::Vector3d::Zero(), torque = Eigen::Vector3d::Zero();
    std::size_t contacts = 0;
  };
  std::map<std::string, Body> bodies;
  for (const auto& entry : colliders) {
    const auto g = groups.find(entry.first);
    if (g != groups.end()) {
      const auto w = wrenches.find(entry.first);
      const ContactWrench cw = w == wrenches.end() ? ContactWrench() : w->second;
      const Eigen::Isometry3d& pc = entry.second.pose;
      const Eigen::Isometry3d pb = pc * g->second.offset.inverse();
      Body& b = bodies[g->second.id];
      b.group = &g->second;
      const Eigen::Matrix3d bodyFromSim = pb.linear().transpose();
      b.force += bodyFromSim * cw.force;
      b.torque += bodyFromSim * (cw.torque + (pc.translation() - pb.translation()).cross(cw.force));
      b.contacts += cw.contacts;
      continue;
    }
    const auto w = wrenches.find(entry.first);
    const ContactWrench cw = w == wrenches.end() ? ContactWrench() : w->second;
    // Sim -> collider frame: the transpose of the collider's rotation.
    const Eigen::Matrix3d colliderFromSim = entry.second.pose.linear().transpose();
    appendEntry(out, entry.first, colliderFrameId(entry.first), stamp, colliderFromSim * cw.force,
                colliderFromSim * cw.torque, cw.contacts);
  }
  for (const auto& entry : bodies)
    appendEntry(out, entry.first, entry.second.group->frame, stamp, entry.second.force, entry.second.torque,
                entry.second.contacts);
}

void colliderTransforms(const std::map<std::string, Collider>& colliders,
                        const std::string& frameId, const ros::Time& stamp,
                        std::vector<geometry_msgs::TransformStamped>& out) {
  out.clear();
  for (const auto& entry : colliders) {
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(entry.second.pose);
    t.header.stamp = stamp;
    t.header.frame_id = frameId;
    t.child_frame_id = colliderFrameId(entry.first);
    out.push_back(t);
  }
}

std::string objectWrenchId(const std::string& from, const std::string& on) {
  return "object/" + from + "/" + on;
}

void appendObjectWrenches(const std::vector<ObjectPairWrench>& pairs, const std::string& simFrame,
                          const ros::Time& stamp, ContactWrenches& out) {
  for (const ObjectPairWrench& pair : pairs)
    appendEntry(out, objectWrenchId(pair.from, pair.on), simFrame, stamp, pair.wrench.force, pair.wrench.torque,
                pair.wrench.contacts);
}

std::string dragWrenchId(const std::string& object, const std::string& drag) {
  return "drag/" + object + "/" + drag;
}

void appendDragWrenches(const std::vector<ObjectSnapshot>& objects, const std::string& simFrame,
                        const ros::Time& stamp, ContactWrenches& out) {
  for (const ObjectSnapshot& o : objects)
    for (const DragView& d : o.drags)
      appendEntry(out, dragWrenchId(o.name, d.id), simFrame, stamp, -d.force, -d.torque, d.particles);
}

}  // namespace deformable_flsm
