/// @file scene_renderer.h
/// What a depth camera sees of the scene: the deformed render meshes, the colliders and the
/// ground, ray cast with Embree (Intel's ray tracing kernels, Debian's libembree-dev) on the CPU,
/// headless: per pixel the depth along the optical axis, a shaded colour and the label of what
/// was hit. Spheres are Embree's exact sphere primitives; planes exact quads; boxes, capsules and
/// cylinders tessellated finely enough for their depth to be within 0.1 % of their size; mesh
/// colliders as given. A collider's shape is built once and its vertices moved with its pose;
/// objects are triangle meshes whose vertices change each frame (their BVHs are refitted). Rays
/// go in packets of 4 x 4 pixels. No ROS.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/mesh.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {

/// A pinhole camera (REP 103 optical frame: x right, y down, z forward).
struct CameraIntrinsics {
  int width = 640;
  int height = 480;
  /// focal lengths and principal point (pixels): pixel (u, v) sees along ((u - cx) / fx,
  /// (v - cy) / fy, 1), as sensor_msgs/CameraInfo's K, image_geometry and depth_image_proc say
  double fx = 525.0, fy = 525.0, cx = 319.5, cy = 239.5;
  /// depths (m along z) nearer than near or farther than far are not seen
  double near = 0.05, far = 10.0;
};

/// One rendered frame, row-major, width x height.
struct RenderedView {
  int width = 0, height = 0;
  /// depth along the optical axis (m); NaN where nothing is seen
  std::vector<float> depth;
  /// rgb8, 3 bytes a pixel: the hit's colour, shaded by the angle to the view ray
  std::vector<std::uint8_t> rgb;
  /// what was hit (SceneRenderer::kNothing, objectLabel(), colliderLabel())
  std::vector<std::uint16_t> label;
};

class SceneRenderer {
 public:
  /// Label of a pixel that sees nothing.
  static constexpr std::uint16_t kNothing = 0;
  /// Object k (its index in setObjects()) is k + 1; collider i (its index in setColliders()'s
  /// map order) is kFirstCollider + i.
  static constexpr std::uint16_t kFirstCollider = 1000;
  static std::uint16_t objectLabel(std::size_t k) { return static_cast<std::uint16_t>(k + 1); }
  static std::uint16_t colliderLabel(std::size_t i) { return static_cast<std::uint16_t>(kFirstCollider + i); }

  /// A deformable object to draw: its triangles (fixed), its vertices now, its colour (0..1).
  struct Object {
    const std::vector<std::array<std::uint32_t, 3>>* triangles = nullptr;
    const std::vector<Eigen::Vector3d>* vertices = nullptr;
    Eigen::Vector3f color = Eigen::Vector3f(0.85f, 0.72f, 0.55f);
  };

  /// @throws std::runtime_error when Embree cannot start.
  SceneRenderer();
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  /// The objects of the next render(), in label order. A list of the same meshes as the last
  /// one only moves their vertices.
  void setObjects(const std::vector<Object>& objects);
  /// The colliders of the next render() (poses as given); a collider whose shape is unchanged
  /// keeps its built geometry and only moves.
  void setColliders(const std::map<std::string, Collider>& colliders);
  /// Renders the scene seen from `cameraPose` (the optical frame in the simulation frame).
  void render(const CameraIntrinsics& camera, const Eigen::Isometry3d& cameraPose, RenderedView& out);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace deformable_flsm
