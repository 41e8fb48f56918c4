#include "deformable_flsm/ros/collider_command_validator.h"

#include "refusal.h"
#include "to_eigen.h"

#include "deformable_flsm/ros/collider_params.h"

#include <cmath>
#include <sstream>
#include <utility>

namespace deformable_flsm {

namespace {

using refusal::refuse;
using refusal::str;

/// A quaternion shorter than this is refused rather than normalised.
constexpr double kMinQuaternionNorm = 1e-6;

/// The message's pose, checked: finite, non-zero quaternion (normalised).
bool toPose(const ColliderCommand& msg, Eigen::Isometry3d& pose, Rejection& why) {
  const geometry_msgs::Quaternion& q = msg.pose.orientation;
  const Eigen::Vector4d qv(q.x, q.y, q.z, q.w);
  const Eigen::Vector3d position = toEigen(msg.pose.position);
  if (!position.allFinite() || !qv.allFinite())
    return refuse(why, "non_finite", "collider '" + msg.id + "': pose is not finite");
  if (qv.norm() < kMinQuaternionNorm)
    return refuse(why, "bad_orientation",
                  "collider '" + msg.id + "': the pose's quaternion is zero: give a unit "
                  "quaternion (w = 1 for no rotation)");
  Eigen::Quaterniond rotation;
  tf2::fromMsg(q, rotation);
  pose = Eigen::Translation3d(position) * rotation.normalized();
  return true;
}

/// The command's shape (type, sizes, mesh), or false with why it is refused; every numeric field
/// must be finite.
bool toShape(const ColliderCommand& msg, ColliderShape& shape, Rejection& why) {
  try {
    shape.type = parseColliderType(msg.type);
  } catch (const std::invalid_argument&) {
    return refuse(why, "bad_type", "collider '" + msg.id + "': type '" + msg.type +
                                       "' unknown: use plane, box, sphere, capsule, cylinder or mesh");
  }
  const Eigen::Vector3d size = toEigen(msg.size);
  if (!size.allFinite() || !std::isfinite(msg.radius) || !std::isfinite(msg.length) ||
      !std::isfinite(msg.mesh_scale) || !std::isfinite(msg.static_friction) ||
      !std::isfinite(msg.kinetic_friction))
    return refuse(why, "non_finite", "collider '" + msg.id + "': size " + str(size) +
                                         ", radius " + str(msg.radius) + ", length " +
                                         str(msg.length) + ", mesh_scale " + str(msg.mesh_scale) +
                                         ", friction " + str(msg.static_friction) + " / " +
                                         str(msg.kinetic_friction) + ": every field must be finite");
  switch (shape.type) {
    case ColliderType::HalfSpace:
      break;
    case ColliderType::Box:
      if ((size.array() <= 0.0).any())
        return refuse(why, "bad_size", "collider '" + msg.id + "': box size " + str(size) +
                                           ": the full edge lengths must be > 0 (m)");
      shape.halfExtents = 0.5 * size;
      break;
    case ColliderType::Cylinder:
      if (msg.length <= 0.0)
        return refuse(why, "bad_size", "collider '" + msg.id + "': cylinder length " +
                                           str(msg.length) + " must be > 0 (m)");
      [[fallthrough]];  // its length and radius as a capsule's
    case ColliderType::Capsule:
      if (msg.length < 0.0)
        return refuse(why, "bad_size", "collider '" + msg.id + "': capsule length " +
                                           str(msg.length) + " must be >= 0 (m)");
      shape.halfLength = 0.5 * msg.length;
      [[fallthrough]];
    case ColliderType::Sphere:
      if (msg.radius <= 0.0)
        return refuse(why, "bad_size", "collider '" + msg.id + "': radius " + str(msg.radius) +
                                           " must be > 0 (m)");
      shape.radius = msg.radius;
      break;
    case ColliderType::Mesh:
      try {
        loadColliderMesh(msg.mesh, msg.mesh_scale == 0.0 ? 1.0 : msg.mesh_scale, shape);
      } catch (const std::invalid_argument& e) {
        return refuse(why, "bad_mesh", "collider '" + msg.id + "': " + e.what());
      }
      break;
  }
  return true;
}

}  // namespace

ColliderCommandValidator::ColliderCommandValidator(std::string simFrame,
                                                   CommandValidator::TransformLookup lookup)
    : simFrame_(std::move(simFrame)), lookup_(std::move(lookup)) {}

bool ColliderCommandValidator::check(const ColliderCommand& msg, CommandBody& out,
                                     Rejection& why) const {
  if (msg.action != ColliderCommand::ADD && msg.action != ColliderCommand::MOVE &&
      msg.action != ColliderCommand::REMOVE)
    return refuse(why, "bad_action", "collider action " + std::to_string(msg.action) +
                                         " unknown: use ADD (0), MOVE (1) or REMOVE (2)");
  if (!validColliderId(msg.id))
    return refuse(why, "bad_id", "collider id '" + msg.id + "': use 1 to " +
                                     std::to_string(CommandLimits::kMaxIdLength) +
                                     " printable characters");
  if (msg.action == ColliderCommand::REMOVE) {
    out = RemoveColliderCommand{msg.id};
    return true;
  }
  Eigen::Isometry3d pose;
  if (!toPose(msg, pose, why)) return false;

  const bool follows = msg.action == ColliderCommand::ADD && !msg.follow_frame.empty() &&
                       msg.follow_frame != simFrame_;
  Eigen::Isometry3d simFromHeader = Eigen::Isometry3d::Identity();
  if (!follows && !msg.header.frame_id.empty() && msg.header.frame_id != simFrame_) {
    std::string reason;
    if (!lookup_(msg.header.frame_id, msg.header.stamp, simFromHeader, reason))
      return refuse(why, "unknown_frame", "collider '" + msg.id + "': no transform from frame '" +
                                              msg.header.frame_id + "' to '" + simFrame_ +
                                              "': " + reason);
    if (!simFromHeader.matrix().allFinite())
      return refuse(why, "unknown_frame", "collider '" + msg.id + "': the transform from '" +
                                              msg.header.frame_id + "' is not finite");
  }

  if (msg.action == ColliderCommand::MOVE) {
    const Eigen::Vector3d v = toEigen(msg.velocity.linear), w = toEigen(msg.velocity.angular);
    if (!v.allFinite() || !w.allFinite())
      return refuse(why, "non_finite", "collider '" + msg.id + "': velocity " + str(v) + ", " +
                                           str(w) + " is not finite");
    MoveColliderCommand move;
    move.id = msg.id;
    move.pose = simFromHeader * pose;
    move.linearVelocity = simFromHeader.linear() * v;  // vectors: rotated, not translated
    move.angularVelocity = simFromHeader.linear() * w;
    out = move;
    return true;
  }

  SetColliderCommand add;
  add.id = msg.id;
  add.followFrame = follows ? msg.follow_frame : std::string();
  add.collider.pose = simFromHeader * pose;
  if (!toShape(msg, add.collider.shape, why)) return false;
  if (msg.kinetic_friction < 0.0 || msg.static_friction < msg.kinetic_friction)
    return refuse(why, "bad_friction", "collider '" + msg.id + "': static_friction " +
                                           str(msg.static_friction) + ", kinetic_friction " +
                                           str(msg.kinetic_friction) +
                                           ": use 0 <= kinetic_friction <= static_friction");
  add.collider.staticFriction = msg.static_friction;
  add.collider.kineticFriction = msg.kinetic_friction;
  try {
    add.collider.validate();
  } catch (const std::invalid_argument& e) {
    return refuse(why, "bad_size", "collider '" + msg.id + "': " + e.what());
  }
  out = std::move(add);
  return true;
}

}  // namespace deformable_flsm
