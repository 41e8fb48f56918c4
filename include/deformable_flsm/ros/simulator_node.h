/// @file simulator_node.h
/// The ROS face of the simulation: owns the publishers and timers, delegates all geometry to
/// the core library.
#pragma once

#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/ros/param_loader.h"

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/timer.h>
#include <sensor_msgs/PointCloud2.h>
#include <visualization_msgs/Marker.h>

#include <Eigen/Core>

#include <vector>

namespace deformable_flsm {

/// Publishes the render mesh at a fixed rate:
///   ~mesh     visualization_msgs/Marker TRIANGLE_LIST (fixed topology)
///   ~surface  sensor_msgs/PointCloud2 of the vertices (x, y, z float32)
/// Publishers are lazy: a message is built only while someone subscribes to it.
///
/// The render state is `vertices_` (#V positions in frameId, m). The publish timer only reads
/// it; whatever moves the mesh (the solver's step timer) only writes it. That split is where the
/// simulation plugs in: a step timer at 1 / SolverParams::timeStep calls Solver::step() and then
/// Embedding::deform(solver.positions(), solver.regionRotations(), vertices_), while the publish
/// path below stays as it is.
class SimulatorNode {
 public:
  /// @param[in] nh      public handle (for topics/services outside the node's namespace)
  /// @param[in] pnh     private handle: ~mesh and ~surface are advertised here
  /// @param[in] params  validated node parameters
  /// @param[in] mesh    the render mesh at rest (m), already validated by loadMesh()
  SimulatorNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh, const NodeParams& params,
                TriMesh mesh);

  /// Publishes the current vertices on every topic that has subscribers (stamp = `stamp`).
  void publish(const ros::Time& stamp);

  const TriMesh& restMesh() const { return mesh_; }

 private:
  void onPublishTimer(const ros::TimerEvent& event);

  ros::NodeHandle nh_;
  ros::NodeHandle pnh_;
  NodeParams params_;
  TriMesh mesh_;
  /// #V current render-vertex positions (m): the rest mesh until a solver moves it
  std::vector<Eigen::Vector3d> vertices_;

  ros::Publisher meshPub_;
  ros::Publisher surfacePub_;
  ros::Timer publishTimer_;

  // Reused between publishes so that a steady stream allocates nothing.
  visualization_msgs::Marker marker_;
  sensor_msgs::PointCloud2 cloud_;
};

}  // namespace deformable_flsm
