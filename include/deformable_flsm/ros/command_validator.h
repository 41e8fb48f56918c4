/// @file command_validator.h
/// Turns ~drag and ~force messages into plain, range-checked commands in the simulation frame.
/// Needs no master: frames are resolved through an injected lookup (tf2 in the node, a table in
/// the tests).
#pragma once

#include "deformable_flsm/runtime/commands.h"

#include <deformable_flsm/DragCommand.h>
#include <deformable_flsm/ForceCommand.h>
#include <ros/time.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <functional>
#include <string>

namespace deformable_flsm {

/// Why a command was refused: a short key counted in ~state and a sentence for the log.
struct Rejection {
  std::string reason;
  std::string detail;
};

/// Checks every field (finite, in range, known frame, within reach of the object) and converts
/// to the simulation frame. Limits are CommandLimits relative to the object size.
class CommandValidator {
 public:
  /// Transform from `frame` to the simulation frame at `stamp` (zero: latest); false with a
  /// reason in `why` when it is not known.
  using TransformLookup = std::function<bool(const std::string& frame, const ros::Time& stamp,
                                             Eigen::Isometry3d& simFromFrame, std::string& why)>;
  /// The object's current centre of mass (m, simulation frame).
  using CenterOfMass = std::function<Eigen::Vector3d()>;

  /// @param[in] particleCount  #P lattice particles
  /// @param[in] objectSize     L, Lattice::objectSize() (m)
  /// @param[in] simFrame       ~frame_id; an empty header frame means this frame
  CommandValidator(std::size_t particleCount, double objectSize, std::string simFrame,
                   TransformLookup lookup, CenterOfMass centerOfMass);

  /// @return false with `why` set when the message is refused; otherwise `out` holds a
  ///         GrabCommand, MoveCommand or ReleaseCommand.
  bool drag(const DragCommand& msg, CommandBody& out, Rejection& why) const;
  /// @return false with `why` set when the message is refused; otherwise `out` holds a
  ///         ForceCommand (the mass-dependent limits are checked by the simulation loop).
  bool force(const ForceCommand& msg, CommandBody& out, Rejection& why) const;
  /// Box of a pin request: finite, min <= max.
  bool box(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, Rejection& why) const;

  double objectSize() const { return objectSize_; }

 private:
  bool toSimFrame(const std_msgs::Header& header, Eigen::Isometry3d& T, Rejection& why) const;
  /// A point in the simulation frame must be finite and within reach of the object.
  bool reachable(const Eigen::Vector3d& p, const char* what, Rejection& why) const;
  bool particleIndex(std::int32_t particle, Rejection& why) const;

  std::size_t particleCount_;
  double objectSize_;
  std::string simFrame_;
  TransformLookup lookup_;
  CenterOfMass centerOfMass_;
};

}  // namespace deformable_flsm
