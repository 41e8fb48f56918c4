#include "deformable_flsm/ros/mesh_messages.h"

#include <sensor_msgs/point_cloud2_iterator.h>

namespace deformable_flsm {

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
    for (const std::uint32_t v : tri) {
      const Eigen::Vector3d& x = vertices[v];
      geometry_msgs::Point& p = marker.points[k++];
      p.x = x.x();
      p.y = x.y();
      p.z = x.z();
    }
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

}  // namespace deformable_flsm
