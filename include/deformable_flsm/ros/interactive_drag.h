/// @file interactive_drag.h
/// The RViz mouse: an interactive marker (~drag_marker) whose invisible handle is a coarse copy
/// of the object; pressing the mouse on it grabs the particles under the cursor, moving it drags
/// them, releasing it lets go. The handle follows the object's rigid frame between drags.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"

#include <deformable_flsm/DragCommand.h>
#include <interactive_markers/interactive_marker_server.h>
#include <ros/node_handle.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <functional>
#include <memory>
#include <string>

namespace deformable_flsm {

/// Main thread only (RViz feedback and the publish timer).
class InteractiveDrag {
 public:
  /// Validates and sends a drag command; true when it was accepted (false: refused and counted).
  using SendDrag = std::function<bool(const DragCommand&)>;

  /// Starts the interactive marker server on pnh's ~drag_marker.
  /// @param[in] frameId     the frame of the handle (~frame_id)
  /// @param[in] lattice     the object, for its rest centre of mass and size
  /// @param[in] renderMesh  the rest render mesh, simplified into the handle
  InteractiveDrag(const ros::NodeHandle& pnh, const std::string& frameId, const Lattice& lattice,
                  const TriMesh& renderMesh, SendDrag sendDrag);

  /// Moves the handle to the object's rigid frame when it moved or turned noticeably, unless the
  /// mouse holds it.
  void follow(const Eigen::Isometry3d& objectFrame);

 private:
  void onFeedback(const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);

  double objectSize_;
  SendDrag sendDrag_;
  std::unique_ptr<interactive_markers::InteractiveMarkerServer> server_;
  bool dragging_ = false;
  Eigen::Vector3d grabPoint_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d grabPose_ = Eigen::Vector3d::Zero();
  Eigen::Isometry3d handlePose_ = Eigen::Isometry3d::Identity();
};

}  // namespace deformable_flsm
