#include "deformable_flsm/runtime/collider_spec.h"

#include "deformable_flsm/runtime/commands.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cctype>
#include <limits>

namespace deformable_flsm {

namespace {

constexpr const char kColliderFramePrefix[] = "flsm_collider/";

}  // namespace

std::string colliderFrameId(const std::string& id) { return kColliderFramePrefix + id; }

bool validColliderId(const std::string& id) {
  if (id.empty() || id.size() > CommandLimits::kMaxIdLength) return false;
  for (const char c : id)
    if (!std::isprint(static_cast<unsigned char>(c))) return false;
  return true;
}

Collider groundCollider(const Lattice& lattice, const TriMesh& mesh, const Eigen::Vector3d& gravity,
                        double contactRadius, double clearance) {
  const Eigen::Vector3d up =
      gravity.norm() > 0.0 ? Eigen::Vector3d(-gravity.normalized()) : Eigen::Vector3d::UnitZ();
  double lowest = std::numeric_limits<double>::infinity();
  for (const Eigen::Vector3d& v : mesh.vertices) lowest = std::min(lowest, up.dot(v));
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& x : lattice.restPositions()) {
    lowest = std::min(lowest, up.dot(x) - contactRadius);
    centre += x;
  }
  centre /= static_cast<double>(std::max<std::size_t>(1, lattice.size()));
  Collider ground;
  ground.shape.type = ColliderType::HalfSpace;
  // The plane's origin below the object's centre; its +z is `up`.
  const Eigen::Vector3d origin = centre + (lowest - clearance - up.dot(centre)) * up;
  ground.pose = Eigen::Translation3d(origin) *
                Eigen::Quaterniond::FromTwoVectors(Eigen::Vector3d::UnitZ(), up);
  return ground;
}

}  // namespace deformable_flsm
