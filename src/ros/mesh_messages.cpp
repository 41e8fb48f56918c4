#include "deformable_flsm/ros/mesh_messages.h"

#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2_eigen/tf2_eigen.h>

#include <cmath>

namespace deformable_flsm {

namespace {

/// Opaque, light clay colour: shading stays readable on RViz's dark background.
constexpr std::array<float, 4> kMeshColor = {0.85f, 0.72f, 0.55f, 1.0f};

}  // namespace

std::array<float, 4> objectColor(std::size_t k) {
  if (k == 0) return kMeshColor;
  const double hue = std::fmod(0.08 + 0.618034 * static_cast<double>(k), 1.0) * 6.0;
  const double x = 1.0 - std::abs(std::fmod(hue, 2.0) - 1.0);
  std::array<double, 3> rgb{};
  switch (static_cast<int>(hue)) {
    case 0: rgb = {1, x, 0}; break;
    case 1: rgb = {x, 1, 0}; break;
    case 2: rgb = {0, 1, x}; break;
    case 3: rgb = {0, x, 1}; break;
    case 4: rgb = {x, 0, 1}; break;
    default: rgb = {1, 0, x}; break;
  }
  // pastel: halfway to white, as light as the clay colour
  return {static_cast<float>(0.45 + 0.5 * rgb[0]), static_cast<float>(0.45 + 0.5 * rgb[1]),
          static_cast<float>(0.45 + 0.5 * rgb[2]), 1.0f};
}

void initTriangleListMarker(const std::string& frameId, const std::string& ns,
                            const std::array<float, 4>& color, visualization_msgs::Marker& marker) {
  marker = visualization_msgs::Marker();
  marker.header.frame_id = frameId;
  marker.ns = ns;
  marker.id = 0;
  marker.type = visualization_msgs::Marker::TRIANGLE_LIST;
  marker.action = visualization_msgs::Marker::ADD;
  marker.pose.orientation.w = 1.0;  // identity: the points are already in frameId
  marker.scale.x = 1.0;
  marker.scale.y = 1.0;
  marker.scale.z = 1.0;
  marker.color.r = color[0];
  marker.color.g = color[1];
  marker.color.b = color[2];
  marker.color.a = color[3];
}

void setTriangleListPoints(const std::vector<Eigen::Vector3d>& vertices,
                           const std::vector<std::array<std::uint32_t, 3>>& triangles,
                           visualization_msgs::Marker& marker) {
  marker.points.resize(3 * triangles.size());
  std::size_t k = 0;
  for (const auto& tri : triangles) {
    for (const std::uint32_t v : tri) marker.points[k++] = tf2::toMsg(vertices[v]);
  }
}

void fillVertexCloud(const std::vector<Eigen::Vector3d>& vertices, const std::string& frameId,
                     sensor_msgs::PointCloud2& cloud) {
  cloud.header.frame_id = frameId;
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  if (cloud.fields.size() != 3) {
    // Not setPointCloud2FieldsByString(1, "xyz"): that pads each point to 16 bytes (for PCL's
    // SSE layout); three explicit float32 fields give a packed 12-byte point.
    modifier.setPointCloud2Fields(3, "x", 1, sensor_msgs::PointField::FLOAT32,  //
                                  "y", 1, sensor_msgs::PointField::FLOAT32,  //
                                  "z", 1, sensor_msgs::PointField::FLOAT32);
  }
  modifier.resize(vertices.size());  // height 1, width #V, unorganised
  cloud.is_dense = true;             // finite by construction: the mesh and solver are checked

  sensor_msgs::PointCloud2Iterator<float> ix(cloud, "x");
  sensor_msgs::PointCloud2Iterator<float> iy(cloud, "y");
  sensor_msgs::PointCloud2Iterator<float> iz(cloud, "z");
  for (const Eigen::Vector3d& x : vertices) {
    *ix = static_cast<float>(x.x());
    *iy = static_cast<float>(x.y());
    *iz = static_cast<float>(x.z());
    ++ix;
    ++iy;
    ++iz;
  }
}

void fillParticleCloud(const std::vector<Eigen::Vector3d>& positions,
                       const std::vector<Eigen::Vector3d>& restPositions,
                       const std::string& frameId, sensor_msgs::PointCloud2& cloud) {
  cloud.header.frame_id = frameId;
  sensor_msgs::PointCloud2Modifier modifier(cloud);
  if (cloud.fields.size() != 4) {
    modifier.setPointCloud2Fields(4, "x", 1, sensor_msgs::PointField::FLOAT32,  //
                                  "y", 1, sensor_msgs::PointField::FLOAT32,  //
                                  "z", 1, sensor_msgs::PointField::FLOAT32,  //
                                  "displacement", 1, sensor_msgs::PointField::FLOAT32);
  }
  modifier.resize(positions.size());
  cloud.is_dense = true;

  sensor_msgs::PointCloud2Iterator<float> ix(cloud, "x");
  sensor_msgs::PointCloud2Iterator<float> id(cloud, "displacement");
  for (std::size_t i = 0; i < positions.size(); ++i, ++ix, ++id) {
    const Eigen::Vector3d& x = positions[i];
    ix[0] = static_cast<float>(x.x());
    ix[1] = static_cast<float>(x.y());
    ix[2] = static_cast<float>(x.z());
    *id = static_cast<float>((x - restPositions[i]).norm());
  }
}

namespace {

/// Sphere diameter as a fraction of the lattice spacing: neighbours stay apart.
constexpr double kParticleSize = 0.35;
/// Drag lines and targets stand out at any lattice resolution.
constexpr double kDragLineWidth = 0.25;
constexpr double kTargetSize = 1.5;

void initListMarker(visualization_msgs::Marker& m, const char* ns, int id, int type, double size,
                    const std::array<float, 4>& color, const std::string& frameId) {
  m.header.frame_id = frameId;
  m.ns = ns;
  m.id = id;
  m.type = type;
  m.pose.orientation.w = 1.0;
  m.scale.x = m.scale.y = m.scale.z = size;
  m.color.r = color[0];
  m.color.g = color[1];
  m.color.b = color[2];
  m.color.a = color[3];
}

/// ADD when there is something to show, DELETE otherwise (RViz refuses empty lists).
void setAction(visualization_msgs::Marker& m) {
  m.action = m.points.empty() ? visualization_msgs::Marker::DELETE
                              : visualization_msgs::Marker::ADD;
}

}  // namespace

void fillLatticeMarkers(const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<char>& pinned,
                        const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& drags,
                        double spacing, const std::string& frameId,
                        visualization_msgs::MarkerArray& markers) {
  using visualization_msgs::Marker;
  markers.markers.resize(4);
  Marker& free = markers.markers[0];
  Marker& held = markers.markers[1];
  Marker& lines = markers.markers[2];
  Marker& targets = markers.markers[3];
  initListMarker(free, "particles", 0, Marker::SPHERE_LIST, kParticleSize * spacing, {0.6f, 0.7f, 0.8f, 1.0f},
                 frameId);
  initListMarker(held, "pinned", 1, Marker::SPHERE_LIST, kParticleSize * spacing, {0.9f, 0.15f, 0.1f, 1.0f},
                 frameId);
  initListMarker(lines, "drags", 2, Marker::LINE_LIST, kDragLineWidth * spacing, {1.0f, 0.85f, 0.1f, 1.0f},
                 frameId);
  initListMarker(targets, "drag_targets", 3, Marker::SPHERE_LIST, kTargetSize * spacing, {1.0f, 0.85f, 0.1f, 1.0f},
                 frameId);

  std::size_t nPinned = 0;
  for (const char p : pinned) nPinned += p ? 1 : 0;
  free.points.resize(positions.size() - nPinned);
  held.points.resize(nPinned);
  std::size_t f = 0, h = 0;
  for (std::size_t i = 0; i < positions.size(); ++i) {
    (pinned[i] ? held.points[h++] : free.points[f++]) = tf2::toMsg(positions[i]);
  }
  lines.points.resize(2 * drags.size());
  targets.points.resize(drags.size());
  for (std::size_t d = 0; d < drags.size(); ++d) {
    lines.points[2 * d] = tf2::toMsg(drags[d].first);
    lines.points[2 * d + 1] = tf2::toMsg(drags[d].second);
    targets.points[d] = tf2::toMsg(drags[d].second);
  }
  for (Marker& m : markers.markers) setAction(m);
}

bool allFinite(const visualization_msgs::Marker& marker) {
  for (const geometry_msgs::Point& p : marker.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) return false;
  }
  return true;
}

}  // namespace deformable_flsm
