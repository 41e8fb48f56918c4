/// @file mesh_messages.h
/// Builds the messages that show the (deforming) render mesh: a Marker TRIANGLE_LIST and a
/// PointCloud2 of its vertices. Pure functions of their inputs: no master, no publishing.
#pragma once

#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/ColorRGBA.h>
#include <visualization_msgs/Marker.h>

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace deformable_flsm {

/// Sets everything of a TRIANGLE_LIST marker except its points: frame, namespace, id, identity
/// pose (w = 1), scale (1, 1, 1), one opaque colour; RViz lights it with per-face normals.
/// @param[in]  frameId  header.frame_id
/// @param[in]  color    RGBA in [0, 1]
/// @param[out] marker   the marker, points cleared
void initTriangleListMarker(const std::string& frameId, const std::string& ns,
                            const std::array<float, 4>& color, visualization_msgs::Marker& marker);

/// Writes the 3 #T corner points of the triangles at the given vertex positions. The topology is
/// fixed, so after the first call the point array is only overwritten, never reallocated.
/// @param[in]     vertices   #V vertex positions (m)
/// @param[in]     triangles  #T triangles, indices into `vertices`
/// @param[in,out] marker     marker whose points are set (resized to 3 #T)
void setTriangleListPoints(const std::vector<Eigen::Vector3d>& vertices,
                           const std::vector<std::array<std::uint32_t, 3>>& triangles,
                           visualization_msgs::Marker& marker);

/// Fills an unorganised cloud (height 1) of packed float32 x, y, z, one point per vertex.
/// @param[in]     vertices  #V positions (m)
/// @param[in]     frameId   header.frame_id
/// @param[in,out] cloud     resized to #V points; its layout is set on the first call
void fillVertexCloud(const std::vector<Eigen::Vector3d>& vertices, const std::string& frameId,
                     sensor_msgs::PointCloud2& cloud);

}  // namespace deformable_flsm
