// Message builders of the ROS adapter: pure functions, so plain gtests without a master.
#include "deformable_flsm/ros/mesh_messages.h"

#include <gtest/gtest.h>
#include <sensor_msgs/point_cloud2_iterator.h>

#include <cmath>

namespace deformable_flsm {
namespace {

// A unit right tetrahedron: 4 vertices, 4 triangles.
const std::vector<Eigen::Vector3d> kVertices = {
    {0.0, 0.0, 0.0}, {1.0, 0.0, 0.0}, {0.0, 1.0, 0.0}, {0.0, 0.0, 1.0}};
const std::vector<std::array<std::uint32_t, 3>> kTriangles = {
    {0, 2, 1}, {0, 1, 3}, {0, 3, 2}, {1, 2, 3}};

TEST(TriangleListMarker, HeaderPoseScaleAndColourAreWhatRVizNeeds) {
  visualization_msgs::Marker m;
  initTriangleListMarker("world", "ns", {0.1f, 0.2f, 0.3f, 1.0f}, m);
  EXPECT_EQ(m.header.frame_id, "world");
  EXPECT_EQ(m.type, visualization_msgs::Marker::TRIANGLE_LIST);
  EXPECT_EQ(m.action, visualization_msgs::Marker::ADD);
  EXPECT_EQ(m.pose.orientation.w, 1.0);  // an all-zero quaternion makes RViz reject the marker
  EXPECT_EQ(m.scale.x, 1.0);
  EXPECT_EQ(m.scale.y, 1.0);
  EXPECT_EQ(m.scale.z, 1.0);
  EXPECT_EQ(m.color.a, 1.0f);
  EXPECT_TRUE(m.points.empty());
}

TEST(TriangleListMarker, ThreeCornersPerTriangleInTriangleOrder) {
  visualization_msgs::Marker m;
  setTriangleListPoints(kVertices, kTriangles, m);
  ASSERT_EQ(m.points.size(), 3 * kTriangles.size());
  for (std::size_t t = 0; t < kTriangles.size(); ++t) {
    for (int c = 0; c < 3; ++c) {
      const Eigen::Vector3d& v = kVertices[kTriangles[t][c]];
      const geometry_msgs::Point& p = m.points[3 * t + c];
      EXPECT_EQ(p.x, v.x());
      EXPECT_EQ(p.y, v.y());
      EXPECT_EQ(p.z, v.z());
    }
  }
}

TEST(TriangleListMarker, MovedVerticesOverwriteWithoutReallocating) {
  visualization_msgs::Marker m;
  setTriangleListPoints(kVertices, kTriangles, m);
  const geometry_msgs::Point* storage = m.points.data();
  std::vector<Eigen::Vector3d> moved = kVertices;
  for (auto& v : moved) v += Eigen::Vector3d(0.5, 0.0, 0.0);
  setTriangleListPoints(moved, kTriangles, m);
  EXPECT_EQ(m.points.data(), storage);
  EXPECT_EQ(m.points[0].x, 0.5);
}

TEST(VertexCloud, PackedXyzFloat32OnePointPerVertex) {
  sensor_msgs::PointCloud2 cloud;
  fillVertexCloud(kVertices, "world", cloud);
  EXPECT_EQ(cloud.header.frame_id, "world");
  EXPECT_EQ(cloud.height, 1u);
  EXPECT_EQ(cloud.width, kVertices.size());
  ASSERT_EQ(cloud.fields.size(), 3u);
  for (const auto& f : cloud.fields) {
    EXPECT_EQ(f.datatype, sensor_msgs::PointField::FLOAT32);
  }
  EXPECT_EQ(cloud.point_step, 12u);  // packed: no padding
  EXPECT_EQ(cloud.data.size(), 12u * kVertices.size());

  sensor_msgs::PointCloud2ConstIterator<float> it(cloud, "x");
  for (const Eigen::Vector3d& v : kVertices) {
    EXPECT_EQ(it[0], static_cast<float>(v.x()));
    EXPECT_EQ(it[1], static_cast<float>(v.y()));
    EXPECT_EQ(it[2], static_cast<float>(v.z()));
    ++it;
  }
}

TEST(VertexCloud, RefillKeepsLayoutAndFollowsVertexCount) {
  sensor_msgs::PointCloud2 cloud;
  fillVertexCloud(kVertices, "world", cloud);
  const std::vector<Eigen::Vector3d> two(kVertices.begin(), kVertices.begin() + 2);
  fillVertexCloud(two, "world", cloud);
  EXPECT_EQ(cloud.width, 2u);
  EXPECT_EQ(cloud.fields.size(), 3u);
  EXPECT_EQ(cloud.data.size(), 24u);
}

TEST(ParticleCloud, PackedXyzAndDisplacement) {
  std::vector<Eigen::Vector3d> moved = kVertices;
  moved[2] += Eigen::Vector3d(0.0, 0.0, 0.25);
  sensor_msgs::PointCloud2 cloud;
  fillParticleCloud(moved, kVertices, "world", cloud);
  EXPECT_EQ(cloud.header.frame_id, "world");
  EXPECT_EQ(cloud.width, kVertices.size());
  ASSERT_EQ(cloud.fields.size(), 4u);
  EXPECT_EQ(cloud.fields[3].name, "displacement");
  EXPECT_EQ(cloud.point_step, 16u);  // packed
  sensor_msgs::PointCloud2ConstIterator<float> it(cloud, "x");
  sensor_msgs::PointCloud2ConstIterator<float> d(cloud, "displacement");
  for (std::size_t i = 0; i < moved.size(); ++i, ++it, ++d) {
    EXPECT_EQ(it[2], static_cast<float>(moved[i].z()));
    EXPECT_FLOAT_EQ(*d, i == 2 ? 0.25f : 0.0f);
  }
}

TEST(LatticeMarkers, PinnedAndFreeSplitDragsAsLines) {
  const std::vector<char> pinned = {1, 0, 0, 1};
  const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> drags = {
      {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0, 0, 1)}};
  visualization_msgs::MarkerArray a;
  fillLatticeMarkers(kVertices, pinned, drags, 0.01, "world", a);
  ASSERT_EQ(a.markers.size(), 4u);
  EXPECT_EQ(a.markers[0].points.size(), 2u);  // free
  EXPECT_EQ(a.markers[1].points.size(), 2u);  // pinned
  EXPECT_EQ(a.markers[1].points[1].z, 1.0);   // vertex 3
  EXPECT_EQ(a.markers[2].type, visualization_msgs::Marker::LINE_LIST);
  EXPECT_EQ(a.markers[2].points.size(), 2u);
  EXPECT_EQ(a.markers[3].points.size(), 1u);
  for (const auto& m : a.markers) {
    EXPECT_EQ(m.action, visualization_msgs::Marker::ADD);
    EXPECT_EQ(m.header.frame_id, "world");
    EXPECT_EQ(m.pose.orientation.w, 1.0);
    EXPECT_GT(m.scale.x, 0.0);
  }
  // Ids are distinct so that RViz keeps all four.
  EXPECT_NE(a.markers[0].id, a.markers[1].id);
}

TEST(LatticeMarkers, NothingToShowIsDeleted) {
  visualization_msgs::MarkerArray a;
  fillLatticeMarkers(kVertices, std::vector<char>(4, 0), {}, 0.01, "world", a);
  EXPECT_EQ(a.markers[0].action, visualization_msgs::Marker::ADD);
  EXPECT_EQ(a.markers[1].action, visualization_msgs::Marker::DELETE);  // no pins
  EXPECT_EQ(a.markers[2].action, visualization_msgs::Marker::DELETE);  // no drags
  EXPECT_EQ(a.markers[3].action, visualization_msgs::Marker::DELETE);
}

TEST(TriangleListMarker, FinitenessCheck) {
  visualization_msgs::Marker m;
  setTriangleListPoints(kVertices, kTriangles, m);
  EXPECT_TRUE(allFinite(m));
  m.points[5].y = std::nan("");
  EXPECT_FALSE(allFinite(m));
}

}  // namespace
}  // namespace deformable_flsm
