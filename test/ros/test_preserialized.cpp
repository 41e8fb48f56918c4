// A heavy message serialized before publish() must be the same message on the wire: the bytes
// roscpp sends (length prefix and body) and the type a subscriber checks are the original's.
#include "deformable_flsm/ros/preserialized.h"

#include <gtest/gtest.h>
#include <sensor_msgs/PointCloud2.h>
#include <visualization_msgs/Marker.h>

#include <cstdint>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

template <typename M>
std::vector<std::uint8_t> onTheWire(const M& m) {
  const ros::SerializedMessage s = ros::serialization::serializeMessage(m);
  return std::vector<std::uint8_t>(s.buf.get(), s.buf.get() + s.num_bytes);
}

visualization_msgs::Marker triangles() {
  visualization_msgs::Marker m;
  m.header.frame_id = "world";
  m.header.stamp = ros::Time(12, 345);
  m.header.seq = 7;
  m.ns = "object";
  m.type = visualization_msgs::Marker::TRIANGLE_LIST;
  for (int i = 0; i < 30; ++i) {
    geometry_msgs::Point p;
    p.x = 0.1 * i;
    p.y = -0.2 * i;
    p.z = 1.0 / (i + 1);
    m.points.push_back(p);
  }
  return m;
}

}  // namespace

TEST(PreSerialized, SendsTheSameBytesAsTheMessage) {
  const visualization_msgs::Marker marker = triangles();
  std::vector<std::uint8_t> bytes;
  EXPECT_EQ(onTheWire(PreSerialized<visualization_msgs::Marker>::serialize(marker, bytes)),
            onTheWire(marker));
}

TEST(PreSerialized, ReusedStorageFollowsTheNewestMessage) {
  visualization_msgs::Marker marker = triangles();
  std::vector<std::uint8_t> bytes;
  PreSerialized<visualization_msgs::Marker>::serialize(marker, bytes);
  marker.points.resize(3);  // a smaller message in the same storage
  marker.header.stamp = ros::Time(13, 0);
  EXPECT_EQ(onTheWire(PreSerialized<visualization_msgs::Marker>::serialize(marker, bytes)),
            onTheWire(marker));
  sensor_msgs::PointCloud2 empty;
  std::vector<std::uint8_t> cloudBytes;
  EXPECT_EQ(onTheWire(PreSerialized<sensor_msgs::PointCloud2>::serialize(empty, cloudBytes)),
            onTheWire(empty));
}

TEST(PreSerialized, IsTheMessagesTypeForSubscribers) {
  using View = PreSerialized<sensor_msgs::PointCloud2>;
  namespace mt = ros::message_traits;
  EXPECT_EQ(std::string(mt::md5sum<View>()), mt::md5sum<sensor_msgs::PointCloud2>());
  EXPECT_EQ(std::string(mt::datatype<View>()), mt::datatype<sensor_msgs::PointCloud2>());
  EXPECT_EQ(std::string(mt::definition<View>()), mt::definition<sensor_msgs::PointCloud2>());
  EXPECT_TRUE(mt::hasHeader<View>());
}
