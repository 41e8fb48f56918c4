/// @file simulator_node.h
/// The ROS face of the simulation: parameters in, commands in, state out. All physics is in the
/// core (through SimulationLoop); this class owns the ROS handles and converts at the edges.
#pragma once

#include "deformable_flsm/ros/collider_topics.h"
#include "deformable_flsm/ros/command_validator.h"
#include "deformable_flsm/ros/commands.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/ros/scene.h"
#include "deformable_flsm/ros/simulation_loop.h"

#include <deformable_flsm/DragCommand.h>
#include <deformable_flsm/FlsmConfig.h>
#include <deformable_flsm/ForceCommand.h>
#include <deformable_flsm/PinBox.h>
#include <deformable_flsm/SimulationState.h>
#include <dynamic_reconfigure/server.h>
#include <interactive_markers/interactive_marker_server.h>
#include <ros/callback_queue.h>
#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/service_server.h>
#include <ros/spinner.h>
#include <ros/subscriber.h>
#include <ros/timer.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Core>

#include <array>
#include <atomic>
#include <boost/thread/recursive_mutex.hpp>
#include <memory>
#include <mutex>
#include <vector>

namespace deformable_flsm {

/// flsm_node's topics, services and timers (see README for the full table):
///   in   ~drag (DragCommand), ~force (ForceCommand), ~collider (ColliderCommand), RViz mouse
///        via ~drag_marker
///   out  ~mesh, ~surface, ~particles, ~lattice, ~colliders (only while subscribed), ~state,
///        ~contact_wrenches, tf
///   srv  ~reset, ~release_all, ~pin_box; dynamic_reconfigure on ~
///
/// Threads: the simulation thread (SimulationLoop) steps the solver; the main thread (ros::spin)
/// runs the publish timer, dynamic_reconfigure and the RViz feedback; a second spinner thread
/// with its own queue serves ~drag, ~force and the services, so that a tf wait or a service
/// waiting for the simulation never delays publishing.
class SimulatorNode {
 public:
  /// @param[in] nh      public handle
  /// @param[in] pnh     private handle ("~"): topics, services and parameters live here
  /// @param[in] params  validated node parameters
  /// @param[in] scene   the built scene; its solver moves into the simulation thread
  SimulatorNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, const NodeParams& params,
                Scene scene);
  ~SimulatorNode();

 private:
  /// A heavy topic: built only while subscribed, not republished while the simulation is idle
  /// except to a new subscriber.
  struct LazyTopic {
    ros::Publisher pub;
    std::uint64_t builtSequence = 0;      ///< snapshot the cached message shows
    std::uint64_t publishedSequence = 0;  ///< snapshot last published
    std::atomic<bool> newSubscriber{false};
  };

  void warnAboutScene() const;
  void advertise();
  void setUpInteractiveMarker();
  void onPublishTimer(const ros::TimerEvent& event);
  /// true when `topic` has subscribers and should be sent now; false leaves it alone
  bool due(LazyTopic& topic, const Snapshot& s) const;
  void publishState(const Snapshot& s, const ros::Time& stamp);
  void publishTf(const Snapshot& s, const ros::Time& stamp);
  void updateHandlePose(const Snapshot& s);
  void reportProblems(const Snapshot& s);

  // Commands in.
  void onDrag(const DragCommand::ConstPtr& msg);
  void onForce(const ForceCommand::ConstPtr& msg);
  void onMarkerFeedback(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);
  bool onReset(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onReleaseAll(std_srvs::Trigger::Request& req, std_srvs::Trigger::Response& res);
  bool onPinBox(PinBox::Request& req, PinBox::Response& res);
  void onReconfigure(FlsmConfig& config, std::uint32_t level);
  /// Sends a command to the simulation thread; waits for its outcome when `wait`.
  CommandOutcome send(CommandBody body, bool wait);
  void rejected(const Rejection& why);
  /// Starts the tf listener on first use (see kFirstTransformTimeout).
  bool lookupTransform(const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d& T,
                       std::string& why);
  /// Starts the tf listener if it is not running; true when this call started it.
  bool startTfListener();

  ros::NodeHandle nh_, pnh_;
  ros::NodeHandle commandNh_;  ///< private namespace, served by commandSpinner_
  ros::CallbackQueue commandQueue_;
  NodeParams params_;
  SceneInfo info_;
  std::shared_ptr<const Lattice> lattice_;
  TriMesh renderMesh_;
  std::unique_ptr<Embedding> embedding_;
  std::shared_ptr<CommandStats> stats_;
  std::unique_ptr<SimulationLoop> loop_;
  std::unique_ptr<CommandValidator> validator_;
  std::unique_ptr<ColliderTopics> colliders_;  ///< ~collider, ~contact_wrenches, ~colliders

  tf2_ros::Buffer tfBuffer_;
  std::mutex tfListenerMutex_;
  std::unique_ptr<tf2_ros::TransformListener> tfListener_;  ///< started by the first lookup
  tf2_ros::TransformBroadcaster tfBroadcaster_;

  LazyTopic mesh_, surface_, particles_, lattice_markers_;
  ros::Publisher statePub_;
  ros::Subscriber dragSub_, forceSub_;
  ros::ServiceServer resetSrv_, releaseAllSrv_, pinBoxSrv_;
  ros::Timer publishTimer_;
  std::unique_ptr<ros::AsyncSpinner> commandSpinner_;

  boost::recursive_mutex reconfigureMutex_;
  std::unique_ptr<dynamic_reconfigure::Server<FlsmConfig>> reconfigure_;
  bool reconfigureReady_ = false;

  std::unique_ptr<interactive_markers::InteractiveMarkerServer> markerServer_;
  bool mouseDragging_ = false;
  Eigen::Vector3d mouseGrabPoint_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d mouseGrabPose_ = Eigen::Vector3d::Zero();
  Eigen::Isometry3d handlePose_ = Eigen::Isometry3d::Identity();

  // Publish-timer state (main thread only).
  std::vector<Eigen::Vector3d> vertices_;  ///< embedded render vertices
  std::uint64_t verticesSequence_ = 0;
  visualization_msgs::Marker marker_;
  sensor_msgs::PointCloud2 surfaceCloud_, particleCloud_;
  visualization_msgs::MarkerArray latticeMarkers_;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> dragLines_;
  SimulationState state_;
  std::uint64_t reportedResets_ = 0, reportedDropped_ = 0;
  bool reportedSaturated_ = false;
  std::uint64_t nonFiniteSkips_ = 0;
};

}  // namespace deformable_flsm
