#include "deformable_flsm/ros/simulator_node.h"

#include "deformable_flsm/ros/mesh_messages.h"
#include "deformable_flsm/ros/render_mesh.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/console.h>
#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>
#include <visualization_msgs/InteractiveMarker.h>
#include <visualization_msgs/InteractiveMarkerControl.h>

#include <chrono>
#include <cmath>
#include <future>
#include <utility>

namespace deformable_flsm {

namespace {

/// Opaque, light clay colour: shading stays readable on RViz's dark background.
constexpr std::array<float, 4> kMeshColor = {0.85f, 0.72f, 0.55f, 1.0f};
constexpr const char kMarkerNamespace[] = "flsm_mesh";
/// Only the newest state matters to a subscriber.
constexpr std::uint32_t kStateQueue = 1;
/// Incoming commands: enough for a burst between two drains of the spinner thread; the
/// simulation's own queue (CommandLimits::kQueueCapacity) is the bound that is counted.
constexpr std::uint32_t kCommandQueue = 100;
/// How long a service waits for the simulation thread to apply its command (s).
constexpr double kServiceTimeout = 2.0;
/// How long a command waits for its transform (s). The tf listener is started by the first
/// command in a frame other than ~frame_id (so that a node nobody commands in other frames
/// does not receive its own tf 30 times a second); that first lookup waits longer, for the
/// listener to hear the frame.
constexpr double kTransformTimeout = 0.1;
constexpr double kFirstTransformTimeout = 1.0;
/// The simulation rests when every particle is slower than this many object sizes per second
/// (1 mm/s for the 30 cm bunny: a 2 Hz wobble of 0.08 mm, invisible) ...
constexpr double kIdleSpeedPerSize = 3e-3;
/// ... for this long (s of simulated time) with nothing acting on it.
constexpr double kIdleHold = 1.0;
/// Warn when the achieved real-time factor falls below this fraction of the requested one.
constexpr double kSlowFraction = 0.9;
constexpr double kWarnPeriod = 5.0;    // s between two warnings of the same kind
constexpr double kRejectPeriod = 1.0;  // s between two rejection warnings
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

geometry_msgs::Point toPoint(const Eigen::Vector3d& v) {
  geometry_msgs::Point p;
  p.x = v.x();
  p.y = v.y();
  p.z = v.z();
  return p;
}

Eigen::Vector3d toEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

bool allFinite(const std::vector<Eigen::Vector3d>& xs) {
  for (const Eigen::Vector3d& x : xs)
    if (!x.allFinite()) return false;
  return true;
}

Eigen::Vector3d restCenterOfMass(const Lattice& L) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < L.size(); ++i) c += L.masses()[i] * L.restPositions()[i];
  return c / L.totalMass();
}

}  // namespace

SimulatorNode::SimulatorNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
                             const NodeParams& params, Scene scene)
    : nh_(nh), pnh_(pnh), commandNh_(pnh), params_(params), info_(scene.info),
      lattice_(scene.lattice), renderMesh_(std::move(scene.renderMesh)),
      embedding_(std::move(scene.embedding)), stats_(std::make_shared<CommandStats>()) {
  stats_->setRejectHook([](const std::string& reason, const std::string& detail) {
    ROS_WARN_THROTTLE(kRejectPeriod, "flsm_node: command rejected (%s): %s", reason.c_str(),
                      detail.c_str());
  });

  LoopSettings settings;
  settings.realTimeFactor = params_.realTimeFactor;
  settings.idleSpeed = kIdleSpeedPerSize * lattice_->objectSize();
  settings.idleHold = kIdleHold;
  loop_ = std::make_unique<SimulationLoop>(std::move(scene.solver), settings, stats_);

  validator_ = std::make_unique<CommandValidator>(
      lattice_->size(), lattice_->objectSize(), params_.frameId,
      [this](const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d& T,
             std::string& why) { return lookupTransform(frame, stamp, T, why); },
      [this] { return loop_->centerOfMass(); });

  initTriangleListMarker(params_.frameId, kMarkerNamespace, kMeshColor, marker_);
  advertise();

  // dynamic_reconfigure: start from the loaded parameters, then listen. The first callback
  // (setCallback calls it at once) only echoes them and is skipped.
  reconfigure_ = std::make_unique<dynamic_reconfigure::Server<FlsmConfig>>(reconfigureMutex_, pnh_);
  FlsmConfig config;
  config.youngs_modulus = params_.solver.youngsModulus;
  config.poissons_ratio = params_.solver.poissonsRatio;
  config.stiffness = params_.solver.stiffness;
  config.damping = params_.solver.damping;
  config.ambient_damping = params_.solver.ambientDamping;
  config.gravity_x = params_.solver.gravity.x();
  config.gravity_y = params_.solver.gravity.y();
  config.gravity_z = params_.solver.gravity.z();
  config.publish_rate = params_.publishRate;
  config.real_time_factor = params_.realTimeFactor;
  reconfigure_->updateConfig(config);
  reconfigure_->setCallback(
      [this](FlsmConfig& c, std::uint32_t level) { onReconfigure(c, level); });
  reconfigureReady_ = true;

  setUpInteractiveMarker();

  warnAboutScene();
  reportedSaturated_ = info_.substepsForModulus > 0;  // warned about above
  loop_->start();
  publishTimer_ = pnh_.createTimer(ros::Duration(1.0 / params_.publishRate),
                                   &SimulatorNode::onPublishTimer, this);
  commandSpinner_ = std::make_unique<ros::AsyncSpinner>(1, &commandQueue_);
  commandSpinner_->start();
}

SimulatorNode::~SimulatorNode() {
  publishTimer_.stop();
  loop_->stop();  // answers services still waiting, so the spinner can stop
  commandSpinner_->stop();
  markerServer_.reset();
}

void SimulatorNode::warnAboutScene() const {
  const std::string saturated = saturationWarning(info_, params_);
  if (!saturated.empty()) ROS_WARN("flsm_node: %s", saturated.c_str());
  for (std::size_t b = 0; b < info_.pinnedPerBox.size(); ++b) {
    if (info_.pinnedPerBox[b] == 0) {
      ROS_WARN("flsm_node: ~pinned box %zu holds no particle (rest positions are in frame '%s', "
               "after ~mesh_scale and ~mesh_rpy; the lattice spans [%.3g, %.3g, %.3g] to "
               "[%.3g, %.3g, %.3g] m)",
               b, params_.frameId.c_str(), lattice_->restMin().x(), lattice_->restMin().y(),
               lattice_->restMin().z(), lattice_->restMax().x(), lattice_->restMax().y(),
               lattice_->restMax().z());
    }
  }
  if (info_.pinned == 0 && !params_.solver.gravity.isZero(0.0)) {
    ROS_WARN("flsm_node: gravity is on and no particle is pinned: with no ground, the object "
             "falls forever. Pin a box (~pinned) or set ~gravity to [0, 0, 0].");
  }
}

void SimulatorNode::advertise() {
  auto lazy = [this](LazyTopic& topic, auto type, const std::string& name, bool latch) {
    using Msg = decltype(type);
    ros::AdvertiseOptions options;
    options.template init<Msg>(
        name, 1, [&topic](const ros::SingleSubscriberPublisher&) { topic.newSubscriber = true; });
    options.latch = latch;
    topic.pub = pnh_.advertise(options);
  };
  // Not latched: a new subscriber is served by the connect callback with a fresh stamp.
  lazy(mesh_, visualization_msgs::Marker(), "mesh", false);
  lazy(surface_, sensor_msgs::PointCloud2(), "surface", false);
  lazy(particles_, sensor_msgs::PointCloud2(), "particles", false);
  lazy(lattice_markers_, visualization_msgs::MarkerArray(), "lattice", false);
  statePub_ = pnh_.advertise<SimulationState>("state", kStateQueue);

  // Commands and services on their own queue and thread (see the class comment).
  commandNh_.setCallbackQueue(&commandQueue_);
  dragSub_ = commandNh_.subscribe("drag", kCommandQueue, &SimulatorNode::onDrag, this);
  forceSub_ = commandNh_.subscribe("force", kCommandQueue, &SimulatorNode::onForce, this);
  resetSrv_ = commandNh_.advertiseService("reset", &SimulatorNode::onReset, this);
  releaseAllSrv_ = commandNh_.advertiseService("release_all", &SimulatorNode::onReleaseAll, this);
  pinBoxSrv_ = commandNh_.advertiseService("pin_box", &SimulatorNode::onPinBox, this);
}

void SimulatorNode::setUpInteractiveMarker() {
  markerServer_ = std::make_unique<interactive_markers::InteractiveMarkerServer>(
      pnh_.resolveName("drag_marker"), "", false);
  const Eigen::Vector3d com = restCenterOfMass(*lattice_);
  handlePose_ = Eigen::Translation3d(com);

  visualization_msgs::InteractiveMarker im;
  im.header.frame_id = params_.frameId;
  im.name = "object";
  im.description = "";
  im.scale = static_cast<float>(lattice_->objectSize());
  im.pose = tf2::toMsg(handlePose_);

  // What RViz picks: a coarse copy of the object, invisible, in the object's frame.
  visualization_msgs::Marker handle;
  initTriangleListMarker(params_.frameId, "flsm_handle", {1.0f, 1.0f, 1.0f, kHandleAlpha}, handle);
  TriMesh coarse = simplifyMesh(renderMesh_, kHandleTriangles).mesh;
  for (Eigen::Vector3d& v : coarse.vertices) v -= com;
  setTriangleListPoints(coarse.vertices, coarse.triangles, handle);
  handle.header.frame_id.clear();  // in the interactive marker's frame

  visualization_msgs::InteractiveMarkerControl control;
  control.name = "drag";
  control.interaction_mode = visualization_msgs::InteractiveMarkerControl::MOVE_3D;
  control.orientation.w = 1.0;
  control.always_visible = true;
  control.markers.push_back(handle);
  im.controls.push_back(control);

  markerServer_->insert(
      im, [this](const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback) {
        onMarkerFeedback(feedback);
      });
  markerServer_->applyChanges();
}

// --------------------------------------------------------------------------------------------
// State out

void SimulatorNode::onPublishTimer(const ros::TimerEvent& event) {
  if (event.profile.last_duration.toSec() > 1.0 / params_.publishRate) {
    ROS_WARN_THROTTLE(kWarnPeriod,
                      "flsm_node: publishing took %.1f ms, longer than the %.1f ms period of "
                      "~publish_rate: lower ~publish_rate or ~render_triangle_budget",
                      1e3 * event.profile.last_duration.toSec(), 1e3 / params_.publishRate);
  }
  const ros::Time stamp = ros::Time::now();
  const Snapshot& s = loop_->acquire();
  publishTf(s, stamp);
  publishState(s, stamp);
  reportProblems(s);
  updateHandlePose(s);

  const bool meshDue = due(mesh_, s);
  const bool surfaceDue = due(surface_, s);
  if ((meshDue && mesh_.builtSequence != s.sequence) ||
      (surfaceDue && surface_.builtSequence != s.sequence)) {
    if (verticesSequence_ != s.sequence) {
      embedding_->deform(s.positions, s.rotations, vertices_);
      verticesSequence_ = s.sequence;
    }
  }
  const bool verticesOk = !(meshDue || surfaceDue) || allFinite(vertices_);
  if (!verticesOk) {
    ++nonFiniteSkips_;
    ROS_ERROR_THROTTLE(kWarnPeriod, "flsm_node: the embedded mesh is not finite; ~mesh and "
                       "~surface skipped (%llu times). This is a bug: please report it.",
                       static_cast<unsigned long long>(nonFiniteSkips_));
  }
  if (meshDue && verticesOk) {
    if (mesh_.builtSequence != s.sequence) {
      setTriangleListPoints(vertices_, renderMesh_.triangles, marker_);
      mesh_.builtSequence = s.sequence;
    }
    marker_.header.stamp = stamp;
    mesh_.pub.publish(marker_);
    mesh_.publishedSequence = s.sequence;
  }
  if (surfaceDue && verticesOk) {
    if (surface_.builtSequence != s.sequence) {
      fillVertexCloud(vertices_, params_.frameId, surfaceCloud_);
      surface_.builtSequence = s.sequence;
    }
    surfaceCloud_.header.stamp = stamp;
    surface_.pub.publish(surfaceCloud_);
    surface_.publishedSequence = s.sequence;
  }
  // Particle positions are finite: the simulation thread resets a non-finite state.
  if (due(particles_, s)) {
    if (particles_.builtSequence != s.sequence) {
      fillParticleCloud(s.positions, lattice_->restPositions(), params_.frameId, particleCloud_);
      particles_.builtSequence = s.sequence;
    }
    particleCloud_.header.stamp = stamp;
    particles_.pub.publish(particleCloud_);
    particles_.publishedSequence = s.sequence;
  }
  if (due(lattice_markers_, s)) {
    if (lattice_markers_.builtSequence != s.sequence) {
      dragLines_.clear();
      for (const DragView& d : s.drags) dragLines_.emplace_back(d.centroid, d.target);
      fillLatticeMarkers(s.positions, s.pinned, dragLines_, lattice_->spacing(), params_.frameId,
                         latticeMarkers_);
      lattice_markers_.builtSequence = s.sequence;
    }
    for (auto& m : latticeMarkers_.markers) m.header.stamp = stamp;
    lattice_markers_.pub.publish(latticeMarkers_);
    lattice_markers_.publishedSequence = s.sequence;
  }
}

bool SimulatorNode::due(LazyTopic& topic, const Snapshot& s) const {
  if (topic.pub.getNumSubscribers() == 0) return false;
  const bool newSubscriber = topic.newSubscriber.exchange(false);
  // While the simulation runs: every tick. At rest: the final state once, then only to new
  // subscribers (what they missed); the others already show it. ~republish_at_rest keeps the
  // stream steady instead (the cached message goes out again with a new stamp).
  return !s.diag.idle || params_.republishAtRest || topic.publishedSequence != s.sequence ||
         newSubscriber;
}

void SimulatorNode::publishTf(const Snapshot& s, const ros::Time& stamp) {
  geometry_msgs::TransformStamped t = tf2::eigenToTransform(s.objectFrame);
  t.header.stamp = stamp;
  t.header.frame_id = params_.frameId;
  t.child_frame_id = params_.objectFrameId;
  tfBroadcaster_.sendTransform(t);
}

void SimulatorNode::publishState(const Snapshot& s, const ros::Time& stamp) {
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
  m.particles = static_cast<std::uint32_t>(lattice_->size());
  m.pinned_particles = static_cast<std::uint32_t>(d.pinned);
  m.active_drags = static_cast<std::uint32_t>(d.drags);
  m.active_forces = static_cast<std::uint32_t>(d.forces);
  m.idle = d.idle;
  m.stiffness_saturated = d.stiffnessSaturated;
  m.alpha = d.alpha;
  m.steps = d.steps;
  m.dropped_steps = d.droppedSteps;
  m.solver_resets = d.solverResets;
  const CommandStats::Counts counts = stats_->counts();
  m.accepted_commands = counts.accepted;
  m.rejected_commands = counts.rejected;
  m.reject_reasons.clear();
  m.reject_counts.clear();
  for (const auto& entry : counts.rejectedByReason) {
    m.reject_reasons.push_back(entry.first);
    m.reject_counts.push_back(entry.second);
  }
  m.last_rejection = counts.lastRejection;
  statePub_.publish(m);
}

void SimulatorNode::reportProblems(const Snapshot& s) {
  const LoopDiagnostics& d = s.diag;
  if (d.stiffnessSaturated != reportedSaturated_) {
    reportedSaturated_ = d.stiffnessSaturated;
    if (d.stiffnessSaturated) {
      ROS_WARN("flsm_node: ~youngs_modulus %.4g Pa now asks for more stiffness than the time "
               "step allows (alpha capped at %.3g): the material is softer than asked; more "
               "~substeps (restart) would fix it", params_.solver.youngsModulus, d.alpha);
    }
  }
  if (d.solverResets > reportedResets_) {
    reportedResets_ = d.solverResets;
    ROS_ERROR("flsm_node: the solver state became non-finite and was reset to rest (%llu "
              "times so far). This should not happen: please report it with the commands sent.",
              static_cast<unsigned long long>(d.solverResets));
  }
  if (d.droppedSteps > reportedDropped_) {
    reportedDropped_ = d.droppedSteps;
    ROS_WARN_THROTTLE(kWarnPeriod,
                      "flsm_node: the machine cannot keep up: %.2f simulated s per wall s (asked "
                      "%.2f), a step takes %.1f ms for %.1f ms of simulated time; %llu steps "
                      "dropped so far. Lower ~real_time_factor, ~substeps or ~particle_budget.",
                      d.achievedRealTimeFactor, d.requestedRealTimeFactor, 1e3 * d.stepSeconds,
                      1e3 * params_.solver.timeStep,
                      static_cast<unsigned long long>(d.droppedSteps));
  } else if (!d.idle && d.achievedRealTimeFactor < kSlowFraction * d.requestedRealTimeFactor &&
             d.steps > 10) {
    // A step may take the wall time it stands for; if it takes (nearly) all of it, the scene is too
    // big for the asked rate (or the machine too busy to give it a core); if not, something else
    // holds the loop up.
    const double budget = params_.solver.timeStep / d.requestedRealTimeFactor;
    const bool stepsTooLong = d.stepSeconds > kSlowFraction * budget;
    ROS_WARN_THROTTLE(kWarnPeriod,
                      "flsm_node: running at %.2f of the asked real-time factor %.2f (a step takes "
                      "%.1f ms of the %.1f ms it may); %s",
                      d.achievedRealTimeFactor / d.requestedRealTimeFactor, d.requestedRealTimeFactor,
                      1e3 * d.stepSeconds, 1e3 * budget,
                      stepsTooLong ? "the steps take too long: lower ~real_time_factor, ~substeps or "
                                     "~particle_budget, or free a core"
                                   : "the steps fit, so other work on this machine holds the loop up");
  }
}

void SimulatorNode::updateHandlePose(const Snapshot& s) {
  if (mouseDragging_) return;  // RViz owns the handle while the mouse holds it
  const double moved = (s.objectFrame.translation() - handlePose_.translation()).norm();
  const Eigen::AngleAxisd turned(s.objectFrame.linear().transpose() * handlePose_.linear());
  if (moved < kHandleMoveFraction * lattice_->objectSize() && std::abs(turned.angle()) < kHandleTurn)
    return;
  handlePose_ = s.objectFrame;
  markerServer_->setPose("object", tf2::toMsg(handlePose_));
  markerServer_->applyChanges();
}

// --------------------------------------------------------------------------------------------
// Commands in

void SimulatorNode::rejected(const Rejection& why) { stats_->reject(why.reason, why.detail); }

CommandOutcome SimulatorNode::send(CommandBody body, bool wait) {
  Command command{std::move(body), nullptr};
  std::future<CommandOutcome> result;
  if (wait) {
    command.outcome = std::make_shared<std::promise<CommandOutcome>>();
    result = command.outcome->get_future();
  }
  loop_->submit(std::move(command));
  if (!wait) return CommandOutcome{true, "queued", 0, 0};
  if (result.wait_for(std::chrono::duration<double>(kServiceTimeout)) != std::future_status::ready) {
    CommandOutcome late;
    late.message = "the simulation thread did not answer within 2 s";
    return late;
  }
  return result.get();
}

bool SimulatorNode::lookupTransform(const std::string& frame, const ros::Time& stamp,
                                    Eigen::Isometry3d& T, std::string& why) {
  double timeout = kTransformTimeout;
  {
    std::lock_guard<std::mutex> lock(tfListenerMutex_);
    if (!tfListener_) {
      tfListener_ = std::make_unique<tf2_ros::TransformListener>(tfBuffer_);
      timeout = kFirstTransformTimeout;
    }
  }
  try {
    const geometry_msgs::TransformStamped t = tfBuffer_.lookupTransform(
        params_.frameId, frame, stamp, ros::Duration(timeout));
    T = tf2::transformToEigen(t);
    return true;
  } catch (const tf2::TransformException& e) {
    why = e.what();
    return false;
  }
}

void SimulatorNode::onDrag(const DragCommand::ConstPtr& msg) {
  CommandBody body;
  Rejection why;
  if (!validator_->drag(*msg, body, why)) return rejected(why);
  send(std::move(body), false);
}

void SimulatorNode::onForce(const ForceCommand::ConstPtr& msg) {
  CommandBody body;
  Rejection why;
  if (!validator_->force(*msg, body, why)) return rejected(why);
  send(std::move(body), false);
}

void SimulatorNode::onMarkerFeedback(
    const visualization_msgs::InteractiveMarkerFeedbackConstPtr& feedback) {
  using visualization_msgs::InteractiveMarkerFeedback;
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
      mouseGrabPoint_ = toEigen(feedback->mouse_point);
      mouseGrabPose_ = pose;
      break;
    case InteractiveMarkerFeedback::POSE_UPDATE:
      if (!mouseDragging_) return;
      drag.action = DragCommand::MOVE;
      drag.target = toPoint(mouseGrabPoint_ + (pose - mouseGrabPose_));
      break;
    case InteractiveMarkerFeedback::MOUSE_UP:
      if (!mouseDragging_) return;
      drag.action = DragCommand::RELEASE;
      break;
    default:
      return;
  }
  CommandBody body;
  Rejection why;
  if (!validator_->drag(drag, body, why)) {
    rejected(why);
    return;
  }
  send(std::move(body), false);
  if (drag.action == DragCommand::GRAB) mouseDragging_ = true;
  if (drag.action == DragCommand::RELEASE) {
    mouseDragging_ = false;
    handlePose_.translation().setConstant(std::nan(""));  // snap back at the next tick
  }
}

bool SimulatorNode::onReset(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  const CommandOutcome o = send(ResetCommand{}, true);
  res.success = o.accepted;
  res.message = o.message;
  return true;
}

bool SimulatorNode::onReleaseAll(std_srvs::Trigger::Request&, std_srvs::Trigger::Response& res) {
  const CommandOutcome o = send(ReleaseAllCommand{}, true);
  res.success = o.accepted;
  res.message = o.message;
  return true;
}

bool SimulatorNode::onPinBox(PinBox::Request& req, PinBox::Response& res) {
  const Eigen::Vector3d lo = toEigen(req.min), hi = toEigen(req.max);
  Rejection why;
  if (!validator_->box(lo, hi, why)) {
    rejected(why);
    res.success = false;
    res.message = why.detail;
    return true;
  }
  const CommandOutcome o = send(PinBoxCommand{lo, hi, static_cast<bool>(req.pin)}, true);
  res.success = o.accepted;
  res.message = o.message;
  res.particles = static_cast<std::uint32_t>(o.particles);
  res.pinned_total = static_cast<std::uint32_t>(o.pinnedTotal);
  return true;
}

void SimulatorNode::onReconfigure(FlsmConfig& config, std::uint32_t /*level*/) {
  if (!reconfigureReady_) return;
  SolverParams p = params_.solver;
  p.regionHalfWidth = info_.regionHalfWidth;
  p.youngsModulus = config.youngs_modulus;
  p.poissonsRatio = config.poissons_ratio;
  p.stiffness = config.stiffness;
  p.damping = config.damping;
  p.ambientDamping = config.ambient_damping;
  p.gravity = Eigen::Vector3d(config.gravity_x, config.gravity_y, config.gravity_z);
  try {
    p.validate();
  } catch (const std::invalid_argument& e) {
    stats_->reject("invalid_params", e.what());
    return;
  }
  params_.solver = p;
  send(ParamsCommand{p}, false);
  if (config.publish_rate != params_.publishRate) {
    params_.publishRate = config.publish_rate;
    publishTimer_.setPeriod(ros::Duration(1.0 / params_.publishRate));
  }
  if (config.real_time_factor != params_.realTimeFactor) {
    params_.realTimeFactor = config.real_time_factor;
    loop_->setRealTimeFactor(params_.realTimeFactor);
  }
}

}  // namespace deformable_flsm
