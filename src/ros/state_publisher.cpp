#include "deformable_flsm/ros/state_publisher.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/ros/mesh_messages.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/console.h>
#include <tf2_eigen/tf2_eigen.h>

#include <array>

namespace deformable_flsm {

namespace {

/// Opaque, light clay colour: shading stays readable on RViz's dark background.
constexpr std::array<float, 4> kMeshColor = {0.85f, 0.72f, 0.55f, 1.0f};
constexpr const char kMarkerNamespace[] = "flsm_mesh";
/// Only the newest state matters to a subscriber.
constexpr std::uint32_t kStateQueue = 1;
constexpr double kWarnPeriod = 5.0;  // s between two warnings of the same kind
/// ~surface and ~particles keep ~publish_rate while the simulation rests: consumers of point
/// clouds (filters, rate monitors, bag recording) expect a steady stream, and a resend of the
/// cached cloud costs a copy onto the wire only.
constexpr bool kCloudsAtRest = true;

bool allFinite(const std::vector<Eigen::Vector3d>& xs) {
  for (const Eigen::Vector3d& x : xs)
    if (!x.allFinite()) return false;
  return true;
}

}  // namespace

StatePublisher::StatePublisher(ros::NodeHandle& pnh, const NodeParams& params, const Lattice& lattice,
                               const TriMesh& renderMesh, const Embedding& embedding,
                               const CommandStats& stats)
    : params_(params), lattice_(lattice), renderMesh_(renderMesh), embedding_(embedding), stats_(stats) {
  initTriangleListMarker(params_.frameId, kMarkerNamespace, kMeshColor, marker_);
  mesh_.advertise<visualization_msgs::Marker>(pnh, "mesh");
  surface_.advertise<sensor_msgs::PointCloud2>(pnh, "surface");
  particles_.advertise<sensor_msgs::PointCloud2>(pnh, "particles");
  latticeMarkers_.advertise<visualization_msgs::MarkerArray>(pnh, "lattice");
  statePub_ = pnh.advertise<SimulationState>("state", kStateQueue);
}

void StatePublisher::publishTf(const Snapshot& s, const ros::Time& stamp) {
  geometry_msgs::TransformStamped t = tf2::eigenToTransform(s.objectFrame);
  t.header.stamp = stamp;
  t.header.frame_id = params_.frameId;
  t.child_frame_id = params_.objectFrameId;
  tfBroadcaster_.sendTransform(t);
}

void StatePublisher::publishState(const Snapshot& s, const ros::Time& stamp,
                                  std::uint64_t colliderFrameMisses) {
  const LoopDiagnostics& d = s.diag;
  SimulationState& m = state_;
  m.header.stamp = stamp;
  m.header.frame_id = params_.frameId;
  m.sim_time = d.simTime;
  m.step_time = d.stepSeconds;
  m.real_time_factor = d.achievedRealTimeFactor;
  m.requested_real_time_factor = d.requestedRealTimeFactor;
  m.kinetic_energy = d.kineticEnergy;
  m.max_displacement = d.maxDisplacement;
  m.max_speed = d.maxSpeed;
  m.shape_error = d.shapeError;
  m.mass = lattice_.totalMass();
  m.particles = static_cast<std::uint32_t>(lattice_.size());
  m.pinned_particles = static_cast<std::uint32_t>(d.pinned);
  m.active_drags = static_cast<std::uint32_t>(d.drags);
  m.active_forces = static_cast<std::uint32_t>(d.forces);
  m.idle = d.idle;
  m.stiffness_saturated = d.stiffnessSaturated;
  m.alpha = d.alpha;
  m.steps = d.steps;
  m.dropped_steps = d.droppedSteps;
  m.solver_resets = d.solverResets;
  const CommandStats::Counts counts = stats_.counts();
  m.accepted_commands = counts.accepted;
  m.rejected_commands = counts.rejected;
  m.reject_reasons.clear();
  m.reject_counts.clear();
  for (const auto& entry : counts.rejectedByReason) {
    m.reject_reasons.push_back(entry.first);
    m.reject_counts.push_back(entry.second);
  }
  m.last_rejection = counts.lastRejection;
  m.colliders = static_cast<std::uint32_t>(s.colliders.size());
  m.collider_frame_misses = colliderFrameMisses;
  statePub_.publish(m);
}

void StatePublisher::publishHeavy(const Snapshot& s, const ros::Time& stamp) {
  // The clouds keep the rate at rest (resent with a new stamp: no simulation, no rebuild);
  // the markers only with ~republish_at_rest (the bunny's ~mesh is 5 MB a message).
  const bool markersAtRest = params_.republishAtRest;
  const bool meshDue = mesh_.due(s, markersAtRest);
  const bool surfaceDue = surface_.due(s, kCloudsAtRest);
  if ((meshDue && mesh_.stale(s)) || (surfaceDue && surface_.stale(s))) {
    if (verticesSequence_ != s.sequence) {
      embedding_.deform(s.positions, s.rotations, vertices_);
      // The embedded surface may dip below a collider the particles rest on: not on screen.
      projectOutOfColliders(vertices_, s.colliders, 0.0);
      verticesSequence_ = s.sequence;
      verticesFinite_ = allFinite(vertices_);
    }
  }
  const bool verticesOk = !(meshDue || surfaceDue) || verticesFinite_;
  if (!verticesOk) {
    ++nonFiniteSkips_;
    ROS_ERROR_THROTTLE(kWarnPeriod, "flsm_node: the embedded mesh is not finite; ~mesh and "
                       "~surface skipped (%llu times). This is a bug: please report it.",
                       static_cast<unsigned long long>(nonFiniteSkips_));
  }
  if (meshDue && verticesOk) {
    mesh_.publish(s, stamp, marker_, [&](visualization_msgs::Marker& m) {
      setTriangleListPoints(vertices_, renderMesh_.triangles, m);
    });
  }
  if (surfaceDue && verticesOk) {
    surface_.publish(s, stamp, surfaceCloud_, [&](sensor_msgs::PointCloud2& cloud) {
      fillVertexCloud(vertices_, params_.frameId, cloud);
    });
  }
  // Particle positions are finite: the simulation thread resets a non-finite state.
  if (particles_.due(s, kCloudsAtRest)) {
    particles_.publish(s, stamp, particleCloud_, [&](sensor_msgs::PointCloud2& cloud) {
      fillParticleCloud(s.positions, lattice_.restPositions(), params_.frameId, cloud);
    });
  }
  if (latticeMarkers_.due(s, markersAtRest)) {
    latticeMarkers_.publish(s, stamp, latticeMarkerArray_, [&](visualization_msgs::MarkerArray& markers) {
      dragLines_.clear();
      for (const DragView& d : s.drags) dragLines_.emplace_back(d.centroid, d.target);
      fillLatticeMarkers(s.positions, s.pinned, dragLines_, lattice_.spacing(), params_.frameId, markers);
    });
  }
}

}  // namespace deformable_flsm
