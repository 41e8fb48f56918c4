/// @file camera_topics.h
/// The node's simulated depth cameras (~cameras): on a thread of their own, at each camera's
/// rate of the node's time and only while someone subscribes, the newest state is rendered
/// (runtime/scene_renderer.h) from where tf puts the camera's frame at the state's stamp, and
/// published under ~<name>/: depth/image_raw (32FC1 m or 16UC1 mm), depth/camera_info,
/// rgb/image_raw (rgb8), rgb/camera_info, depth/points (organized, NaN where nothing is seen, in
/// the optical frame) and mask (16UC1: 0 nothing, object k k + 1 in the scene's order, collider
/// i 1000 + i in the order of their ids): one frame, one stamp, the state's.
#pragma once

#include "deformable_flsm/runtime/camera_spec.h"
#include "deformable_flsm/runtime/scene.h"
#include "deformable_flsm/runtime/scene_renderer.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include <ros/callback_queue.h>
#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/spinner.h>
#include <ros/timer.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/static_transform_broadcaster.h>

#include <deque>
#include <functional>
#include <memory>
#include <random>
#include <shared_mutex>
#include <string>
#include <vector>

namespace deformable_flsm {

class CameraTopics {
 public:
  /// The stamp of a state in the node's clock (SimulatorNode::stampOf); false when the state is
  /// not to be sent (stamped beyond a followed clock).
  using StampOf = std::function<bool(const Snapshot&, ros::Time& stamp)>;

  /// @param[in] pnh        the node's private handle: topics under ~<camera>/
  /// @param[in] cameras    the validated ~cameras
  /// @param[in] simFrame   ~frame_id
  /// @param[in] loop       the simulation, read with copyState()
  /// @param[in] objects    the node's objects (render meshes, embeddings), read under
  ///                       `objectsMutex` (shared)
  /// @param[in] tfBuffer   where the cameras' frames are looked up (the node's listener fills it)
  /// @param[in] startTfListener  starts the node's tf listener (at start-up, when a camera is set)
  CameraTopics(ros::NodeHandle& pnh, const std::vector<CameraSpec>& cameras, std::string simFrame,
               const SimulationLoop& loop, const std::deque<SceneObject>& objects,
               std::shared_mutex& objectsMutex, const tf2_ros::Buffer& tfBuffer,
               const std::function<void()>& startTfListener, StampOf stampOf);
  ~CameraTopics();
  CameraTopics(const CameraTopics&) = delete;
  CameraTopics& operator=(const CameraTopics&) = delete;

 private:
  struct Camera;
  void onTimer(Camera& camera);
  void render(Camera& camera);
  /// The newest state into state_, its render meshes into the renderer; false when it cannot be
  /// (nothing to render yet).
  void updateScene();
  void publish(Camera& camera, const ros::Time& stamp, const RenderedView& view);

  std::string simFrame_;
  const SimulationLoop& loop_;
  const std::deque<SceneObject>& objects_;
  std::shared_mutex& objectsMutex_;
  const tf2_ros::Buffer& tfBuffer_;
  StampOf stampOf_;
  tf2_ros::StaticTransformBroadcaster staticFrames_;  ///< the frames of placed cameras
  ros::NodeHandle nh_;  ///< private namespace on queue_: the camera thread
  ros::CallbackQueue queue_;
  std::vector<std::unique_ptr<Camera>> cameras_;
  std::unique_ptr<ros::AsyncSpinner> spinner_;

  // The camera thread's.
  SceneRenderer renderer_;
  Snapshot state_;
  std::uint64_t sceneSequence_ = 0;  ///< the state the renderer holds
  std::vector<std::vector<Eigen::Vector3d>> vertices_;
  std::vector<const TriMesh*> meshes_;
  RenderedView view_;
};

}  // namespace deformable_flsm
