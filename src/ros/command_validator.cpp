#include "deformable_flsm/ros/command_validator.h"

#include "refusal.h"
#include "to_eigen.h"

#include <cctype>
#include <cmath>
#include <sstream>
#include <utility>

namespace deformable_flsm {

namespace {

using refusal::refuse;
using refusal::str;

bool validId(const std::string& id) {
  if (id.empty() || id.size() > CommandLimits::kMaxIdLength) return false;
  for (const char c : id)
    if (!std::isprint(static_cast<unsigned char>(c))) return false;
  return true;
}

}  // namespace

CommandValidator::CommandValidator(std::size_t particleCount, double objectSize,
                                   std::string simFrame, TransformLookup lookup,
                                   CenterOfMass centerOfMass)
    : particleCount_(particleCount), objectSize_(objectSize), simFrame_(std::move(simFrame)),
      lookup_(std::move(lookup)), centerOfMass_(std::move(centerOfMass)) {}

bool CommandValidator::toSimFrame(const std_msgs::Header& header, Eigen::Isometry3d& T,
                                  Rejection& why) const {
  if (header.frame_id.empty() || header.frame_id == simFrame_) {
    T.setIdentity();
    return true;
  }
  std::string reason;
  if (!lookup_(header.frame_id, header.stamp, T, reason))
    return refuse(why, "unknown_frame", "no transform from frame '" + header.frame_id +
                                            "' to '" + simFrame_ + "': " + reason);
  if (!T.matrix().allFinite())
    return refuse(why, "unknown_frame", "transform from '" + header.frame_id + "' is not finite");
  return true;
}

bool CommandValidator::reachable(const Eigen::Vector3d& p, const char* what,
                                 Rejection& why) const {
  if (!p.allFinite())
    return refuse(why, "non_finite", std::string(what) + " " + str(p) + " is not finite");
  const double reach = CommandLimits::kMaxReach * objectSize_;
  const Eigen::Vector3d c = centerOfMass_();
  if ((p - c).norm() > reach)
    return refuse(why, "out_of_reach",
                  std::string(what) + " " + str(p) + " is " + str((p - c).norm()) +
                      " m from the object's centre " + str(c) + ": at most " + str(reach) +
                      " m (2 object sizes) in frame '" + simFrame_ + "'");
  return true;
}

bool CommandValidator::particleIndex(std::int32_t particle, Rejection& why) const {
  if (particle < -1 || particle >= static_cast<std::int64_t>(particleCount_))
    return refuse(why, "bad_index", "particle " + std::to_string(particle) +
                                        " out of range: use -1 or an index in [0, " +
                                        std::to_string(particleCount_) + ")");
  return true;
}

bool CommandValidator::drag(const DragCommand& msg, CommandBody& out, Rejection& why) const {
  if (msg.action != DragCommand::GRAB && msg.action != DragCommand::MOVE &&
      msg.action != DragCommand::RELEASE && msg.action != DragCommand::ATTACH)
    return refuse(why, "bad_action", "drag action " + std::to_string(msg.action) +
                                         " unknown: use GRAB (0), MOVE (1), RELEASE (2) or "
                                         "ATTACH (3)");
  if (!validId(msg.id))
    return refuse(why, "bad_id", "drag id '" + msg.id + "': use 1 to " +
                                     std::to_string(CommandLimits::kMaxIdLength) +
                                     " printable characters");
  if (msg.action == DragCommand::RELEASE) {
    out = ReleaseCommand{msg.id};
    return true;
  }
  // Every number must be finite, used or not: NaN anywhere means a broken sender.
  const Eigen::Vector3d point = toEigen(msg.point), target = toEigen(msg.target);
  if (!point.allFinite() || !target.allFinite() || !std::isfinite(msg.stiffness))
    return refuse(why, "non_finite", "drag '" + msg.id + "': point " + str(point) + ", target " +
                                         str(target) + ", stiffness " + str(msg.stiffness) +
                                         ": every field must be finite");
  Eigen::Isometry3d T;
  if (!toSimFrame(msg.header, T, why)) return false;
  const bool attach = msg.action == DragCommand::ATTACH;
  const Eigen::Vector3d simTarget = T * target;
  // ATTACH has no target: the frame carries the particles.
  if (!attach && !reachable(simTarget, "drag target", why)) return false;
  if (msg.action == DragCommand::MOVE) {
    out = MoveCommand{msg.id, simTarget};
    return true;
  }

  GrabCommand grab;
  grab.id = msg.id;
  grab.target = simTarget;
  if (!particleIndex(msg.particle, why)) return false;
  grab.particle = msg.particle;
  if (msg.particle < 0) {
    grab.point = T * point;
    if (!reachable(grab.point, "grab point", why)) return false;
    grab.count = msg.count == 0 ? 1 : msg.count;
    const std::size_t most = std::min<std::size_t>(CommandLimits::kMaxGrabCount, particleCount_);
    if (grab.count > most)
      return refuse(why, "bad_count", "drag '" + msg.id + "': count " +
                                          std::to_string(msg.count) + " out of range [1, " +
                                          std::to_string(most) + "]");
  }
  if (msg.stiffness < 0.0)
    return refuse(why, "bad_stiffness", "drag '" + msg.id + "': stiffness " +
                                            str(msg.stiffness) +
                                            " N/m: use 0 for a hard drag or > 0 for a spring");
  grab.stiffness = msg.stiffness;
  if (!attach) {
    out = grab;
    return true;
  }
  AttachCommand a;
  a.grab = grab;
  // The simulation frame itself does not move: nothing to follow.
  if (!(msg.header.frame_id.empty() || msg.header.frame_id == simFrame_))
    a.frame = msg.header.frame_id;
  a.pose = T;
  out = a;
  return true;
}

bool CommandValidator::force(const ForceCommand& msg, CommandBody& out, Rejection& why) const {
  if (msg.kind != ForceCommand::FORCE && msg.kind != ForceCommand::IMPULSE)
    return refuse(why, "bad_action", "force kind " + std::to_string(msg.kind) +
                                         " unknown: use FORCE (0) or IMPULSE (1)");
  const Eigen::Vector3d point = toEigen(msg.point), f = toEigen(msg.force);
  if (!point.allFinite() || !f.allFinite() || !std::isfinite(msg.radius) ||
      !std::isfinite(msg.duration))
    return refuse(why, "non_finite", "force: point " + str(point) + ", radius " +
                                         str(msg.radius) + ", force " + str(f) + ", duration " +
                                         str(msg.duration) + ": every field must be finite");
  if (!particleIndex(msg.particle, why)) return false;
  ApplyForceCommand push;
  push.impulse = msg.kind == ForceCommand::IMPULSE;
  if (!push.impulse && (msg.duration <= 0.0 || msg.duration > CommandLimits::kMaxForceDuration))
    return refuse(why, "bad_duration", "force duration " + str(msg.duration) +
                                           " s: it must be in (0, " +
                                           str(CommandLimits::kMaxForceDuration) +
                                           "] (use IMPULSE for an instantaneous push)");
  const double maxRadius = CommandLimits::kMaxRadius * objectSize_;
  if (msg.radius < 0.0 || msg.radius > maxRadius)
    return refuse(why, "bad_radius", "force radius " + str(msg.radius) + " m: it must be in [0, " +
                                         str(maxRadius) + "] (0 = the nearest particle)");
  Eigen::Isometry3d T;
  if (!toSimFrame(msg.header, T, why)) return false;
  push.particle = msg.particle;
  if (msg.particle < 0) {
    push.point = T * point;
    if (!reachable(push.point, "force point", why)) return false;
    push.radius = msg.radius;
  }
  push.force = T.linear() * f;  // a vector: rotated, not translated
  push.duration = push.impulse ? 0.0 : msg.duration;
  out = push;
  return true;
}

bool CommandValidator::box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
                           Rejection& why) const {
  if (!lo.allFinite() || !hi.allFinite())
    return refuse(why, "non_finite", "pin box " + str(lo) + " - " + str(hi) + " is not finite");
  if ((lo.array() > hi.array()).any())
    return refuse(why, "bad_box", "pin box min " + str(lo) + " exceeds max " + str(hi) +
                                      " on some axis");
  return true;
}

}  // namespace deformable_flsm
