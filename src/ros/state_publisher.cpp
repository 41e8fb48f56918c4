#include "deformable_flsm/ros/state_publisher.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/ros/log_queue.h"
#include "deformable_flsm/ros/mesh_messages.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/console.h>
#include <tf2_eigen/tf2_eigen.h>

#include <algorithm>
#include <array>

namespace deformable_flsm {

namespace {

/// The single object's marker namespace on ~mesh (with ~objects, the object's name).
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

/// One object's heavy topics and its state topic (with ~objects).
class StatePublisher::ObjectTopics {
 public:
  ObjectTopics(ros::NodeHandle& pnh, const NodeParams& params, const SceneObject& object,
               std::size_t index, std::size_t count, bool namespaced)
      : params_(params), object_(object), namespaced_(namespaced) {
    ros::NodeHandle nh = namespaced ? ros::NodeHandle(pnh, "objects/" + object.name) : pnh;
    initTriangleListMarker(params_.frameId, namespaced ? object.name : kMarkerNamespace,
                           objectColor(index), marker_);
    marker_.id = static_cast<std::int32_t>(index);
    // every object's marker on the one ~mesh: a queue that holds one tick's markers
    mesh_.advertise<visualization_msgs::Marker>(pnh, "mesh", static_cast<std::uint32_t>(count));
    surface_.advertise<sensor_msgs::PointCloud2>(nh, "surface");
    particles_.advertise<sensor_msgs::PointCloud2>(nh, "particles");
    latticeMarkers_.advertise<visualization_msgs::MarkerArray>(nh, "lattice");
    if (namespaced) statePub_ = nh.advertise<SimulationState>("state", kStateQueue);
  }

  const SceneObject& object() const { return object_; }
  const visualization_msgs::Marker& marker() const { return marker_; }
  ros::Publisher& statePublisher() { return statePub_; }
  SimulationState& state() { return state_; }

  void publishHeavy(const Snapshot& s, const ObjectSnapshot& o, const ros::Time& stamp) {
    const Lattice& lattice = *object_.lattice;
    // One object of several is at rest while its version stays, although others move: its
    // messages are neither rebuilt nor, for the markers, re-sent. The single object rests with
    // the node, as it always did.
    const std::uint64_t seq = namespaced_ ? o.version : s.sequence;
    const bool resting = s.diag.idle || (namespaced_ && o.version != s.sequence);
    // The clouds keep the rate at rest (resent with a new stamp: no simulation, no rebuild);
    // the markers only with ~republish_at_rest (the bunny's ~mesh is 5 MB a message).
    const bool markersAtRest = params_.republishAtRest;
    const bool meshDue = mesh_.due(seq, resting, markersAtRest);
    const bool surfaceDue = surface_.due(seq, resting, kCloudsAtRest);
    if ((meshDue && mesh_.stale(seq)) || (surfaceDue && surface_.stale(seq))) {
      if (verticesSequence_ != seq) {
        object_.embedding->deform(o.positions, o.rotations, vertices_);
        // The embedded surface may dip below a collider the particles rest on: not on screen.
        projectOutOfColliders(vertices_, s.colliders, 0.0);
        verticesSequence_ = seq;
        verticesFinite_ = allFinite(vertices_);
      }
    }
    const bool verticesOk = !(meshDue || surfaceDue) || verticesFinite_;
    if (!verticesOk) {
      ++nonFiniteSkips_;
      static LogThrottle throttle(kWarnPeriod);
      if (throttle.ready())
        postLog(LogLevel::Error, formatted("flsm_node: the embedded mesh of object '%s' is not finite; its "
                                            "~mesh marker and ~surface skipped (%llu times). This is a "
                                            "bug: please report it.",
                                            object_.name.c_str(),
                                            static_cast<unsigned long long>(nonFiniteSkips_)));
    }
    if (meshDue && verticesOk) {
      mesh_.publish(seq, stamp, marker_, [&](visualization_msgs::Marker& m) {
        setTriangleListPoints(vertices_, object_.renderMesh.triangles, m);
      });
    }
    if (surfaceDue && verticesOk) {
      surface_.publish(seq, stamp, surfaceCloud_, [&](sensor_msgs::PointCloud2& cloud) {
        fillVertexCloud(vertices_, params_.frameId, cloud);
      });
    }
    // Particle positions are finite: the simulation thread resets a non-finite state.
    if (particles_.due(seq, resting, kCloudsAtRest)) {
      particles_.publish(seq, stamp, particleCloud_, [&](sensor_msgs::PointCloud2& cloud) {
        fillParticleCloud(o.positions, lattice.restPositions(), params_.frameId, cloud);
      });
    }
    if (latticeMarkers_.due(seq, resting, markersAtRest)) {
      latticeMarkers_.publish(seq, stamp, latticeMarkerArray_, [&](visualization_msgs::MarkerArray& markers) {
        dragLines_.clear();
        for (const DragView& d : o.drags) dragLines_.emplace_back(d.centroid, d.target);
        fillLatticeMarkers(o.positions, o.pinned, dragLines_, lattice.spacing(), params_.frameId, markers);
      });
    }
  }

 private:
  const NodeParams& params_;
  const SceneObject& object_;
  bool namespaced_;
  LazyTopic mesh_, surface_, particles_, latticeMarkers_;
  ros::Publisher statePub_;
  SimulationState state_;
  std::vector<Eigen::Vector3d> vertices_;  ///< embedded render vertices
  std::uint64_t verticesSequence_ = 0;
  bool verticesFinite_ = true;  ///< checked once per deform, not per resend at rest
  visualization_msgs::Marker marker_;
  sensor_msgs::PointCloud2 surfaceCloud_, particleCloud_;
  visualization_msgs::MarkerArray latticeMarkerArray_;
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> dragLines_;
  std::uint64_t nonFiniteSkips_ = 0;
};

StatePublisher::StatePublisher(ros::NodeHandle& pnh, const NodeParams& params,
                               const std::deque<SceneObject>& objects, bool namespaced,
                               const CommandStats& stats)
    : params_(params), stats_(stats), pnh_(pnh), namespaced_(namespaced) {
  for (std::size_t k = 0; k < objects.size(); ++k) {
    objects_.push_back(std::make_unique<ObjectTopics>(pnh, params_, objects[k], k, objects.size(),
                                                      namespaced));
    totalMass_ += objects[k].lattice->totalMass();
    totalParticles_ += objects[k].lattice->size();
  }
  advertised_ = objects.size();
  transforms_.resize(objects.size());
  statePub_ = pnh.advertise<SimulationState>("state", kStateQueue);
  meshPub_ = pnh.advertise<visualization_msgs::Marker>("mesh", static_cast<std::uint32_t>(objects.size()));
}

StatePublisher::~StatePublisher() = default;

void StatePublisher::addObject(const SceneObject& object) {
  objects_.push_back(std::make_unique<ObjectTopics>(pnh_, params_, object, advertised_++,
                                                    objects_.size() + 1, namespaced_));
  totalMass_ += object.lattice->totalMass();
  totalParticles_ += object.lattice->size();
}

bool StatePublisher::removeObject(const std::string& name, const ros::Time& stamp) {
  const auto it = std::find_if(objects_.begin(), objects_.end(),
                               [&](const std::unique_ptr<ObjectTopics>& o) { return o->object().name == name; });
  if (it == objects_.end()) return false;
  visualization_msgs::Marker gone = (*it)->marker();
  gone.action = visualization_msgs::Marker::DELETE;
  gone.points.clear();
  gone.header.stamp = stamp;
  meshPub_.publish(gone);
  totalMass_ -= (*it)->object().lattice->totalMass();
  totalParticles_ -= (*it)->object().lattice->size();
  objects_.erase(it);
  return true;
}

template <class Each>
void StatePublisher::forEachObject(const Snapshot& s, Each&& each) {
  // Both lists are in the order the objects were added; an object the loop has but we have not
  // advertised yet (or have just removed) is skipped.
  std::size_t k = 0;
  for (const ObjectSnapshot& o : s.objects) {
    if (k == objects_.size()) break;
    if (o.name == objects_[k]->object().name) each(*objects_[k++], o);
  }
}

void StatePublisher::publishTf(const Snapshot& s, const ros::Time& stamp) {
  std::size_t n = 0;
  forEachObject(s, [&](ObjectTopics& topics, const ObjectSnapshot& o) {
    if (transforms_.size() <= n) transforms_.resize(n + 1);
    geometry_msgs::TransformStamped& t = transforms_[n++];
    t = tf2::eigenToTransform(o.objectFrame);
    t.header.stamp = stamp;
    t.header.frame_id = params_.frameId;
    t.child_frame_id = topics.object().name;
  });
  transforms_.resize(n);
  tfBroadcaster_.sendTransform(transforms_);
}

void StatePublisher::fillState(const LoopDiagnostics& d, const ros::Time& stamp, double mass,
                               std::size_t particles, std::size_t colliders,
                               std::uint64_t colliderFrameMisses, SimulationState& m) const {
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
  m.mass = mass;
  m.particles = static_cast<std::uint32_t>(particles);
  m.pinned_particles = static_cast<std::uint32_t>(d.pinned);
  m.active_drags = static_cast<std::uint32_t>(d.drags);
  m.active_forces = static_cast<std::uint32_t>(d.forces);
  m.idle = d.idle;
  m.paused = d.paused;
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
  m.colliders = static_cast<std::uint32_t>(colliders);
  m.collider_frame_misses = colliderFrameMisses;
}

void StatePublisher::publishState(const Snapshot& s, const ros::Time& stamp,
                                  std::uint64_t colliderFrameMisses) {
  fillState(s.diag, stamp, totalMass_, totalParticles_, s.colliders.size(), colliderFrameMisses,
            state_);
  statePub_.publish(state_);
  forEachObject(s, [&](ObjectTopics& o, const ObjectSnapshot& snapshot) {
    if (!o.statePublisher() || o.statePublisher().getNumSubscribers() == 0) return;
    const Lattice& L = *o.object().lattice;
    fillState(snapshot.diag, stamp, L.totalMass(), L.size(), s.colliders.size(),
              colliderFrameMisses, o.state());
    o.statePublisher().publish(o.state());
  });
}

void StatePublisher::publishHeavy(const Snapshot& s, const ros::Time& stamp) {
  forEachObject(s, [&](ObjectTopics& o, const ObjectSnapshot& snapshot) { o.publishHeavy(s, snapshot, stamp); });
}

}  // namespace deformable_flsm
