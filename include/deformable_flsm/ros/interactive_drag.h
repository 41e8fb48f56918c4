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
#include <visualization_msgs/InteractiveMarker.h>
#include <visualization_msgs/InteractiveMarkerFeedback.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {

/// Main thread only (RViz feedback and the publish timer).
class InteractiveDrag {
 public:
  /// Validates and sends a drag command to object `object` (index in the handles given to the
  /// constructor); true when it was accepted (false: refused and counted).
  using SendDrag = std::function<bool(std::size_t object, const DragCommand&)>;

  /// What RViz picks for one object.
  struct Handle {
    /// the interactive marker's name
    std::string name;
    /// the object, for its rest centre of mass and size
    const Lattice* lattice = nullptr;
    /// the rest render mesh, simplified into the handle
    const TriMesh* renderMesh = nullptr;
  };

  /// Starts the interactive marker server on pnh's ~drag_marker, with one handle per object:
  /// RViz picks the handle under the cursor, so the press grabs the object under it.
  /// @param[in] frameId  the frame of the handles (~frame_id)
  InteractiveDrag(const ros::NodeHandle& pnh, const std::string& frameId,
                  const std::vector<Handle>& handles, SendDrag sendDrag);

  /// The interactive marker of one object's handle (a simplified copy of its render mesh, which
  /// takes a while for a large mesh: any thread, before add()).
  static visualization_msgs::InteractiveMarker makeHandle(const Handle& handle, const std::string& frameId);
  /// Adds the handle of object `object` (an object added at run time), made by makeHandle().
  void add(std::size_t object, const visualization_msgs::InteractiveMarker& handle);
  /// Erases the handle of object `object` (removed at run time): RViz no longer shows it.
  void remove(std::size_t object);
  /// Moves handle `object` to the object's rigid frame when it moved or turned noticeably,
  /// unless the mouse holds it.
  void follow(std::size_t object, const Eigen::Isometry3d& objectFrame);

 private:
  struct State {
    std::string name;
    double objectSize = 0.0;
    bool present = false;  // its handle is on the server
    bool dragging = false;
    Eigen::Vector3d grabPoint = Eigen::Vector3d::Zero();
    Eigen::Vector3d grabPose = Eigen::Vector3d::Zero();
    Eigen::Isometry3d handlePose = Eigen::Isometry3d::Identity();
  };
  void onFeedback(std::size_t object,
                  const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback);

  /// Puts handle `object` on the server (applyChanges() is the caller's).
  void insert(std::size_t object, const visualization_msgs::InteractiveMarker& handle);

  SendDrag sendDrag_;
  std::unique_ptr<interactive_markers::InteractiveMarkerServer> server_;
  std::vector<State> states_;
};

}  // namespace deformable_flsm
