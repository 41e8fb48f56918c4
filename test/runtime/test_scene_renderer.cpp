/// @file test_scene_renderer.cpp
/// Tests of runtime/scene_renderer.h against ray geometry worked out here: the depth of a plane
/// seen straight and at a slant, of a sphere pixel by pixel, of the other shapes and of an
/// object's triangles at the centre; labels; colliders that move.
#include "deformable_flsm/runtime/scene_renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace {

/// A camera at `eye` looking straight down -z (optical x = +x, y = -y, z = -z).
Eigen::Isometry3d lookingDown(const Eigen::Vector3d& eye) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  T.translation() = eye;
  return T;
}

CameraIntrinsics smallCamera() {
  CameraIntrinsics c;
  c.width = 80;
  c.height = 60;
  c.fx = c.fy = 70.0;
  c.cx = 40.0;  // the centre pixel (40, 30) looks straight ahead
  c.cy = 30.0;
  c.near = 0.05;
  c.far = 10.0;
  return c;
}

/// The ray of pixel (u, v) in the simulation frame, with z = 1 in the optical frame.
Eigen::Vector3d rayOf(const CameraIntrinsics& c, const Eigen::Isometry3d& T, int u, int v) {
  return T.linear() * Eigen::Vector3d((u - c.cx) / c.fx, (v - c.cy) / c.fy, 1.0);
}

Collider shape(ColliderType type, const Eigen::Vector3d& at) {
  Collider c;
  c.shape.type = type;
  c.pose = Eigen::Translation3d(at) * Eigen::Isometry3d::Identity();
  return c;
}

float centreDepth(const RenderedView& view) {
  return view.depth[static_cast<std::size_t>(view.height / 2) * view.width + view.width / 2];
}

TEST(SceneRenderer, APlaneSeenStraightIsAtOneDepthEverywhere) {
  SceneRenderer r;
  r.setColliders({{"ground", shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero())}});
  RenderedView view;
  r.render(smallCamera(), lookingDown(Eigen::Vector3d(0.1, -0.2, 1.5)), view);
  for (std::size_t p = 0; p < view.depth.size(); ++p) {
    ASSERT_NEAR(view.depth[p], 1.5, 2e-6) << "pixel " << p;
    ASSERT_EQ(view.label[p], SceneRenderer::colliderLabel(0));
  }
}

TEST(SceneRenderer, ASlantedPlaneHasTheDepthOfItsRays) {
  // the plane through (0, 0, 0.2) with normal (0, sin 30, cos 30): t = n.(p - o) / n.d
  Collider plane = shape(ColliderType::HalfSpace, Eigen::Vector3d(0, 0, 0.2));
  plane.pose.linear() = Eigen::AngleAxisd(-M_PI / 6.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  SceneRenderer r;
  r.setColliders({{"wall", plane}});
  const CameraIntrinsics c = smallCamera();
  const Eigen::Isometry3d T = lookingDown(Eigen::Vector3d(0, 0, 1.2));
  RenderedView view;
  r.render(c, T, view);
  const Eigen::Vector3d n = plane.pose.linear().col(2);
  for (int v = 0; v < c.height; ++v)
    for (int u = 0; u < c.width; ++u) {
      const Eigen::Vector3d d = rayOf(c, T, u, v);
      const double t = n.dot(plane.pose.translation() - T.translation()) / n.dot(d);
      ASSERT_NEAR(view.depth[static_cast<std::size_t>(v) * c.width + u], t, 1e-5) << u << ", " << v;
    }
}

TEST(SceneRenderer, ASphereHasTheDepthOfItsRaysPixelByPixel) {
  Collider ball = shape(ColliderType::Sphere, Eigen::Vector3d(0.02, 0.01, 0.5));
  ball.shape.radius = 0.1;
  SceneRenderer r;
  r.setColliders({{"ball", ball}, {"ground", shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero())}});
  const CameraIntrinsics c = smallCamera();
  const Eigen::Isometry3d T = lookingDown(Eigen::Vector3d(0, 0, 1.5));
  RenderedView view;
  r.render(c, T, view);
  int onBall = 0, mislabelled = 0;
  for (int v = 0; v < c.height; ++v)
    for (int u = 0; u < c.width; ++u) {
      const std::size_t p = static_cast<std::size_t>(v) * c.width + u;
      const Eigen::Vector3d d = rayOf(c, T, u, v);
      // |o + t d - centre| = r: a t^2 + b t + cc = 0
      const Eigen::Vector3d oc = T.translation() - ball.pose.translation();
      const double a = d.squaredNorm(), b = 2.0 * oc.dot(d), cc = oc.squaredNorm() - 0.01;
      const double disc = b * b - 4.0 * a * cc;
      const bool hits = disc > 0.0;
      const double t = hits ? (-b - std::sqrt(disc)) / (2.0 * a) : 1.5;  // else the ground
      if (std::abs(disc) < 1e-4) continue;  // the silhouette's pixels
      ASSERT_NEAR(view.depth[p], t, 1e-5) << u << ", " << v;
      onBall += hits;
      mislabelled += view.label[p] != (hits ? SceneRenderer::colliderLabel(0) : SceneRenderer::colliderLabel(1));
    }
  EXPECT_GT(onBall, 100);
  EXPECT_EQ(mislabelled, 0);
  // the centre pixel looks straight down, 0.0224 m beside the sphere's centre
  EXPECT_NEAR(centreDepth(view), 1.5 - 0.5 - std::sqrt(0.01 - 0.02 * 0.02 - 0.01 * 0.01), 1e-5);
}

TEST(SceneRenderer, TessellatedShapesAreWithinAThousandthOfTheirSize) {
  const CameraIntrinsics c = smallCamera();
  const Eigen::Isometry3d T = lookingDown(Eigen::Vector3d(0, 0, 1.0));
  // box top at 0.1 + 0.05, cylinder's flat end at 0.1 + 0.08, a capsule lying along y
  // (rotated about x) seen on its side: top at 0.1 + its radius
  Collider box = shape(ColliderType::Box, Eigen::Vector3d(0, 0, 0.1));
  box.shape.halfExtents = Eigen::Vector3d(0.05, 0.07, 0.05);
  Collider cylinder = shape(ColliderType::Cylinder, Eigen::Vector3d(0, 0, 0.1));
  cylinder.shape.radius = 0.04;
  cylinder.shape.halfLength = 0.08;
  Collider capsule = shape(ColliderType::Capsule, Eigen::Vector3d(0, 0, 0.1));
  capsule.shape.radius = 0.03;
  capsule.shape.halfLength = 0.1;
  capsule.pose.linear() = Eigen::AngleAxisd(M_PI / 2.0, Eigen::Vector3d::UnitX()).toRotationMatrix();
  const std::vector<std::pair<Collider, double>> cases = {{box, 0.15}, {cylinder, 0.18}, {capsule, 0.13}};
  for (const auto& [collider, top] : cases) {
    SceneRenderer r;
    r.setColliders({{"shape", collider}});
    RenderedView view;
    r.render(c, T, view);
    EXPECT_NEAR(centreDepth(view), 1.0 - top, 1e-4) << toString(collider.shape.type);
  }
}

TEST(SceneRenderer, AnObjectIsDrawnWithItsLabelAndItsVerticesFollowed) {
  // a square of two triangles at z = 0.3 (object 0) over the ground
  std::vector<std::array<std::uint32_t, 3>> triangles = {{0, 1, 2}, {0, 2, 3}};
  std::vector<Eigen::Vector3d> vertices = {{-1, -1, 0.3}, {1, -1, 0.3}, {1, 1, 0.3}, {-1, 1, 0.3}};
  SceneRenderer r;
  r.setColliders({{"ground", shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero())}});
  r.setObjects({{&triangles, &vertices, Eigen::Vector3f(1, 0, 0)}});
  const CameraIntrinsics c = smallCamera();
  const Eigen::Isometry3d T = lookingDown(Eigen::Vector3d(0, 0, 1.0));
  RenderedView view;
  r.render(c, T, view);
  EXPECT_NEAR(centreDepth(view), 0.7, 1e-6);
  EXPECT_EQ(view.label[static_cast<std::size_t>(c.height / 2) * c.width + c.width / 2], SceneRenderer::objectLabel(0));
  // lit straight on: the object's colour at full light
  EXPECT_EQ(view.rgb[3 * (static_cast<std::size_t>(c.height / 2) * c.width + c.width / 2)], 255);
  // moved (the same mesh, new vertices): refitted, not rebuilt
  for (Eigen::Vector3d& x : vertices) x.z() = 0.5;
  r.setObjects({{&triangles, &vertices, Eigen::Vector3f(1, 0, 0)}});
  r.render(c, T, view);
  EXPECT_NEAR(centreDepth(view), 0.5, 1e-6);
  // a collider moved by its pose
  Collider ball = shape(ColliderType::Sphere, Eigen::Vector3d(0, 0, 0.7));
  ball.shape.radius = 0.05;
  r.setColliders({{"ball", ball}, {"ground", shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero())}});
  r.render(c, T, view);
  EXPECT_NEAR(centreDepth(view), 0.25, 1e-5);
  ball.pose.translation().z() = 0.8;
  r.setColliders({{"ball", ball}, {"ground", shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero())}});
  r.render(c, T, view);
  EXPECT_NEAR(centreDepth(view), 0.15, 1e-5);
}

TEST(SceneRenderer, NothingWithinRangeIsNaNAndLabelledNothing) {
  SceneRenderer r;
  r.setColliders({{"ground", shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero())}});
  CameraIntrinsics c = smallCamera();
  c.far = 1.0;  // the ground is 1.5 away
  RenderedView view;
  r.render(c, lookingDown(Eigen::Vector3d(0, 0, 1.5)), view);
  for (std::size_t p = 0; p < view.depth.size(); ++p) {
    ASSERT_TRUE(std::isnan(view.depth[p]));
    ASSERT_EQ(view.label[p], SceneRenderer::kNothing);
  }
}

// A box over the ground seen straight down (rays along the axes: direction components exactly 0,
// the camera inside the box's x and y slabs): the box's top where the box is, the ground around
// it, pixel by pixel, both with their labels; then the same id turned into a plane and back.
TEST(SceneRenderer, ABoxOverThePlaneAndTheSameIdAsAPlaneAndABoxAgain) {
  SceneRenderer r;
  Collider box = shape(ColliderType::Box, Eigen::Vector3d(0, 0, 0.25));
  box.shape.halfExtents = Eigen::Vector3d(0.2, 0.2, 0.25);  // top at z = 0.5
  const Collider ground = shape(ColliderType::HalfSpace, Eigen::Vector3d::Zero());
  const CameraIntrinsics c = smallCamera();
  const Eigen::Isometry3d T = lookingDown(Eigen::Vector3d(0, 0, 1.5));
  RenderedView view;
  const auto check = [&](bool boxThere) {
    r.render(c, T, view);
    for (int v = 0; v < c.height; ++v) {
      for (int u = 0; u < c.width; ++u) {
        const Eigen::Vector3d d = rayOf(c, T, u, v);
        const Eigen::Vector3d onTop = T.translation() + d * (1.0 / -d.z());  // z = 0.5
        const bool onBox = boxThere && std::abs(onTop.x()) < 0.2 && std::abs(onTop.y()) < 0.2;
        const std::size_t p = static_cast<std::size_t>(v) * c.width + u;
        // pixels whose ray passes within a hair of the box's edge may go either way
        if (boxThere && std::abs(std::max(std::abs(onTop.x()), std::abs(onTop.y())) - 0.2) < 1e-4) continue;
        ASSERT_NEAR(view.depth[p], onBox ? 1.0 : 1.5, 1e-5) << u << ", " << v;
        const std::uint16_t label = view.label[p];
        ASSERT_EQ(label, onBox ? SceneRenderer::colliderLabel(0) : SceneRenderer::colliderLabel(boxThere ? 1 : 0))
            << u << ", " << v;
      }
    }
  };
  // colliders in id order: "a" (the box) then "b" (the ground)
  r.setColliders({{"a", box}, {"b", ground}});
  check(true);
  r.setColliders({{"a", ground}, {"b", ground}});  // "a" a plane now, at the same place as "b"
  check(false);
  r.setColliders({{"a", box}, {"b", ground}});
  check(true);
}

}  // namespace
}  // namespace deformable_flsm
