/// @file mesh_messages.h
/// Builds the messages that show the simulation: the render mesh as a Marker TRIANGLE_LIST, its
/// vertices and the lattice particles as PointCloud2, and the lattice (particles, pins, drags)
/// as a MarkerArray. Pure functions of their inputs: no master, no publishing.
#pragma once

#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/ColorRGBA.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <string>
#include <utility>
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

/// A colour per object (rgba, 0..1), so that touching objects stay apart on screen and in the
/// cameras: the clay colour for the first, then hues around the wheel at the golden angle.
std::array<float, 4> objectColor(std::size_t k);

/// Fills an unorganised cloud (height 1) of packed float32 x, y, z, one point per vertex.
/// @param[in]     vertices  #V positions (m)
/// @param[in]     frameId   header.frame_id
/// @param[in,out] cloud     resized to #V points; its layout is set on the first call
void fillVertexCloud(const std::vector<Eigen::Vector3d>& vertices, const std::string& frameId,
                     sensor_msgs::PointCloud2& cloud);

/// Fills an unorganised cloud of the lattice particles: packed float32 x, y, z and
/// `displacement` = |x - x0| (m), 16 bytes per point, for RViz's Intensity colouring.
/// @param[in]     positions      #P current positions (m)
/// @param[in]     restPositions  #P rest positions (m)
/// @param[in]     frameId        header.frame_id
/// @param[in,out] cloud          resized to #P points; its layout is set on the first call
void fillParticleCloud(const std::vector<Eigen::Vector3d>& positions,
                       const std::vector<Eigen::Vector3d>& restPositions,
                       const std::string& frameId, sensor_msgs::PointCloud2& cloud);

/// The lattice as four markers, one namespace each so that RViz can show them separately:
/// "particles" (id 0, free particles, grey spheres), "pinned" (1, red spheres), "drags" (2,
/// yellow lines from the grabbed particles' centroid to the target) and "drag_targets" (3,
/// yellow spheres). A marker with nothing to show is sent with action DELETE, so that RViz
/// removes what it showed before.
/// @param[in]     positions  #P particle positions (m)
/// @param[in]     pinned     #P 1 for pinned particles
/// @param[in]     drags      (centroid, target) of every drag (m)
/// @param[in]     spacing    lattice spacing (m): sets the sphere size
/// @param[in]     frameId    header.frame_id
/// @param[in,out] markers    the four markers; point arrays are reused between calls
void fillLatticeMarkers(const std::vector<Eigen::Vector3d>& positions,
                        const std::vector<char>& pinned,
                        const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& drags,
                        double spacing, const std::string& frameId,
                        visualization_msgs::MarkerArray& markers);

/// true when every point of the marker is finite.
bool allFinite(const visualization_msgs::Marker& marker);

}  // namespace deformable_flsm
