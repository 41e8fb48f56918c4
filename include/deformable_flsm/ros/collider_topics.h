/// @file collider_topics.h
/// The colliders' ROS face: ~collider commands in, ~contact_wrenches, ~colliders markers and the
/// colliders' tf frames out, and the tf frames that colliders follow sampled at the step rate
/// (the parameters' colliders and the robot's links, ~robot_description, from start-up on).
/// SimulatorNode owns one and calls publish() from its publish timer.
#pragma once

#include "deformable_flsm/ros/collider_command_validator.h"
#include "deformable_flsm/ros/collider_follower.h"
#include "deformable_flsm/ros/collider_messages.h"
#include "deformable_flsm/runtime/commands.h"
#include "deformable_flsm/ros/lazy_topic.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/runtime/sequence_gaps.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include <deformable_flsm/ColliderCommand.h>
#include <deformable_flsm/ContactWrenches.h>
#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/subscriber.h>
#include <ros/timer.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/MarkerArray.h>

#include <functional>
#include <map>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {

/// An object at rest as the colliders see it at start-up.
struct RestObject {
  const Lattice* lattice;  ///< rest positions in the simulation frame
  double contactRadius;    ///< its particles' contact radius (m)
};

class ColliderTopics {
 public:
  /// Sends a validated command to the simulation thread (without waiting).
  using Send = std::function<void(CommandBody)>;

  /// Registers the parameters' colliders that follow tf frames and the robot's colliders with
  /// the loop (call before loop.start()), starts the tf listener when there are any, advertises
  /// the topics and starts the follow timer.
  /// @param[in] pnh        private handle for the publishers (main queue)
  /// @param[in] stateNh    private handle on the state thread's queue, for the follow timer
  /// @param[in] commandNh  private handle on the command queue, for the ~collider subscriber
  /// @param[in] params     the node's parameters (colliders, frame, publish and step rates)
  /// @param[in] loop       the simulation, outlives this object
  /// @param[in] stats      where refused commands are counted
  /// @param[in] tfBuffer   the node's tf buffer (followed frames are read from it, never waited
  ///                       for)
  /// @param[in] startTfListener  starts the node's tf listener (called when a frame is followed)
  /// @param[in] lookup     transform of a command's header frame (the node's command lookup)
  /// @param[in] send       hands a command to the simulation thread
  /// @param[in] objects    every object's rest lattice (outliving this) and contact radius (m):
  ///                       the largest object sets the size the ground is drawn at; robot links
  ///                       that overlap any object's rest particles are left out
  ColliderTopics(ros::NodeHandle& pnh, ros::NodeHandle& stateNh, ros::NodeHandle& commandNh,
                 const NodeParams& params,
                 SimulationLoop& loop, std::shared_ptr<CommandStats> stats,
                 const tf2_ros::Buffer& tfBuffer, std::function<void()> startTfListener,
                 CommandValidator::TransformLookup lookup, Send send,
                 const std::vector<RestObject>& objects);

  /// Every publish tick (the main thread): ~contact_wrenches (also at rest) and, `withTf`, the
  /// colliders' tf frames (not with ~clock sim, where each step sends them, nor twice at one
  /// stamp).
  void publishFrames(const Snapshot& s, const ros::Time& stamp, bool withTf);
  /// Every publish tick (the main thread): ~colliders when it is due (LazyTopic::due(): while
  /// subscribed, like ~lattice).
  void publishMarkers(const Snapshot& s, const ros::Time& stamp);
  /// Samples that found a followed tf frame unknown or stale (for ~state).
  std::uint64_t frameMisses() const { return follower_.misses(); }

 private:
  void onCommand(const ros::MessageEvent<const ColliderCommand>& event);
  void onFollowTimer(const ros::TimerEvent& event);
  /// Registers the robot's colliders (params.robot) with the loop and the follower.
  void addRobot(const RobotColliders& robot, const std::vector<RestObject>& objects);

  std::string simFrame_;
  SimulationLoop& loop_;
  std::shared_ptr<CommandStats> stats_;
  SequenceGaps gaps_;  ///< of ~collider (SimulatorNode counts those of ~drag, ~force)
  std::function<void()> startTfListener_;
  ColliderCommandValidator validator_;
  Send send_;
  double planeSize_;
  bool republishAtRest_;
  ColliderFollower follower_;

  ros::Publisher wrenchPub_;
  LazyTopic markers_;
  ros::Subscriber commandSub_;
  ros::Timer followTimer_;
  tf2_ros::TransformBroadcaster tfBroadcaster_;

  // The state thread's (the follow timer).
  ColliderFollower::Report report_;
  // The main thread's (publishFrames(), publishMarkers()).
  ContactWrenches wrenches_;
  std::vector<geometry_msgs::TransformStamped> transforms_;
  visualization_msgs::MarkerArray markerArray_;
  /// robot colliders: summed per link on ~contact_wrenches
  std::map<std::string, WrenchGroup> robotLinks_;
};

}  // namespace deformable_flsm
