/// @file state_publisher.h
/// What flsm_node sends out each publish tick: tf (each object's rigid frame), ~state, and the
/// heavy topics ~mesh, ~surface, ~particles and ~lattice, each built only while subscribed.
/// With ~objects, each object's clouds, lattice markers and state go to ~objects/<name>/..., its
/// mesh to the shared ~mesh as a Marker of namespace <name>.
#pragma once

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/runtime/commands.h"
#include "deformable_flsm/ros/lazy_topic.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/runtime/scene.h"
#include "deformable_flsm/runtime/simulation_loop.h"

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
#include <deque>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {

/// Converts snapshots to messages and publishes them. Main thread only (the publish timer).
class StatePublisher {
 public:
  /// Advertises the topics on `pnh`. Keeps references to `params`, `objects` (their lattices,
  /// render meshes and embeddings) and `stats`, which must outlive it.
  /// @param[in] objects     the scene's objects, in the World's order
  /// @param[in] namespaced  each object's topics under ~objects/<name>/ (a node with ~objects);
  ///                        false: the single object's topics directly under ~
  StatePublisher(ros::NodeHandle& pnh, const NodeParams& params,
                 const std::deque<SceneObject>& objects, bool namespaced,
                 const CommandStats& stats);
  ~StatePublisher();

  /// Advertises the topics of an object added at run time (~add_object), kept by reference like
  /// the others. The snapshots are matched to the objects by name: until the object is in one,
  /// nothing of it goes out.
  void addObject(const SceneObject& object);
  /// Unadvertises object `name`'s topics and deletes its ~mesh marker (a DELETE action); false
  /// when there is no such object.
  bool removeObject(const std::string& name, const ros::Time& stamp);

  /// Each object's frame on tf: ~frame_id -> the object's name (~object_frame_id for the
  /// single object).
  void publishTf(const Snapshot& s, const ros::Time& stamp);
  /// ~state: the loop's diagnostics, the command counts and the colliders, of the whole scene;
  /// with ~objects, each object's own on ~objects/<name>/state.
  /// @param[in] colliderFrameMisses  samples that found a followed tf frame unknown or stale
  ///                                 (ColliderFollower::misses())
  void publishState(const Snapshot& s, const ros::Time& stamp, std::uint64_t colliderFrameMisses);
  /// ~mesh, ~surface, ~particles, ~lattice (per object), to those that are due
  /// (LazyTopic::due()): at rest the clouds keep the rate with the cached message and a new
  /// stamp; the markers go out once, then to new subscribers only, unless ~republish_at_rest.
  /// Nothing non-finite goes out: a non-finite embedded mesh skips its ~mesh marker and
  /// ~surface (logged). The embedded render vertices are projected out of the snapshot's
  /// colliders first.
  void publishHeavy(const Snapshot& s, const ros::Time& stamp);

 private:
  class ObjectTopics;
  /// Calls `each(topics, snapshot object)` for every object of ours in `s`, in order (the
  /// World's order, which is also the order the objects were added in, are ours).
  template <class Each>
  void forEachObject(const Snapshot& s, Each&& each);
  /// The whole-scene or one object's state message (mass and particles of `lattices`).
  void fillState(const LoopDiagnostics& d, const ros::Time& stamp, double mass,
                 std::size_t particles, std::size_t colliders, std::uint64_t colliderFrameMisses,
                 SimulationState& m) const;

  const NodeParams& params_;
  const CommandStats& stats_;
  ros::NodeHandle pnh_;
  bool namespaced_ = false;
  std::vector<std::unique_ptr<ObjectTopics>> objects_;
  /// objects advertised so far (removed ones included): the next one's colour and marker id
  std::size_t advertised_ = 0;
  ros::Publisher meshPub_;  ///< ~mesh, for the DELETE of a removed object's marker
  double totalMass_ = 0.0;
  std::size_t totalParticles_ = 0;

  tf2_ros::TransformBroadcaster tfBroadcaster_;
  std::vector<geometry_msgs::TransformStamped> transforms_;
  ros::Publisher statePub_;
  SimulationState state_;
};

}  // namespace deformable_flsm
