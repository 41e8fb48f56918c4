#include "deformable_flsm/ros/simulator_node.h"

#include "deformable_flsm/ros/collider_messages.h"
#include "deformable_flsm/ros/object_params.h"

#include "simulator_node_internal.h"
#include "thread_name.h"
#include "to_eigen.h"

#include <geometry_msgs/TransformStamped.h>
#include <ros/console.h>
#include <ros/wall_timer.h>
#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

#include <chrono>
#include <cmath>
#include <future>
#include <iterator>
#include <utility>

namespace deformable_flsm {

namespace {

/// Incoming commands. Their callback never waits (tf is not waited for, services have their
/// own thread), so this queue only has to hold what arrives while it validates a message
/// (microseconds) or, once, while the first foreign frame starts the tf listener: 1000 holds
/// a second of several floods at a few hundred messages per second. Beyond it roscpp would drop
/// the oldest uncounted; the simulation's own queue (CommandLimits::kQueueCapacity) is counted.
constexpr std::uint32_t kCommandQueue = 1000;
/// Commands do not wait for tf. The tf listener is started by the first command in a frame
/// other than ~frame_id (so that a node nobody commands in other frames does not receive its
/// own tf 30 times a second); that first lookup alone waits, for the listener to hear the
/// frames, up to this long (s).
constexpr double kFirstTransformTimeout = 1.0;
constexpr double kRejectPeriod = 1.0;  // s between two rejection warnings
/// A frame that drags are attached to whose newest transform is older than this (s) is stale:
/// its drags hold still (as colliders that follow a frame do, ColliderFollower::kStaleAfter).
constexpr double kAttachStaleAfter = 0.5;
constexpr double kAttachWarnPeriod = 5.0;  // s between two warnings about attached frames
/// /clock carries one tick each; a subscriber that falls behind needs only the newest.
constexpr std::uint32_t kClockQueue = 10;

LoopTime loopTime(NodeParams::Clock clock) {
  switch (clock) {
    case NodeParams::Clock::Sim: return LoopTime::Served;
    case NodeParams::Clock::Follow: return LoopTime::Followed;
    case NodeParams::Clock::Wall: break;
  }
  return LoopTime::Paced;
}

}  // namespace

SimulatorNode::SimulatorNode(const ros::NodeHandle& nh, const ros::NodeHandle& pnh,
                             const NodeParams& params, WorldScene scene, bool namespaced)
    : log_(std::make_unique<LogQueue>(writeToRosconsole)),
      logInstalled_(log_.get()),
      nh_(nh), pnh_(pnh), stateNh_(pnh), commandNh_(pnh), serviceNh_(pnh), reconfigureNh_(pnh),
      params_(params), objects_(std::make_move_iterator(scene.objects.begin()),
                                std::make_move_iterator(scene.objects.end())),
      namespaced_(namespaced),
      stats_(std::make_shared<CommandStats>()) {
  stats_->setRejectHook([throttle = std::make_shared<LogThrottle>(kRejectPeriod)](
                            const std::string& reason, const std::string& detail) {
    if (throttle->ready())
      postLog(LogLevel::Warn, "flsm_node: command rejected (" + reason + "): " + detail);
  });

  checkClock();
  startLoop(scene);
  makeValidators();
  makeReporter();
  makeInterfaces();
  reporter_->warnAboutScene();
  makeSensors();
  startThreads();
}

void SimulatorNode::startLoop(WorldScene& scene) {
  for (const TactileSpec& t : params_.tactile) {
    try {
      scene.world->recordContacts(t.collider, true);
    } catch (const std::invalid_argument& e) {
      throw ParamError("~tactile sensor '" + t.name + "': " + e.what() + " (set ~object_contact and "
                       "~self_contact false, or no tactile sensor)");
    }
  }
  LoopSettings settings;
  settings.realTimeFactor = params_.realTimeFactor;
  settings.time = loopTime(params_.clock);
  settings.startPaused = params_.startPaused;
  // Rest (LoopSettings::restFraction, idleHold): the defaults, relative to the object size.
  loop_ = std::make_unique<SimulationLoop>(std::move(scene.world), settings, stats_);
  loop_->setNotice([](const std::string& what) { postLog(LogLevel::Warn, "flsm_node: " + what); });
  if (params_.clock == NodeParams::Clock::Sim) {
    clockPub_ = nh_.advertise<rosgraph_msgs::Clock>("/clock", kClockQueue);
    loop_->setTickObserver([this](double time, const Snapshot* state) { onTick(time, state); });
  }
}

void SimulatorNode::makeValidators() {
  commands_.resize(objects_.size());
  for (std::size_t k = 0; k < objects_.size(); ++k) {
    const Lattice& L = *objects_[k].lattice;
    commands_[k].validator = std::make_unique<CommandValidator>(
        L.size(), L.objectSize(), params_.frameId,
        [this](const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d& T,
               std::string& why) { return lookupTransform(frame, stamp, T, why); },
        [this, k] { return loop_->centerOfMass(k); });
  }
}

void SimulatorNode::makeReporter() {
  const SceneObject& first = objects_.front();
  publisher_ = std::make_unique<StatePublisher>(pnh_, params_, objects_, namespaced_, *stats_);
  // The pins of the whole scene: a ~pinned box holds nothing only if it holds no object's
  // particle. The material warnings are the first object's (flsm_node warns of the others').
  sceneInfo_ = first.info;
  for (std::size_t k = 1; k < objects_.size(); ++k) {
    const SceneInfo& other = objects_[k].info;
    sceneInfo_.pinned += other.pinned;
    for (std::size_t b = 0; b < sceneInfo_.pinnedPerBox.size() && b < other.pinnedPerBox.size(); ++b)
      sceneInfo_.pinnedPerBox[b] += other.pinnedPerBox[b];
  }
  reporter_ = std::make_unique<ProblemReporter>(
      params_, sceneInfo_, *first.lattice, [](ProblemSeverity severity, const std::string& line) {
        postLog(severity == ProblemSeverity::Error ? LogLevel::Error : LogLevel::Warn, line);
      });
  reporter_->setResetCause([this] { return loop_->lastResetCause(); });
}

void SimulatorNode::makeInterfaces() {
  advertise();
  stateNh_.setCallbackQueue(&stateQueue_);
  std::vector<RestObject> rest;
  for (const SceneObject& o : objects_) rest.push_back({o.lattice.get(), o.info.contactRadius});
  colliders_ = std::make_unique<ColliderTopics>(
      pnh_, stateNh_, commandNh_, params_, *loop_, stats_, tfBuffer_, [this] { startTfListener(); },
      [this](const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d& T,
             std::string& why) { return lookupTransform(frame, stamp, T, why); },
      [this](CommandBody body) { send(std::move(body), false); }, rest);
  reconfigureNh_.setCallbackQueue(&reconfigureQueue_);
  reconfigure_ = std::make_unique<Reconfigure>(reconfigureNh_, params_,
                                               [this](const FlsmConfig& c) { return onReconfigure(c); });
  // The single object's handle keeps the name "object"; with ~objects each is named after its
  // object.
  std::vector<InteractiveDrag::Handle> handles;
  for (const SceneObject& o : objects_)
    handles.push_back({namespaced_ ? o.name : std::string("object"), o.lattice.get(), &o.renderMesh});
  mouse_ = std::make_unique<InteractiveDrag>(
      pnh_, params_.frameId, handles,
      [this](std::size_t k, const DragCommand& d) { return onMouseDrag(k, d); });
}

void SimulatorNode::makeSensors() {
  loop_->setFrameSource([this](const std::string& frame, Eigen::Isometry3d& T) {
    return attachedFrame(frame, T);
  });
  // (before the loop starts: a sensor that cannot start leaves no thread running)
  if (!params_.tactile.empty()) tactile_ = std::make_unique<TactileTopics>(pnh_, params_.tactile);
  if (!params_.cameras.empty()) {
    cameras_ = std::make_unique<CameraTopics>(
        pnh_, params_.cameras, params_.frameId, *loop_, objects_, objectsMutex_, tfBuffer_,
        [this] { startTfListener(); },
        [this](const Snapshot& s, ros::Time& stamp) { return sendable(s, stamp); });
  }
}

void SimulatorNode::startThreads() {
  loop_->start();
  if (params_.clock == NodeParams::Clock::Follow) {
    clockSub_ = stateNh_.subscribe("/clock", kClockQueue, &SimulatorNode::onClock, this);
  }
  publishTimer_ = pnh_.createTimer(ros::Duration(1.0 / params_.publishRate),
                                   &SimulatorNode::onPublishTimer, this);
  stateTimer_ = stateNh_.createTimer(ros::Duration(1.0 / params_.publishRate),
                                     &SimulatorNode::onStateTimer, this);
  nameQueueThread(stateQueue_, "flsm_state");
  nameQueueThread(commandQueue_, "flsm_commands");
  nameQueueThread(serviceQueue_, "flsm_services");
  nameQueueThread(reconfigureQueue_, "flsm_reconfig");
  stateSpinner_ = std::make_unique<ros::AsyncSpinner>(1, &stateQueue_);
  stateSpinner_->start();
  commandSpinner_ = std::make_unique<ros::AsyncSpinner>(1, &commandQueue_);
  commandSpinner_->start();
  serviceSpinner_ = std::make_unique<ros::AsyncSpinner>(1, &serviceQueue_);
  serviceSpinner_->start();
  reconfigureSpinner_ = std::make_unique<ros::AsyncSpinner>(1, &reconfigureQueue_);
  reconfigureSpinner_->start();
}

SimulatorNode::~SimulatorNode() {
  cameras_.reset();
  publishTimer_.stop();
  stateTimer_.stop();
  stateSpinner_->stop();
  reconfigureSpinner_->stop();
  loop_->stop();  // answers services still waiting, so the spinner can stop
  commandSpinner_->stop();
  serviceSpinner_->stop();
  mouse_.reset();
}

void SimulatorNode::advertise() {
  // Commands and services on queues and threads of their own (see the class comment).
  commandNh_.setCallbackQueue(&commandQueue_);
  serviceNh_.setCallbackQueue(&serviceQueue_);
  resetSrv_ = serviceNh_.advertiseService("reset", &SimulatorNode::onReset, this);
  pauseSrv_ = serviceNh_.advertiseService("pause", &SimulatorNode::onPause, this);
  unpauseSrv_ = serviceNh_.advertiseService("unpause", &SimulatorNode::onUnpause, this);
  stepSrv_ = serviceNh_.advertiseService("step", &SimulatorNode::onStep, this);
  releaseAllSrv_ = serviceNh_.advertiseService("release_all", &SimulatorNode::onReleaseAll, this);
  // The top-level topics and service address the first object; with ~objects every object has
  // its own under ~objects/<name>/.
  subscribeCommands(0, "", dragSub_, forceSub_, pinBoxSrv_);
  if (!namespaced_) return;
  addObjectSrv_ = serviceNh_.advertiseService("add_object", &SimulatorNode::onAddObject, this);
  removeObjectSrv_ = serviceNh_.advertiseService("remove_object", &SimulatorNode::onRemoveObject, this);
  for (std::size_t k = 0; k < objects_.size(); ++k) {
    ObjectCommands& c = commands_[k];
    subscribeCommands(k, "objects/" + objects_[k].name + "/", c.dragSub, c.forceSub, c.pinBoxSrv);
  }
}

void SimulatorNode::subscribeCommands(std::size_t object, const std::string& prefix,
                                      ros::Subscriber& dragSub, ros::Subscriber& forceSub,
                                      ros::ServiceServer& pinBoxSrv) {
  const std::string dragTopic = "~" + prefix + "drag", forceTopic = "~" + prefix + "force";
  ros::SubscribeOptions drag;
  drag.initByFullCallbackType<const ros::MessageEvent<const DragCommand>&>(
      prefix + "drag", kCommandQueue,
      [this, object, dragTopic](const ros::MessageEvent<const DragCommand>& e) {
        onDrag(object, dragTopic, e);
      });
  drag.callback_queue = &commandQueue_;
  ros::SubscribeOptions force;
  force.initByFullCallbackType<const ros::MessageEvent<const ForceCommand>&>(
      prefix + "force", kCommandQueue,
      [this, object, forceTopic](const ros::MessageEvent<const ForceCommand>& e) {
        onForce(object, forceTopic, e);
      });
  force.callback_queue = &commandQueue_;
  dragSub = commandNh_.subscribe(drag);
  forceSub = commandNh_.subscribe(force);
  pinBoxSrv = serviceNh_.advertiseService<PinBox::Request, PinBox::Response>(
      prefix + "pin_box",
      [this, object](PinBox::Request& req, PinBox::Response& res) { return onPinBox(object, req, res); });
}

// --------------------------------------------------------------------------------------------
// State out

void SimulatorNode::onPublishTimer(const ros::TimerEvent& event) {
  {
    std::lock_guard<std::mutex> lock(paramsMutex_);
    reporter_->publishingTook(event.profile.last_duration.toSec());
  }
  publishNewest();
}

void SimulatorNode::publishNewest() {
  const Snapshot& s = loop_->acquire();
  ros::Time stamp;
  if (!sendable(s, stamp)) return;
  std::shared_lock<std::shared_mutex> lock(objectsMutex_);
  // tf, the wrenches and the clouds of one snapshot carry one stamp: a subscriber pairs a cloud
  // with the colliders' and objects' frames of the same step by it. tf goes once per stamp (a
  // listener warns of a repeat, TF_REPEATED_DATA): a state the timer sends again, when the
  // simulation runs slower than the publish rate, keeps its stamp and sends no tf. With ~clock
  // sim every step sends its tf (onTick).
  // (!=, not >: a followed clock that went back, and the scene with it, sends tf again)
  const bool tfDue = params_.clock != NodeParams::Clock::Sim && stamp != lastTfStamp_;
  if (tfDue) {
    publisher_->publishTf(s, stamp);
    lastTfStamp_ = stamp;
  }
  colliders_->publishFrames(s, stamp, tfDue);
  colliders_->publishMarkers(s, stamp);
  // The handles of objects added or removed since the last tick, then every handle to its
  // object's frame: the snapshot lists the objects in the order they were added, without those
  // removed, as objects_ does with the removed ones marked.
  {
    std::lock_guard<std::mutex> handlesLock(handlesMutex_);
    // erased first: an object removed and one of the same name added within a tick
    for (std::size_t k : handlesToRemove_) mouse_->remove(k);
    for (const auto& [k, handle] : handlesToAdd_) mouse_->add(k, handle);
    handlesToAdd_.clear();
    handlesToRemove_.clear();
  }
  std::size_t next = 0;
  for (const ObjectSnapshot& o : s.objects) {
    std::size_t k = next;
    while (k < objects_.size() && (commands_[k].removed || objects_[k].name != o.name)) ++k;
    if (k == objects_.size()) break;  // added since: its handle comes with the next snapshot
    mouse_->follow(k, o.objectFrame);
    next = k + 1;
  }
  publisher_->publishHeavy(s, stamp);
  if (tactile_) tactile_->publish(s, stamp);
  reporter_->watchContacts(s.wrenches, s.time);
  published_.store(s.sequence);
}

void SimulatorNode::onStateTimer(const ros::TimerEvent&) { publishState(); }

void SimulatorNode::publishState() {
  loop_->copySummary(summary_);
  ros::Time stamp;
  if (!sendable(summary_, stamp)) return;
  {
    std::shared_lock<std::shared_mutex> lock(objectsMutex_);
    publisher_->publishState(summary_, stamp, colliders_->frameMisses());
  }
  std::lock_guard<std::mutex> lock(paramsMutex_);
  reporter_->report(summary_.diag);
}

// --------------------------------------------------------------------------------------------
// Commands in

void SimulatorNode::rejected(const Rejection& why) { stats_->reject(why.reason, why.detail); }

CommandOutcome SimulatorNode::send(CommandBody body, bool wait, const std::string& object) {
  Command command{std::move(body), nullptr, object};
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

CommandOutcome SimulatorNode::sendAndWaitForTheAnswer(CommandBody body) {
  Command command{std::move(body), std::make_shared<std::promise<CommandOutcome>>(), std::string()};
  std::future<CommandOutcome> result = command.outcome->get_future();
  loop_->submit(std::move(command));
  while (result.wait_for(std::chrono::duration<double>(kServiceTimeout)) != std::future_status::ready) {
    if (!ros::ok()) {
      CommandOutcome late;
      late.message = "the node is shutting down";
      return late;
    }
  }
  try {
    return result.get();
  } catch (const std::future_error&) {  // the simulation thread ended without answering
    CommandOutcome late;
    late.message = "the simulation thread ended without answering";
    return late;
  }
}

bool SimulatorNode::startTfListener() {
  std::lock_guard<std::mutex> lock(tfListenerMutex_);
  if (tfListener_) return false;
  // The listener's thread takes the name this thread has when it starts: "flsm_tf", not the
  // name of whichever thread first needed tf.
  char name[16] = {};
  pthread_getname_np(pthread_self(), name, sizeof name);
  pthread_setname_np(pthread_self(), "flsm_tf");
  try {
    tfListener_ = std::make_unique<tf2_ros::TransformListener>(tfBuffer_);
  } catch (...) {
    pthread_setname_np(pthread_self(), name);
    throw;
  }
  pthread_setname_np(pthread_self(), name);
  return true;
}

bool SimulatorNode::attachedFrame(const std::string& frame, Eigen::Isometry3d& simFromFrame) {
  geometry_msgs::TransformStamped t;
  try {
    // The latest transform, no timeout: the simulation thread never waits for tf. (The ATTACH
    // that named the frame started the listener when it looked the frame up.)
    t = tfBuffer_.lookupTransform(params_.frameId, frame, ros::Time(0));
  } catch (const tf2::TransformException& e) {
    static LogThrottle throttle(kAttachWarnPeriod);
    if (throttle.ready())
      postLog(LogLevel::Warn, formatted("flsm_node: frame '%s', which a drag is attached to, is not known "
                                         "now (%s): the drag holds still until it is",
                                         frame.c_str(), e.what()));
    return false;
  }
  const double age = (ros::Time::now() - t.header.stamp).toSec();
  if (!t.header.stamp.isZero() && age > kAttachStaleAfter) {  // a static transform never is
    static LogThrottle throttle(kAttachWarnPeriod);
    if (throttle.ready())
      postLog(LogLevel::Warn, formatted("flsm_node: the newest transform of frame '%s', which a drag is "
                                         "attached to, is %.2f s old: the drag holds still until the "
                                         "frame moves again",
                                         frame.c_str(), age));
    return false;
  }
  // tf accepts quaternions normalised to within 1 %: the drag needs an exact rotation.
  Eigen::Quaterniond q;
  tf2::fromMsg(t.transform.rotation, q);
  if (!(q.norm() > 0.0)) return false;
  q.normalize();
  simFromFrame = Eigen::Translation3d(toEigen(t.transform.translation)) * q;
  return simFromFrame.matrix().allFinite();
}

bool SimulatorNode::lookupTransform(const std::string& frame, const ros::Time& stamp,
                                    Eigen::Isometry3d& T, std::string& why) {
  if (startTfListener()) {
    // Once: let the new listener hear the frames (tf_static at once, tf within a period). A wait
    // in wall time: on simulated time that stands still (paused) tf's own timeout never ends.
    const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(kFirstTransformTimeout);
    while (!tfBuffer_.canTransform(params_.frameId, frame, ros::Time(0)) && ros::WallTime::now() < end)
      ros::WallDuration(kFirstTransformPoll).sleep();
  }
  // Never wait: at the command's stamp if tf has it, else the latest transform (a command
  // stamped a little ahead of the last tf message), else refused. Waiting here would hold up
  // every other client's commands for as long as one client names a frame nobody publishes.
  std::string atStamp;
  ros::Time when = stamp;
  if (stamp.isZero() || !tfBuffer_.canTransform(params_.frameId, frame, stamp, &atStamp)) {
    when = ros::Time(0);
    if (!tfBuffer_.canTransform(params_.frameId, frame, when, &why)) return false;
  }
  try {
    T = tf2::transformToEigen(tfBuffer_.lookupTransform(params_.frameId, frame, when));
    return true;
  } catch (const tf2::TransformException& e) {
    why = e.what();
    return false;
  }
}

void SimulatorNode::onDrag(std::size_t object, const std::string& topic,
                           const ros::MessageEvent<const DragCommand>& event) {
  const DragCommand::ConstPtr& msg = event.getMessage();
  countMissed(gaps_, *stats_, topic, event.getPublisherName(), msg->header.seq);
  std::shared_lock<std::shared_mutex> lock(objectsMutex_);
  const ObjectCommands& c = commands_[object];
  CommandBody body;
  Rejection why;
  if (!c.validator->drag(*msg, body, why)) return rejected(why);
  send(std::move(body), false, objects_[object].name);
}

void SimulatorNode::onForce(std::size_t object, const std::string& topic,
                            const ros::MessageEvent<const ForceCommand>& event) {
  const ForceCommand::ConstPtr& msg = event.getMessage();
  countMissed(gaps_, *stats_, topic, event.getPublisherName(), msg->header.seq);
  std::shared_lock<std::shared_mutex> lock(objectsMutex_);
  const ObjectCommands& c = commands_[object];
  CommandBody body;
  Rejection why;
  if (!c.validator->force(*msg, body, why)) return rejected(why);
  send(std::move(body), false, objects_[object].name);
}

bool SimulatorNode::onMouseDrag(std::size_t object, const DragCommand& drag) {
  std::shared_lock<std::shared_mutex> lock(objectsMutex_);
  if (commands_[object].removed) {
    stats_->reject("unknown_object", "object '" + objects_[object].name +
                                         "' was removed: its RViz handle drags nothing");
    return false;
  }
  CommandBody body;
  Rejection why;
  if (!commands_[object].validator->drag(drag, body, why)) {
    rejected(why);
    return false;
  }
  send(std::move(body), false, objects_[object].name);
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

bool SimulatorNode::onPinBox(std::size_t object, PinBox::Request& req, PinBox::Response& res) {
  const Eigen::Vector3d lo = toEigen(req.min), hi = toEigen(req.max);
  Rejection why;
  std::string name;
  {
    std::shared_lock<std::shared_mutex> lock(objectsMutex_);
    name = objects_[object].name;
    if (!commands_[object].validator->box(lo, hi, why)) {
      rejected(why);
      res.success = false;
      res.message = why.detail;
      return true;
    }
  }
  const CommandOutcome o = send(PinBoxCommand{lo, hi, static_cast<bool>(req.pin)}, true, name);
  res.success = o.accepted;
  res.message = o.message;
  res.particles = static_cast<std::uint32_t>(o.particles);
  res.pinned_total = static_cast<std::uint32_t>(o.pinnedTotal);
  return true;
}

// On reconfigureSpinner_'s thread; params_ is also read by the publish timer's reporter_.
bool SimulatorNode::onReconfigure(const FlsmConfig& config) {
  std::unique_lock<std::mutex> lock(paramsMutex_);
  NodeParams changed = params_;
  if (!Reconfigure::apply(config, changed)) {
    stats_->reject("invalid_params", "material '" + config.material +
                                         "': use 'youngs' or 'classic'; nothing changed");
    return false;
  }
  if (changed.material == NodeParams::Material::Youngs &&
      !(std::isfinite(changed.youngsModulus) && changed.youngsModulus > 0.0)) {
    // dynamic_reconfigure has clamped anything below the range to its minimum, 0.
    stats_->reject("invalid_params",
                   "youngs_modulus " + std::to_string(changed.youngsModulus) +
                       ": it must be > 0 Pa (a value below 0 arrives clamped to 0); the material "
                       "is unchanged. For alpha = stiffness per sub-step, set material classic");
    return false;
  }
  if (config.real_time_factor == 0.0 && params_.clock != NodeParams::Clock::Sim) {
    // dynamic_reconfigure has clamped anything below the range to its minimum, 0.
    stats_->reject("invalid_params", "real_time_factor " + std::to_string(config.real_time_factor) +
                                         ": it must be > 0 (0, as fast as the machine can, only with "
                                         "~clock sim); nothing changed");
    return false;
  }
  // Every object takes the change with its own regions and density: one gravity, one material.
  std::shared_lock<std::shared_mutex> objectsLock(objectsMutex_);
  std::vector<SolverParams> perObject;
  std::vector<std::string> names;
  for (std::size_t k = 0; k < objects_.size(); ++k) {
    if (commands_[k].removed) continue;
    const SceneObject& o = objects_[k];
    names.push_back(o.name);
    SolverParams p = changed.solver;
    p.regionHalfWidth = o.info.regionHalfWidth;
    p.density = o.params.solver.density;
    try {
      p.validate();
    } catch (const std::invalid_argument& e) {
      stats_->reject("invalid_params", std::string(e.what()) + "; nothing changed");
      return false;
    }
    perObject.push_back(p);
  }
  params_.material = changed.material;
  params_.youngsModulus = changed.youngsModulus;
  params_.poissonsRatio = changed.poissonsRatio;
  params_.solver = perObject.front();
  for (std::size_t k = 0; k < names.size(); ++k) send(ParamsCommand{perObject[k]}, false, names[k]);
  const bool newRate = config.publish_rate != params_.publishRate;
  const bool newPace = config.real_time_factor != params_.realTimeFactor;
  params_.publishRate = config.publish_rate;
  params_.realTimeFactor = config.real_time_factor;
  objectsLock.unlock();
  lock.unlock();  // the timer's own lock is not taken under ours
  if (newRate) {
    publishTimer_.setPeriod(ros::Duration(1.0 / config.publish_rate));
    stateTimer_.setPeriod(ros::Duration(1.0 / config.publish_rate));
  }
  if (newPace) loop_->setRealTimeFactor(config.real_time_factor);
  return true;
}

}  // namespace deformable_flsm
