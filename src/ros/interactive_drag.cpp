#include "deformable_flsm/ros/interactive_drag.h"

#include "deformable_flsm/ros/mesh_messages.h"
#include "deformable_flsm/runtime/render_mesh.h"
#include "to_eigen.h"

#include <tf2_eigen/tf2_eigen.h>
#include <visualization_msgs/InteractiveMarker.h>
#include <visualization_msgs/InteractiveMarkerControl.h>
#include <visualization_msgs/Marker.h>

#include <cmath>
#include <cstdint>
#include <utility>
#include <vector>

namespace deformable_flsm {

namespace {

/// The RViz mouse drag: its id, how many particles it grabs, and the invisible handle that
/// RViz picks (a simplified copy of the render mesh, following the object's rigid frame).
/// The mouse takes the particle under the cursor and its 6 nearest neighbours: one particle
/// pulled alone by centimetres drags out a spike one cell wide.
constexpr const char kMouseDragId[] = "rviz";
constexpr std::uint32_t kMouseGrabCount = 7;
constexpr std::size_t kHandleTriangles = 1500;
constexpr float kHandleAlpha = 0.0f;
/// The handle follows the object when it moved by more than these (fraction of the size, rad).
constexpr double kHandleMoveFraction = 1e-3;
constexpr double kHandleTurn = 1e-2;
/// The handle is the rest shape moved out along its vertex normals by this many lattice
/// spacings: RViz picks the nearest thing under the cursor, and where the object bulges beyond
/// its rest shape (a soft body sagging on the ground) the visible mesh would hide a handle of the
/// rest shape itself, and the mouse would turn the camera instead of grabbing.
constexpr double kHandleOffsetSpacings = 1.0;

/// `mesh` with every vertex moved outwards by `offset` along its area-weighted normal (outwards:
/// the side that makes the enclosed volume positive, whichever way the file winds its triangles).
void offsetAlongNormals(TriMesh& mesh, double offset) {
  double volume6 = 0.0;  // six times the signed volume (divergence theorem)
  for (const auto& t : mesh.triangles)
    volume6 += mesh.vertices[t[0]].dot(mesh.vertices[t[1]].cross(mesh.vertices[t[2]]));
  if (volume6 < 0.0) offset = -offset;
  std::vector<Eigen::Vector3d> normals;
  computeVertexNormals(mesh.vertices, mesh.triangles, normals);  // unit, or zero where no area
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) mesh.vertices[v] += offset * normals[v];
}

Eigen::Vector3d restCenterOfMass(const Lattice& L) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < L.size(); ++i) c += L.masses()[i] * L.restPositions()[i];
  return c / L.totalMass();
}

}  // namespace

InteractiveDrag::InteractiveDrag(const ros::NodeHandle& pnh, const std::string& frameId,
                                 const std::vector<Handle>& handles, SendDrag sendDrag)
    : sendDrag_(std::move(sendDrag)) {
  server_ = std::make_unique<interactive_markers::InteractiveMarkerServer>(
      pnh.resolveName("drag_marker"), "", false);
  for (std::size_t k = 0; k < handles.size(); ++k) insert(k, makeHandle(handles[k], frameId));
  server_->applyChanges();
}

visualization_msgs::InteractiveMarker InteractiveDrag::makeHandle(const Handle& handle, const std::string& frameId) {
  const Lattice& lattice = *handle.lattice;
  const Eigen::Vector3d com = restCenterOfMass(lattice);
  visualization_msgs::InteractiveMarker im;
  im.header.frame_id = frameId;
  im.name = handle.name;
  im.description = "";
  im.scale = static_cast<float>(lattice.objectSize());
  im.pose = tf2::toMsg(Eigen::Isometry3d(Eigen::Translation3d(com)));

  // What RViz picks: a coarse copy of the object, invisible, in the object's frame.
  visualization_msgs::Marker marker;
  initTriangleListMarker(frameId, "flsm_handle", {1.0f, 1.0f, 1.0f, kHandleAlpha}, marker);
  TriMesh coarse = simplifyMesh(*handle.renderMesh, kHandleTriangles).mesh;
  offsetAlongNormals(coarse, kHandleOffsetSpacings * lattice.spacing());
  for (Eigen::Vector3d& v : coarse.vertices) v -= com;
  setTriangleListPoints(coarse.vertices, coarse.triangles, marker);
  marker.header.frame_id.clear();  // in the interactive marker's frame

  visualization_msgs::InteractiveMarkerControl control;
  control.name = "drag";
  control.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_3D;
  control.orientation.w = 1.0;
  control.always_visible = true;
  control.markers.push_back(marker);
  im.controls.push_back(control);
  return im;
}

void InteractiveDrag::add(std::size_t object, const visualization_msgs::InteractiveMarker& handle) {
  insert(object, handle);
  server_->applyChanges();
}

void InteractiveDrag::remove(std::size_t object) {
  if (object >= states_.size() || !states_[object].present) return;
  State& state = states_[object];
  state.present = false;
  state.dragging = false;
  server_->erase(state.name);
  server_->applyChanges();
}

void InteractiveDrag::insert(std::size_t object, const visualization_msgs::InteractiveMarker& handle) {
  if (states_.size() <= object) states_.resize(object + 1);
  State& state = states_[object];
  state = State();
  state.name = handle.name;
  state.objectSize = handle.scale;
  state.present = true;
  tf2::fromMsg(handle.pose, state.handlePose);
  server_->insert(handle, [this, object](const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback) {
    onFeedback(object, feedback);
  });
}

void InteractiveDrag::follow(std::size_t object, const Eigen::Isometry3d& objectFrame) {
  if (object >= states_.size() || !states_[object].present) return;
  State& state = states_[object];
  if (state.dragging) return;  // RViz owns the handle while the mouse holds it
  const double moved = (objectFrame.translation() - state.handlePose.translation()).norm();
  const Eigen::AngleAxisd turned(objectFrame.linear().transpose() * state.handlePose.linear());
  if (moved < kHandleMoveFraction * state.objectSize && std::abs(turned.angle()) < kHandleTurn) return;
  state.handlePose = objectFrame;
  server_->setPose(state.name, tf2::toMsg(state.handlePose));
  server_->applyChanges();
}

void InteractiveDrag::onFeedback(std::size_t object,
                                 const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback) {
  using visualization_msgs::InteractiveMarkerFeedback;
  if (object >= states_.size() || !states_[object].present) return;
  State& state = states_[object];
  DragCommand drag;
  drag.header = feedback->header;
  drag.id = kMouseDragId;
  const Eigen::Vector3d pose = toEigen(feedback->pose.position);
  switch (feedback->event_type) {
    case InteractiveMarkerFeedback::MOUSE_DOWN:
      if (!feedback->mouse_point_valid) return;
      // Grab the particle under the cursor and hold it there; the target then follows the
      // handle's motion from this pose.
      drag.action = DragCommand::GRAB;
      drag.particle = -1;
      drag.point = feedback->mouse_point;
      drag.count = kMouseGrabCount;
      drag.target = feedback->mouse_point;
      state.grabPoint = toEigen(feedback->mouse_point);
      state.grabPose = pose;
      break;
    case InteractiveMarkerFeedback::POSE_UPDATE:
      if (!state.dragging) return;
      drag.action = DragCommand::MOVE;
      drag.target = tf2::toMsg(Eigen::Vector3d(state.grabPoint + (pose - state.grabPose)));
      break;
    case InteractiveMarkerFeedback::MOUSE_UP:
      if (!state.dragging) return;
      drag.action = DragCommand::RELEASE;
      break;
    default:
      return;
  }
  if (!sendDrag_(object, drag)) return;
  if (drag.action == DragCommand::GRAB) state.dragging = true;
  if (drag.action == DragCommand::RELEASE) {
    state.dragging = false;
    state.handlePose.translation().setConstant(std::nan(""));  // snap back at the next tick
  }
}

}  // namespace deformable_flsm
