/// @file simulator_node_time.cpp
/// SimulatorNode: its clock (wall, served or followed), the stamps of its states, pause and step.
#include "deformable_flsm/ros/simulator_node.h"

#include "simulator_node_internal.h"

#include <ros/console.h>
#include <ros/wall_timer.h>
#include <tf2_eigen/tf2_eigen.h>

#include <chrono>
#include <cstdint>

namespace deformable_flsm {

namespace {

/// A one-shot wall timer's delay for "on the main thread, now" (s).
constexpr double kPublishAtOnce = 1e-4;

ros::Time rosTime(std::chrono::system_clock::time_point t) {
  ros::Time out;
  out.fromNSec(static_cast<std::uint64_t>(
      std::chrono::duration_cast<std::chrono::nanoseconds>(t.time_since_epoch()).count()));
  return out;
}

}  // namespace

// --------------------------------------------------------------------------------------------
// Time

void SimulatorNode::checkClock() const {
  const bool simTime = ros::Time::isSimTime();
  if (params_.clock == NodeParams::Clock::Wall && simTime) {
    throw ParamError("/use_sim_time is true but ~clock is 'wall': the node would stamp its "
                     "messages with the wall clock among nodes on simulated time. Set ~clock to "
                     "'sim' (this node serves /clock) or 'follow' (another node serves /clock, "
                     "e.g. Gazebo or rosbag play --clock)");
  }
  if (params_.clock != NodeParams::Clock::Wall && !simTime) {
    throw ParamError(std::string("~clock is '") + toString(params_.clock) +
                     "' but /use_sim_time is not true: set it before any node starts "
                     "(roslaunch deformable_flsm flsm.launch sim_time:=true, or <param "
                     "name=\"/use_sim_time\" value=\"true\"/> first in your launch file), or "
                     "set ~clock to 'wall'");
  }
}

ros::Time SimulatorNode::stampOf(const Snapshot& s) const {
  if (params_.clock == NodeParams::Clock::Wall) {
    // at rest or paused the state holds on: it is the state now
    return s.diag.idle || s.diag.paused ? ros::Time::now() : rosTime(s.wallTime);
  }
  return ros::Time(s.diag.idle && !s.diag.paused ? loop_->clockTime() : s.time);
}

bool SimulatorNode::aheadOfTheClock(const ros::Time& stamp) const {
  return params_.clock == NodeParams::Clock::Follow && stamp > ros::Time::now();
}

bool SimulatorNode::sendable(const Snapshot& s, ros::Time& stamp) const {
  stamp = stampOf(s);
  return s.timeStarted && !aheadOfTheClock(stamp);
}

void SimulatorNode::onTick(double time, const Snapshot* state) {
  const ros::Time stamp(time);
  if (state != nullptr) {
    colliderTransforms(state->colliders, params_.frameId, stamp, tickTransforms_);
    for (const ObjectSnapshot& o : state->objects) {
      geometry_msgs::TransformStamped t = tf2::eigenToTransform(o.objectFrame);
      t.header.frame_id = params_.frameId;
      t.child_frame_id = o.name;
      tickTransforms_.push_back(t);
    }
  }
  for (geometry_msgs::TransformStamped& t : tickTransforms_) t.header.stamp = stamp;
  // the state's tf first, then the time: a listener that looks a frame up at ros::Time::now()
  // finds it
  tickBroadcaster_.sendTransform(tickTransforms_);
  rosgraph_msgs::Clock clock;
  clock.clock = stamp;
  clockPub_.publish(clock);
}

void SimulatorNode::onClock(const rosgraph_msgs::Clock::ConstPtr& clock) {
  loop_->followTime(clock->clock.toSec());
}

bool SimulatorNode::onPause(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  const CommandOutcome o = send(PauseCommand{true}, true);
  if (!o.accepted) postLog(LogLevel::Warn, "flsm_node: ~pause: " + o.message);
  // ~state says so at once: on simulated time that stands still its timer would not
  pauseState_ = stateNh_.createWallTimer(
      ros::WallDuration(kPublishAtOnce), [this](const ros::WallTimerEvent&) { publishState(); }, true);
  return o.accepted;
}

bool SimulatorNode::onUnpause(std_srvs::Empty::Request&, std_srvs::Empty::Response&) {
  const CommandOutcome o = send(PauseCommand{false}, true);
  if (!o.accepted) postLog(LogLevel::Warn, "flsm_node: ~unpause: " + o.message);
  return o.accepted;
}

bool SimulatorNode::onStep(Step::Request& req, Step::Response& res) {
  // However many steps it takes: the answer says they are done.
  const CommandOutcome o = sendAndWaitForTheAnswer(StepCommand{req.steps});
  res.success = o.accepted;
  res.message = o.message;
  res.time = loop_->clockTime();
  if (!o.accepted) return true;
  // The state the steps reached goes out before the answer: the publish timer's next tick may
  // lie beyond it, and a paused time would never bring it. On the main thread, as every tick.
  Snapshot reached;
  loop_->copySummary(reached);
  stepPublish_ = pnh_.createWallTimer(
      ros::WallDuration(kPublishAtOnce), [this](const ros::WallTimerEvent&) { publishNewest(); }, true);
  const ros::WallTime end = ros::WallTime::now() + ros::WallDuration(kServiceTimeout);
  while (published_.load() < reached.sequence && ros::WallTime::now() < end && ros::ok())
    ros::WallDuration(kFirstTransformPoll).sleep();
  return true;
}

}  // namespace deformable_flsm
