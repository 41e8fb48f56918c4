// Collider geometry: parsing and validation, signed distances and normals of every shape against
// their analytic values, the mesh distance field against the primitives it should reproduce.
#include "deformable_flsm/core/collider.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/mesh_distance_field.h"
#include "fixtures.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <limits>
#include <memory>
#include <random>

using namespace deformable_flsm;

namespace {

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;

ColliderShape box(const Eigen::Vector3d& half) {
  ColliderShape s;
  s.type = ColliderType::Box;
  s.halfExtents = half;
  return s;
}

ColliderShape sphere(double radius) {
  ColliderShape s;
  s.type = ColliderType::Sphere;
  s.radius = radius;
  return s;
}

ColliderShape capsule(double radius, double halfLength) {
  ColliderShape s;
  s.type = ColliderType::Capsule;
  s.radius = radius;
  s.halfLength = halfLength;
  return s;
}

ColliderShape cylinder(double radius, double halfLength) {
  ColliderShape s;
  s.type = ColliderType::Cylinder;
  s.radius = radius;
  s.halfLength = halfLength;
  return s;
}

/// The gradient of shapeDistance() by central differences: the normal must be it where the
/// distance is differentiable.
Eigen::Vector3d numericGradient(const ColliderShape& s, const Eigen::Vector3d& p, double eps = 1e-7) {
  Eigen::Vector3d g, n;
  for (int a = 0; a < 3; ++a) {
    Eigen::Vector3d d = Eigen::Vector3d::Zero();
    d[a] = eps;
    g[a] = (shapeDistance(s, p + d, n) - shapeDistance(s, p - d, n)) / (2 * eps);
  }
  return g;
}

std::vector<Eigen::Vector3d> randomPoints(std::size_t count, double extent, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-extent, extent);
  std::vector<Eigen::Vector3d> out;
  for (std::size_t i = 0; i < count; ++i) out.emplace_back(u(rng), u(rng), u(rng));
  return out;
}

}  // namespace

TEST(ColliderType, ParsesAndPrints) {
  for (ColliderType t : {ColliderType::HalfSpace, ColliderType::Box, ColliderType::Sphere, ColliderType::Capsule,
                         ColliderType::Cylinder, ColliderType::Mesh})
    EXPECT_EQ(parseColliderType(toString(t)), t);
  EXPECT_EQ(parseColliderType("half_space"), ColliderType::HalfSpace);
  try {
    parseColliderType("cone");
    FAIL() << "accepted 'cone'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("cone"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("cylinder"), std::string::npos) << "names the accepted words";
    EXPECT_NE(std::string(e.what()).find("capsule"), std::string::npos) << "names the accepted words";
  }
}

TEST(Collider, ValidateSaysWhatIsWrong) {
  auto message = [](const Collider& c) {
    try {
      c.validate();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  Collider c;
  EXPECT_EQ(message(c), "") << "a default collider (ground plane) is valid";
  c.shape = box(Eigen::Vector3d(0.1, -0.1, 0.1));
  EXPECT_NE(message(c).find("half extents"), std::string::npos);
  c.shape = box(Eigen::Vector3d(0.1, std::nan(""), 0.1));
  EXPECT_NE(message(c).find("half extents"), std::string::npos);
  c.shape = sphere(0.0);
  EXPECT_NE(message(c).find("radius"), std::string::npos);
  c.shape = capsule(0.1, -1.0);
  EXPECT_NE(message(c).find("half length"), std::string::npos);
  c.shape = cylinder(0.1, 0.0);
  EXPECT_NE(message(c).find("cylinder half length"), std::string::npos) << "a cylinder has a length";
  c.shape = cylinder(-0.1, 0.1);
  EXPECT_NE(message(c).find("cylinder radius"), std::string::npos);
  c.shape = ColliderShape();
  c.shape.type = ColliderType::Mesh;
  EXPECT_NE(message(c).find("without a mesh"), std::string::npos);
  c.shape.mesh = std::make_shared<const TriMesh>();
  EXPECT_NE(message(c).find("no triangles"), std::string::npos);
  TriMesh open = test::boxMesh(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
  open.triangles.erase(open.triangles.begin(), open.triangles.begin() + 2);
  c.shape.mesh = std::make_shared<const TriMesh>(open);
  EXPECT_NE(message(c).find("open edges"), std::string::npos);
  c.shape.mesh = std::make_shared<const TriMesh>(test::boxMesh(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()));
  EXPECT_EQ(message(c), "") << "a closed box mesh is a valid collider";
  c = Collider();
  c.staticFriction = 0.3;
  c.kineticFriction = 0.5;
  EXPECT_NE(message(c).find("exceeds static"), std::string::npos);
  c = Collider();
  c.staticFriction = std::numeric_limits<double>::infinity();
  EXPECT_NE(message(c).find("static friction"), std::string::npos);
  c = Collider();
  c.linearVelocity.x() = std::nan("");
  EXPECT_NE(message(c).find("linear velocity"), std::string::npos);
  c = Collider();
  c.pose.linear() *= 2.0;
  EXPECT_NE(message(c).find("rotation"), std::string::npos);
}

TEST(ShapeDistance, HalfSpaceIsTheHeightAlongItsNormal) {
  ColliderShape plane;
  Collider c;
  // tilted by 0.3 rad about y, origin at (1, 2, 3)
  c.pose = Eigen::Translation3d(1, 2, 3) * Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY());
  const Eigen::Vector3d n = c.pose.linear().col(2);
  for (const Eigen::Vector3d& x : randomPoints(100, 5.0, 1)) {
    Eigen::Vector3d normal;
    EXPECT_NEAR(colliderDistance(plane, c.pose, x, normal), n.dot(x - Eigen::Vector3d(1, 2, 3)), 1e-12);
    EXPECT_TRUE(normal.isApprox(n, 1e-12));
  }
}

TEST(ShapeDistance, BoxSphereCapsuleMatchTheirFormulas) {
  const Eigen::Vector3d e(0.3, 0.2, 0.1);
  const ColliderShape b = box(e), s = sphere(0.25), c = capsule(0.1, 0.2);
  int insideBox = 0;
  for (const Eigen::Vector3d& p : randomPoints(2000, 0.5, 2)) {
    Eigen::Vector3d n;
    // box: outside, distance to the clamped point; inside, minus the distance to the nearest face
    const Eigen::Vector3d clamped = p.cwiseMax(-e).cwiseMin(e);
    const double face = (e - p.cwiseAbs()).minCoeff();
    const double expectedBox = (p - clamped).norm() > 0 ? (p - clamped).norm() : -face;
    insideBox += expectedBox < 0;
    EXPECT_NEAR(shapeDistance(b, p, n), expectedBox, 1e-12) << p.transpose();
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    EXPECT_TRUE(n.isApprox(numericGradient(b, p), 1e-5)) << "box normal is the gradient at " << p.transpose();
    // sphere
    EXPECT_NEAR(shapeDistance(s, p, n), p.norm() - 0.25, 1e-12);
    EXPECT_TRUE(n.isApprox(p.normalized(), 1e-12));
    // capsule: distance to the segment minus the radius
    const Eigen::Vector3d axis(0, 0, std::clamp(p.z(), -0.2, 0.2));
    EXPECT_NEAR(shapeDistance(c, p, n), (p - axis).norm() - 0.1, 1e-12);
    EXPECT_TRUE(n.isApprox(numericGradient(c, p), 1e-5)) << "capsule normal is the gradient at " << p.transpose();
  }
  EXPECT_GT(insideBox, 50) << "the sample should reach inside the box";
  // degenerate points still get a unit normal
  Eigen::Vector3d n;
  EXPECT_NEAR(shapeDistance(s, Eigen::Vector3d::Zero(), n), -0.25, 1e-15);
  EXPECT_NEAR(n.norm(), 1.0, 1e-15);
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d(0, 0, 0.1), n), -0.1, 1e-15);
  EXPECT_NEAR(n.z(), 0.0, 1e-15) << "on the axis, the nearest surface is radial";
}

TEST(ShapeDistance, CylinderIsExactOnItsSideItsEndsAndItsRims) {
  // R = 0.1, H = 0.2: a flat-ended cylinder, not a capsule
  const double R = 0.1, H = 0.2;
  const ColliderShape c = cylinder(R, H);
  Eigen::Vector3d n;
  // beside the side: rho - R, radial
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d(0.0, 0.3, 0.15), n), 0.2, 1e-15);
  EXPECT_TRUE(n.isApprox(Eigen::Vector3d::UnitY(), 1e-15));
  // above an end disc (a capsule would give |p - (0, 0, H)| - R = 0.1 here): |z| - H
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d(0.06, 0.0, -0.25), n), 0.05, 1e-15);
  EXPECT_TRUE(n.isApprox(-Eigen::Vector3d::UnitZ(), 1e-15));
  // beyond a rim: the distance to the rim circle, along the line from it (a 3-4-5 triangle)
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d(R + 0.03, 0.0, H + 0.04), n), 0.05, 1e-15);
  EXPECT_TRUE(n.isApprox(Eigen::Vector3d(0.6, 0.0, 0.8), 1e-15));
  // inside: minus the distance to the nearer of the side and the end face
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d(0.0, 0.07, 0.0), n), -0.03, 1e-15);
  EXPECT_TRUE(n.isApprox(Eigen::Vector3d::UnitY(), 1e-15));
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d(0.0, 0.0, 0.19), n), -0.01, 1e-15);
  EXPECT_TRUE(n.isApprox(Eigen::Vector3d::UnitZ(), 1e-15));
  // on the axis, at the centre: the side is nearer (R < H), any radial direction
  EXPECT_NEAR(shapeDistance(c, Eigen::Vector3d::Zero(), n), -R, 1e-15);
  EXPECT_NEAR(n.norm(), 1.0, 1e-15);
  EXPECT_NEAR(n.z(), 0.0, 1e-15);

  // Everywhere, against the nearest point found independently: outside, the point clamped in
  // cylindrical coordinates (rho to R, z to [-H, H]); inside, the nearer face.
  int inside = 0, capRegion = 0;
  for (const Eigen::Vector3d& p : randomPoints(4000, 0.4, 5)) {
    const double rho = std::hypot(p.x(), p.y());
    double expected;
    if (rho <= R && std::abs(p.z()) <= H) {
      expected = -std::min(R - rho, H - std::abs(p.z()));
      ++inside;
    } else {
      const double s = rho > R ? R / rho : 1.0;
      const Eigen::Vector3d nearest(s * p.x(), s * p.y(), std::clamp(p.z(), -H, H));
      expected = (p - nearest).norm();
      capRegion += rho <= R;
    }
    EXPECT_NEAR(shapeDistance(c, p, n), expected, 1e-12) << p.transpose();
    EXPECT_NEAR(n.norm(), 1.0, 1e-12);
    EXPECT_TRUE(n.isApprox(numericGradient(c, p), 1e-5)) << "cylinder normal is the gradient at " << p.transpose();
  }
  EXPECT_GT(inside, 50) << "the sample should reach inside the cylinder";
  EXPECT_GT(capRegion, 50) << "and over its end discs";
}

TEST(ColliderBounds, CylinderBoundsAreTightAtAnyTilt) {
  // A link's cylinder is mostly tilted: its bounds are those of its two rim circles, so that the
  // broad phase does not see a far tilted link as near.
  const ColliderShape c = cylinder(0.05, 0.3);
  for (const double tilt : {0.0, 0.4, M_PI / 4, 1.2, M_PI / 2}) {
    const Eigen::Isometry3d pose(Eigen::Translation3d(0.2, -0.1, 0.3) *
                                 Eigen::AngleAxisd(tilt, Eigen::Vector3d(1, 1, 0).normalized()));
    Eigen::Vector3d lo, hi;
    ASSERT_TRUE(colliderBounds(c, pose, lo, hi));
    Eigen::Vector3d rimLo = Eigen::Vector3d::Constant(1e9), rimHi = -rimLo;
    for (int k = 0; k < 3600; ++k) {
      const double a = 2 * M_PI * k / 3600;
      for (const double z : {-0.3, 0.3}) {
        const Eigen::Vector3d x = pose * Eigen::Vector3d(0.05 * std::cos(a), 0.05 * std::sin(a), z);
        rimLo = rimLo.cwiseMin(x);
        rimHi = rimHi.cwiseMax(x);
      }
    }
    // sampled every 0.1 degree: the true extreme is at most R (1 - cos(0.05 deg)) beyond
    EXPECT_TRUE(lo.isApprox(rimLo, 1e-6) && hi.isApprox(rimHi, 1e-6))
        << "tilt " << tilt << ": bounds " << lo.transpose() << " / " << hi.transpose() << ", rims "
        << rimLo.transpose() << " / " << rimHi.transpose();
  }
}

TEST(ColliderBounds, ContainTheShapeAtAnyPose) {
  const Eigen::Isometry3d pose(Eigen::Translation3d(0.5, -0.2, 0.1) *
                               Eigen::AngleAxisd(0.7, Eigen::Vector3d(1, 2, 3).normalized()));
  for (const ColliderShape& s :
       {box(Eigen::Vector3d(0.3, 0.2, 0.1)), sphere(0.2), capsule(0.1, 0.3), cylinder(0.1, 0.3)}) {
    Eigen::Vector3d lo, hi, n;
    ASSERT_TRUE(colliderBounds(s, pose, lo, hi));
    for (const Eigen::Vector3d& p : randomPoints(3000, 1.0, 3)) {
      const Eigen::Vector3d x = pose * p;
      if (colliderDistance(s, pose, x, n) <= 0.0) {
        EXPECT_TRUE((x.array() >= lo.array() - 1e-12).all() && (x.array() <= hi.array() + 1e-12).all())
            << toString(s.type) << " point inside the shape outside its bounds";
      }
    }
    // and the broad phase never misses a box near the shape
    EXPECT_TRUE(boxNearCollider(s, pose, lo - Eigen::Vector3d::Constant(0.05), lo, 0.0));
    EXPECT_FALSE(boxNearCollider(s, pose, hi + Eigen::Vector3d::Constant(0.1), hi + Eigen::Vector3d::Constant(0.2), 0.05));
  }
  ColliderShape plane;
  Eigen::Vector3d lo, hi;
  EXPECT_FALSE(colliderBounds(plane, pose, lo, hi)) << "a half-space is unbounded";
  EXPECT_TRUE(boxNearCollider(plane, Eigen::Isometry3d::Identity(), Eigen::Vector3d(0, 0, 0.04),
                              Eigen::Vector3d(1, 1, 1), 0.05));
  EXPECT_FALSE(boxNearCollider(plane, Eigen::Isometry3d::Identity(), Eigen::Vector3d(0, 0, 0.06),
                               Eigen::Vector3d(1, 1, 1), 0.05));
}

TEST(AdvancePose, MovesAlongTheVelocityAndTurnsAboutTheAngularVelocity) {
  Eigen::Isometry3d pose(Eigen::Translation3d(1, 0, 0));
  const Eigen::Isometry3d later = advancePose(pose, Eigen::Vector3d(0, 2, 0), Eigen::Vector3d(0, 0, M_PI), 0.5);
  EXPECT_TRUE(later.translation().isApprox(Eigen::Vector3d(1, 1, 0), 1e-15));
  // a quarter turn about z: x -> y
  EXPECT_TRUE((later.linear() * Eigen::Vector3d::UnitX()).isApprox(Eigen::Vector3d::UnitY(), 1e-12));
}

TEST(MeshDistanceField, ReproducesABox) {
  const Eigen::Vector3d lo(-0.3, -0.2, -0.1), hi(0.3, 0.2, 0.1);
  const TriMesh mesh = test::boxMesh(lo, hi);
  const MeshDistanceField field(mesh, 40);
  const double dx = field.cellSize();
  EXPECT_NEAR(dx, 0.6 / 40, 1e-12);
  const ColliderShape exact = box(0.5 * (hi - lo));
  double worst = 0.0;
  // points over the grid (the mesh's bounds and two of the three padding cells)
  const Eigen::Vector3d reach = 0.5 * (hi - lo) + Eigen::Vector3d::Constant(2 * dx);
  for (Eigen::Vector3d p : randomPoints(4000, 1.0, 4)) {
    p = p.cwiseProduct(reach);
    Eigen::Vector3d n, ne;
    const double d = field.distance(p, n);
    const double de = shapeDistance(exact, p, ne);
    worst = std::max(worst, std::abs(d - de));
    // Trilinear interpolation is exact where the distance is affine over a cell; next to edges
    // and corners the distance bends within a cell: a cell's worth at most.
    EXPECT_NEAR(d, de, dx) << p.transpose();
    if (std::abs(de) > dx) {
      EXPECT_EQ(d < 0.0, de < 0.0) << "sign at " << p.transpose();
    }
    // near a face, two cells or more from its edges and from the box's medial planes, the field
    // is affine over the cell: exact, with the face's normal
    const Eigen::Vector3d q = p.cwiseAbs() - 0.5 * (hi - lo);
    int axis;
    q.maxCoeff(&axis);
    bool faceInterior = true;
    for (int a = 0; a < 3; ++a)
      if (a != axis && (q[a] > -2 * dx || q[a] > q[axis] - 3 * dx)) faceInterior = false;
    if (faceInterior && std::abs(q[axis]) < 2 * dx) {
      EXPECT_NEAR(d, de, 1e-9) << p.transpose();
      EXPECT_TRUE(n.isApprox(ne, 1e-6)) << p.transpose();
    }
  }
  std::cout << "box mesh field: cell " << dx << " m, worst |error| " << worst << " m\n";
  // far outside the grid: still the distance (grid value + gap)
  Eigen::Vector3d n;
  EXPECT_NEAR(field.distance(Eigen::Vector3d(5, 0, 0), n), 4.7, dx);
  EXPECT_TRUE(n.isApprox(Eigen::Vector3d::UnitX(), 1e-9));
}

TEST(MeshDistanceField, RefusesOpenMeshes) {
  TriMesh mesh = test::boxMesh(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones());
  mesh.triangles.erase(mesh.triangles.begin(), mesh.triangles.begin() + 2);
  EXPECT_THROW(MeshDistanceField field(mesh), MeshError);
}

TEST(MeshDistanceField, BunnyInsideAndOutside) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const TriMesh bunny = loadMesh(kBunnyPath, 0.1);
  const MeshDistanceField field(bunny, 32);
  // Voxelization: cells whose centre is inside by parity; the field must agree for centres more
  // than a field cell from the surface.
  VoxelizeOptions options;
  options.resolution = 16;
  const Voxelization voxels = voxelize(bunny, options);
  Eigen::Vector3d n;
  int deepInside = 0;
  for (const auto& cell : voxels.cells) {
    const double d = field.distance(voxels.cellCenter(cell), n);
    if (d < -field.cellSize()) ++deepInside;
    EXPECT_LT(d, 0.5 * std::sqrt(3.0) * voxels.spacing + field.cellSize())
        << "an occupied cell's centre lies within half a cell diagonal of the solid";
  }
  EXPECT_GT(deepInside, static_cast<int>(voxels.cells.size() / 4));
  const Eigen::Vector3d top = bunny.boundsMax() + Eigen::Vector3d::Constant(0.05);
  EXPECT_GT(field.distance(top, n), 0.05);
}

TEST(ProjectOutOfColliders, MovesOnlyThePointsThatAreTooClose) {
  std::map<std::string, Collider> colliders;
  colliders["ground"] = Collider();
  Collider ball;
  ball.shape = sphere(0.1);
  ball.pose.translation() = Eigen::Vector3d(1, 0, 0.5);
  colliders["ball"] = ball;
  std::vector<Eigen::Vector3d> points = {{0, 0, -0.02}, {0, 0, 0.004}, {0, 0, 0.3}, {1, 0, 0.45}};
  EXPECT_EQ(projectOutOfColliders(points, colliders, 0.005), 3u);
  EXPECT_TRUE(points[0].isApprox(Eigen::Vector3d(0, 0, 0.005), 1e-12));
  EXPECT_TRUE(points[1].isApprox(Eigen::Vector3d(0, 0, 0.005), 1e-12));
  EXPECT_TRUE(points[2].isApprox(Eigen::Vector3d(0, 0, 0.3), 1e-15)) << "far points stay";
  EXPECT_NEAR((points[3] - ball.pose.translation()).norm(), 0.105, 1e-12);
  EXPECT_THROW(projectOutOfColliders(points, colliders, -1.0), std::invalid_argument);
}
