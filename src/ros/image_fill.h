/// @file image_fill.h
/// Private to the adapter: a sensor_msgs/Image filled from a row-major array of pixels.
#pragma once

#include <ros/time.h>
#include <sensor_msgs/Image.h>

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

namespace deformable_flsm {

/// `m` = the `rows` x `cols` image of `values` (`channels` values of T a pixel, row-major), in
/// `encoding` (sensor_msgs/image_encodings), little-endian.
template <class T>
void fillImage(const std::string& encoding, const std::vector<T>& values, int channels, int rows, int cols,
               const std::string& frame, const ros::Time& stamp, sensor_msgs::Image& m) {
  m.header.stamp = stamp;
  m.header.frame_id = frame;
  m.height = static_cast<std::uint32_t>(rows);
  m.width = static_cast<std::uint32_t>(cols);
  m.encoding = encoding;
  m.is_bigendian = 0;
  m.step = static_cast<std::uint32_t>(cols) * static_cast<std::uint32_t>(channels) *
           static_cast<std::uint32_t>(sizeof(T));
  m.data.resize(values.size() * sizeof(T));
  std::memcpy(m.data.data(), values.data(), m.data.size());
}

}  // namespace deformable_flsm
