/// @file collider_command_validator.h
/// Turns ~collider messages (ColliderCommand) into plain, checked collider commands in the
/// simulation frame. Needs no master: frames are resolved through an injected lookup, meshes
/// through loadColliderMesh.
#pragma once

#include "deformable_flsm/ros/command_validator.h"
#include "deformable_flsm/runtime/commands.h"

#include <deformable_flsm/ColliderCommand.h>

#include <string>

namespace deformable_flsm {

class ColliderCommandValidator {
 public:
  /// @param[in] simFrame  ~frame_id; an empty header frame means this frame
  /// @param[in] lookup    transform from a frame to the simulation frame
  ColliderCommandValidator(std::string simFrame, CommandValidator::TransformLookup lookup);

  /// @return false with `why` set when the message is refused (reasons: bad_action, bad_id,
  ///         bad_type, non_finite, bad_orientation, bad_size, bad_friction, bad_mesh,
  ///         unknown_frame); otherwise `out` holds a SetColliderCommand (pose in the simulation
  ///         frame, or the offset in its follow frame), a MoveColliderCommand (pose and velocity
  ///         in the simulation frame) or a RemoveColliderCommand.
  bool check(const ColliderCommand& msg, CommandBody& out, Rejection& why) const;

 private:
  std::string simFrame_;
  CommandValidator::TransformLookup lookup_;
};

}  // namespace deformable_flsm
