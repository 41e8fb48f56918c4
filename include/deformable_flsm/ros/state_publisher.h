/// @file state_publisher.h
/// What flsm_node sends out each publish tick: tf (the object's rigid frame), ~state, and the
/// heavy topics ~mesh, ~surface, ~particles and ~lattice, each built only while subscribed.
#pragma once

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/ros/commands.h"
#include "deformable_flsm/ros/lazy_topic.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/ros/simulation_loop.h"

#include <deformable_flsm/SimulationState.h>
#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/time.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/transform_broadcaster.h>
#include <visualization_msgs/Marker.h>
#include <visualization_msgs/MarkerArray.h>

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

namespace deformable_flsm {

/// Converts snapshots to messages and publishes them. Main thread only (the publish timer).
class StatePublisher {
 public:
  /// Advertises the topics on `pnh`. Keeps references to `params`, `lattice`, `renderMesh`,
  /// `embedding` and `stats`, which must outlive it.
  /// @param[in] renderMesh  the render mesh whose vertices `embedding` deforms (~mesh)
  StatePublisher(ros::NodeHandle& pnh, const NodeParams& params, const Lattice& lattice,
                 const TriMesh& renderMesh, const Embedding& embedding, const CommandStats& stats);

  /// The object's frame on tf: ~frame_id -> ~object_frame_id.
  void publishTf(const Snapshot& s, const ros::Time& stamp);
  /// ~state: the loop's diagnostics, the command counts and the colliders.
  /// @param[in] colliderFrameMisses  samples that found a followed tf frame unknown or stale
  ///                                 (ColliderFollower::misses())
  void publishState(const Snapshot& s, const ros::Time& stamp, std::uint64_t colliderFrameMisses);
  /// ~mesh, ~surface, ~particles, ~lattice, to those that are due (LazyTopic::due()): at rest
  /// the clouds (~surface, ~particles) keep the rate with the cached message and a new stamp;
  /// the markers (~mesh, ~lattice) go out once, then to new subscribers only, unless
  /// ~republish_at_rest. Nothing non-finite goes out: a non-finite embedded mesh skips ~mesh and
  /// ~surface (logged). The embedded render vertices are projected out of the snapshot's
  /// colliders first.
  void publishHeavy(const Snapshot& s, const ros::Time& stamp);

 private:
  const NodeParams& params_;
  const Lattice& lattice_;
  const TriMesh& renderMesh_;
  const Embedding& embedding_;
  const CommandStats& stats_;

  tf2_ros::TransformBroadcaster tfBroadcaster_;
  ros::Publisher statePub_;
  LazyTopic mesh_, surface_, particles_, latticeMarkers_;

  std::vector<Eigen::Vector3d> vertices_;  ///< embedded render vertices
  std::uint64_t verticesSequence_ = 0;
  bool verticesFinite_ = true;  ///< checked once per deform, not per resend at rest
  visualization_msgs::Marker marker_;
  sensor_msgs::PointCloud2 surfaceCloud_, particleCloud_;
  visualization_msgs::MarkerArray latticeMarkerArray_;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> dragLines_;
  SimulationState state_;
  std::uint64_t nonFiniteSkips_ = 0;
};

}  // namespace deformable_flsm
