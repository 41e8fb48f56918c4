#include "deformable_flsm/runtime/robot_spec.h"

#include "deformable_flsm/core/contact.h"

namespace deformable_flsm {

namespace {

constexpr const char kIdPrefix[] = "robot/";

}  // namespace

std::string robotLinkWrenchId(const std::string& link) { return kIdPrefix + link; }

bool overlapsParticles(const ColliderShape& shape, const Eigen::Isometry3d& pose,
                       const std::vector<Eigen::Vector3d>& positions, double radius) {
  Eigen::Vector3d lo, hi;
  const bool bounded = colliderBounds(shape, pose, lo, hi);
  if (bounded) {
    lo.array() -= radius;
    hi.array() += radius;
  }
  for (const Eigen::Vector3d& x : positions) {
    if (bounded && ((x.array() < lo.array()).any() || (x.array() > hi.array()).any())) continue;
    Eigen::Vector3d n;
    if (colliderDistance(shape, pose, x, n) < radius) return true;
  }
  return false;
}

}  // namespace deformable_flsm
