/// @file collider_follower.h
/// Colliders that follow tf frames: samples each frame's latest transform without waiting
/// (tf2::BufferCore, no timeout), derives the velocity from the last two transforms, and hands
/// pose and velocity to the simulation (SimulationLoop::setColliderMotion). A collider whose
/// frame has not appeared yet waits for it (reported once, not counted as a miss); only a frame
/// that was seen and is then lost or stale is a problem. Needs no master: the tests fill a
/// BufferCore by hand.
#pragma once

#include "deformable_flsm/runtime/simulation_loop.h"

#include <ros/time.h>
#include <tf2/buffer_core.h>

#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {

class ColliderFollower {
 public:
  /// Receives a collider's new pose and velocity (simulation frame).
  using Post = std::function<void(const std::string& id, const ColliderMotion& motion)>;

  /// Decides, at a collider's first transform, whether it joins the simulation at that pose
  /// (true) or is dropped (false; e.g. a robot link that starts inside the object).
  using Admit = std::function<bool(const Eigen::Isometry3d& pose)>;

  /// What one sample() found besides the motions it posted.
  struct Report {
    /// followed frames that were seen before and are now unknown, stale or not finite (every
    /// sample while it lasts; each counted in misses())
    std::vector<std::string> problems;
    /// colliders found waiting for a frame that has not appeared yet, as (id, frame): each
    /// named once, at the first sample that finds it waiting
    std::vector<std::pair<std::string, std::string>> waiting;
    /// colliders their Admit refused at their first transform: forgotten since
    std::vector<std::string> excluded;
    /// colliders whose frame jumped (moved faster than kJumpSpeed between two transforms, or
    /// changed its speed faster than kJumpAcceleration): placed at the new pose at rest
    std::vector<std::string> jumped;
    void clear() {
      problems.clear();
      waiting.clear();
      excluded.clear();
      jumped.clear();
    }
  };

  /// A frame whose newest transform is older than this (s) is stale: its collider holds still.
  /// A publisher that pauses for less than this changes nothing: the collider moves on along
  /// its last velocity (SimulationLoop::kMaxExtrapolation), and the first transform after the
  /// pause gives the mean velocity over it.
  static constexpr double kStaleAfter = 0.5;

  /// A frame that moves faster than this between two transforms (m/s) has jumped (a robot
  /// relocalised, a frame teleported, a publisher restarted at another place): its collider is
  /// placed at the new pose with zero velocity, as a collider set there would be, instead of
  /// being swept through the scene at a speed no link moves at (the contact pass then moves
  /// particles it finds inside out by position, without throwing them). Well above the speeds
  /// of robot links, a few m/s at an industrial arm's tool.
  static constexpr double kJumpSpeed = 10.0;
  /// A frame whose speed changes faster than this between two transforms (m/s^2, ten g) has
  /// jumped too: a hand that stood still and is 0.22 m further at the next sample (a robot's
  /// first joint state after a pause) would otherwise move on along 6.6 m/s until the next one.
  /// Well above what robot arms do (a few m/s^2 at the tool; the first sample after a frame
  /// was seen, after a jump or after a hold has no speed to compare with).
  static constexpr double kJumpAcceleration = 100.0;

  /// @param[in] buffer    where transforms are looked up (latest available, never waiting)
  /// @param[in] simFrame  ~frame_id
  ColliderFollower(const tf2::BufferCore& buffer, std::string simFrame);

  /// Collider `id` follows `frame`; `offset` is its pose in that frame; `admit`, when given, is
  /// asked at the first transform whether it joins. Any thread.
  void follow(const std::string& id, const std::string& frame, const Eigen::Isometry3d& offset,
              Admit admit = nullptr);
  /// Collider `id` follows no frame any more (nothing happens if it did not). Any thread.
  void forget(const std::string& id);
  /// true when some collider follows a frame.
  bool empty() const;

  /// Samples every followed frame at wall time `now` and posts, for each collider:
  ///   - a new transform: its pose and the velocity from the previous transform (zero for the
  ///     first one, for a static transform and after a jump, named in report.jumped); at the
  ///     first one, a collider its Admit refuses is forgotten instead and named in
  ///     report.excluded;
  ///   - a frame not seen yet (unknown, or only stale transforms): nothing; the collider waits
  ///     for it, named once in report.waiting, no miss counted;
  ///   - an unknown or stale frame seen before: the last pose with zero velocity, once, and the
  ///     problem appended to report.problems (every call while it lasts) and counted in
  ///     misses();
  ///   - no new transform yet, still fresh: nothing (the simulation moves on along the
  ///     velocity); a static transform (stamp 0) is posted again every time, at rest.
  /// `report` is appended to.
  void sample(const ros::Time& now, const Post& post, Report& report);

  /// Samples so far that found a frame unknown or stale after it had been seen.
  std::uint64_t misses() const;
  /// Colliders still waiting for the first transform of their frame.
  std::size_t waiting() const;

 private:
  struct Entry {
    std::string frame;
    Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
    Admit admit;             // asked at the first transform
    bool seen = false;       // a transform has been posted
    bool announced = false;  // named in Report::waiting
    bool holding = false;    // posted with zero velocity because the frame is unknown or stale
    ros::Time stamp;         // of the newest transform
    /// the velocity posted with it (m/s), and whether it was a steady one (from two transforms,
    /// no jump) that the next may be compared with
    Eigen::Vector3d velocity = Eigen::Vector3d::Zero();
    bool velocityKnown = false;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  // collider pose at `stamp`
  };
  /// The newest transform of e's frame into `t`, or why there is none (unknown, stale) in words.
  std::string lookup(const ros::Time& now, const std::string& id, const Entry& e,
                     geometry_msgs::TransformStamped& t) const;

  const tf2::BufferCore& buffer_;
  std::string simFrame_;
  mutable std::mutex mutex_;
  std::map<std::string, Entry> entries_;
  std::uint64_t misses_ = 0;
};

}  // namespace deformable_flsm
