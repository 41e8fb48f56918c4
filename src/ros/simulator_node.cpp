#include "deformable_flsm/ros/simulator_node.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/console.h>
#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

#include <chrono>
#include <future>
#include <utility>

namespace deformable_flsm {

namespace {

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
constexpr double kRejectPeriod = 1.0;  // s between two rejection warnings

Eigen::Vector3d toEigen(const geometry_msgs::Point& p) { return {p.x, p.y, p.z}; }

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

  publisher_ = std::make_unique<StatePublisher>(pnh_, params_, *lattice_, renderMesh_, *embedding_, *stats_);
  reporter_ = std::make_unique<ProblemReporter>(params_, info_, *lattice_);
  advertise();
  reconfigure_ = std::make_unique<Reconfigure>(pnh_, params_,
                                               [this](const FlsmConfig& c) { onReconfigure(c); });
  mouse_ = std::make_unique<InteractiveDrag>(pnh_, params_.frameId, *lattice_, renderMesh_,
                                             [this](const DragCommand& d) { return onMouseDrag(d); });

  reporter_->warnAboutScene();
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
  mouse_.reset();
}

void SimulatorNode::advertise() {
  // Commands and services on their own queue and thread (see the class comment).
  commandNh_.setCallbackQueue(&commandQueue_);
  dragSub_ = commandNh_.subscribe("drag", kCommandQueue, &SimulatorNode::onDrag, this);
  forceSub_ = commandNh_.subscribe("force", kCommandQueue, &SimulatorNode::onForce, this);
  resetSrv_ = commandNh_.advertiseService("reset", &SimulatorNode::onReset, this);
  releaseAllSrv_ = commandNh_.advertiseService("release_all", &SimulatorNode::onReleaseAll, this);
  pinBoxSrv_ = commandNh_.advertiseService("pin_box", &SimulatorNode::onPinBox, this);
}

// --------------------------------------------------------------------------------------------
// State out

void SimulatorNode::onPublishTimer(const ros::TimerEvent& event) {
  reporter_->publishingTook(event.profile.last_duration.toSec());
  const ros::Time stamp = ros::Time::now();
  const Snapshot& s = loop_->acquire();
  publisher_->publishTf(s, stamp);
  publisher_->publishState(s, stamp);
  reporter_->report(s.diag);
  mouse_->follow(s.objectFrame);
  publisher_->publishHeavy(s, stamp);
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

bool SimulatorNode::onMouseDrag(const DragCommand& drag) {
  CommandBody body;
  Rejection why;
  if (!validator_->drag(drag, body, why)) {
    rejected(why);
    return false;
  }
  send(std::move(body), false);
  return true;
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

void SimulatorNode::onReconfigure(const FlsmConfig& config) {
  SolverParams p = Reconfigure::solverParams(config, params_.solver);
  p.regionHalfWidth = info_.regionHalfWidth;
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
