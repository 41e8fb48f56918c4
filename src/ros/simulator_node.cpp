#include "deformable_flsm/ros/simulator_node.h"

#include "deformable_flsm/ros/mesh_messages.h"

#include <ros/console.h>

#include <utility>

namespace deformable_flsm {

namespace {

/// Opaque, light clay colour: shading stays readable on RViz's dark background.
constexpr std::array<float, 4> kMeshColor = {0.85f, 0.72f, 0.55f, 1.0f};
constexpr const char kMarkerNamespace[] = "flsm_mesh";
constexpr std::uint32_t kQueueSize = 1;  // only the newest shape matters

}  // namespace

SimulatorNode::SimulatorNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
                             const NodeParams& params, TriMesh mesh)
    : nh_(nh), pnh_(pnh), params_(params), mesh_(std::move(mesh)), vertices_(mesh_.vertices) {
  initTriangleListMarker(params_.frameId, kMarkerNamespace, kMeshColor, marker_);

  meshPub_ = pnh_.advertise<visualization_msgs::Marker>("mesh", kQueueSize);
  surfacePub_ = pnh_.advertise<sensor_msgs::PointCloud2>("surface", kQueueSize);
  publishTimer_ = pnh_.createTimer(ros::Duration(1.0 / params_.publishRate),
                                   &SimulatorNode::onPublishTimer, this);

  ROS_INFO("flsm_node: mesh '%s' (%zu vertices, %zu triangles), publishing %s and %s at %.1f Hz "
           "in frame '%s'",
           params_.mesh.c_str(), mesh_.vertices.size(), mesh_.triangles.size(),
           meshPub_.getTopic().c_str(), surfacePub_.getTopic().c_str(), params_.publishRate,
           params_.frameId.c_str());
}

void SimulatorNode::onPublishTimer(const ros::TimerEvent& event) {
  constexpr double kLateWarningPeriod = 5.0;  // s between two "late" warnings
  if (event.profile.last_duration.toSec() > 1.0 / params_.publishRate) {
    ROS_WARN_THROTTLE(kLateWarningPeriod,
                      "flsm_node: publishing took %.1f ms, longer than the %.1f ms period of "
                      "~publish_rate: lower ~publish_rate or use a smaller mesh",
                      1e3 * event.profile.last_duration.toSec(), 1e3 / params_.publishRate);
  }
  publish(ros::Time::now());
}

void SimulatorNode::publish(const ros::Time& stamp) {
  if (meshPub_.getNumSubscribers() > 0) {
    setTriangleListPoints(vertices_, mesh_.triangles, marker_);
    marker_.header.stamp = stamp;
    meshPub_.publish(marker_);
  }
  if (surfacePub_.getNumSubscribers() > 0) {
    fillVertexCloud(vertices_, params_.frameId, cloud_);
    cloud_.header.stamp = stamp;
    surfacePub_.publish(cloud_);
  }
}

}  // namespace deformable_flsm
