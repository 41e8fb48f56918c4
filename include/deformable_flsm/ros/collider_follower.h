/// @file collider_follower.h
/// Colliders that follow tf frames: samples each frame's latest transform without waiting
/// (tf2::BufferCore, no timeout), derives the velocity from the last two transforms, and hands
/// pose and velocity to the simulation (SimulationLoop::setColliderMotion). Needs no master:
/// the tests fill a BufferCore by hand.
#pragma once

#include "deformable_flsm/ros/simulation_loop.h"

#include <ros/time.h>
#include <tf2/buffer_core.h>

#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace deformable_flsm {

class ColliderFollower {
 public:
  /// Receives a collider's new pose and velocity (simulation frame).
  using Post = std::function<void(const std::string& id, const ColliderMotion& motion)>;

  /// A frame whose newest transform is older than this (s) is stale: its collider holds still.
  static constexpr double kStaleAfter = 0.5;

  /// @param[in] buffer    where transforms are looked up (latest available, never waiting)
  /// @param[in] simFrame  ~frame_id
  ColliderFollower(const tf2::BufferCore& buffer, std::string simFrame);

  /// Collider `id` follows `frame`; `offset` is its pose in that frame. Any thread.
  void follow(const std::string& id, const std::string& frame, const Eigen::Isometry3d& offset);
  /// Collider `id` follows no frame any more (nothing happens if it did not). Any thread.
  void forget(const std::string& id);
  /// true when some collider follows a frame.
  bool empty() const;

  /// Samples every followed frame at wall time `now` and posts, for each collider:
  ///   - a new transform: its pose and the velocity from the previous transform (zero for the
  ///     first one and for a static transform);
  ///   - an unknown or stale frame (seen before): the last pose with zero velocity, once, and
  ///     the problem appended to `problems` (every call while it lasts) and counted in misses();
  ///   - no new transform yet, still fresh: nothing (the simulation moves on along the
  ///     velocity); a static transform (stamp 0) is posted again every time, at rest.
  void sample(const ros::Time& now, const Post& post, std::vector<std::string>& problems);

  /// Samples so far that found a followed frame unknown or stale.
  std::uint64_t misses() const;

 private:
  struct Entry {
    std::string frame;
    Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
    bool seen = false;       // a transform has been posted
    bool holding = false;    // posted with zero velocity because the frame is unknown or stale
    ros::Time stamp;         // of the newest transform
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // collider pose at `stamp`
  };

  const tf2::BufferCore& buffer_;
  std::string simFrame_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry> entries_;
  std::uint64_t misses_ = 0;
};

}  // namespace deformable_flsm
