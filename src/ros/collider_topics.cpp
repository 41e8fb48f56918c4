#include "deformable_flsm/ros/collider_topics.h"

#include "deformable_flsm/ros/log_queue.h"
#include "deformable_flsm/ros/robot_colliders.h"

#include <ros/console.h>

#include <algorithm>
#include <sstream>
#include <utility>

namespace deformable_flsm {

namespace {

/// Incoming ~collider commands between two drains of the command thread.
constexpr std::uint32_t kCommandQueue = 100;
/// The ground is drawn as a square this many object sizes wide.
constexpr double kPlaneSizePerObject = 4.0;
/// s between two warnings about followed frames.
constexpr double kFrameWarnPeriod = 5.0;
/// Names listed in one log line before "and N more".
constexpr std::size_t kNamesPerLine = 8;

std::string list(const std::vector<std::string>& items) {
  std::ostringstream out;
  for (std::size_t i = 0; i < items.size() && i < kNamesPerLine; ++i) out << (i ? ", " : "") << items[i];
  if (items.size() > kNamesPerLine) out << ", and " << items.size() - kNamesPerLine << " more";
  return out.str();
}

double largestObjectSize(const std::vector<RestObject>& objects) {
  double size = 0.0;
  for (const RestObject& o : objects) size = std::max(size, o.lattice->objectSize());
  return size;
}

}  // namespace

ColliderTopics::ColliderTopics(ros::NodeHandle& pnh, ros::NodeHandle& stateNh,
                               ros::NodeHandle& commandNh, const NodeParams& params, SimulationLoop& loop,
                               std::shared_ptr<CommandStats> stats,
                               const tf2_ros::Buffer& tfBuffer,
                               std::function<void()> startTfListener,
                               CommandValidator::TransformLookup lookup, Send send,
                               const std::vector<RestObject>& objects)
    : simFrame_(params.frameId), loop_(loop), stats_(std::move(stats)),
      startTfListener_(std::move(startTfListener)),
      validator_(params.frameId, std::move(lookup)), send_(std::move(send)),
      planeSize_(kPlaneSizePerObject * largestObjectSize(objects)),
      republishAtRest_(params.republishAtRest),
      follower_(tfBuffer, params.frameId) {
  for (const ColliderSpec& spec : params.colliders) {
    if (spec.followFrame.empty()) continue;
    loop_.addFollowedCollider(spec.id, spec.collider);
    follower_.follow(spec.id, spec.followFrame, spec.collider.pose);
  }
  addRobot(params.robot, objects);
  // From start-up, so that the frames are known by the first samples.
  if (!follower_.empty()) startTfListener_();

  markers_.advertise<visualization_msgs::MarkerArray>(pnh, "colliders");
  wrenchPub_ = pnh.advertise<ContactWrenches>("contact_wrenches", 1);
  commandSub_ = commandNh.subscribe("collider", kCommandQueue, &ColliderTopics::onCommand, this);
  // Followed frames are sampled once per simulation step; the timer runs from the first
  // followed collider on (a node without any does not wake for it). On simulated time (~clock
  // sim or follow) a timer's period is simulated time already.
  const double period = params.clock == NodeParams::Clock::Wall
                            ? params.solver.timeStep / params.realTimeFactor
                            : params.solver.timeStep;
  followTimer_ = stateNh.createTimer(ros::Duration(period), &ColliderTopics::onFollowTimer, this,
                                     false, !follower_.empty());
}

void ColliderTopics::addRobot(const RobotColliders& robot, const std::vector<RestObject>& objects) {
  if (robot.options.descriptionParam.empty()) return;
  std::vector<std::string> links;
  for (const RobotCollider& rc : robot.colliders) {
    const ColliderSpec& spec = rc.spec;
    loop_.addFollowedCollider(spec.id, spec.collider);
    ColliderFollower::Admit admit;
    if (robot.options.excludeOverlapping) {
      // The lattices are immutable and outlive the node's parts. A link inside any object
      // stays out: the object was placed on or around it.
      const ColliderShape shape = spec.collider.shape;
      admit = [objects, shape](const Eigen::Isometry3d& pose) {
        for (const RestObject& o : objects)
          if (overlapsParticles(shape, pose, o.lattice->restPositions(), o.contactRadius))
            return false;
        return true;
      };
    }
    follower_.follow(spec.id, spec.followFrame, spec.collider.pose, admit);
    robotLinks_[spec.id] = WrenchGroup{robotLinkWrenchId(rc.link), rc.link, spec.collider.pose};
    if (links.empty() || links.back() != rc.link) links.push_back(rc.link);
  }
  std::ostringstream names;
  for (std::size_t i = 0; i < links.size(); ++i) names << (i ? ", " : "") << links[i];
  ROS_INFO("flsm_node: robot '%s' from '%s': %zu colliders on %zu links (%s), each following its "
           "link's tf frame%s",
           robot.robotName.c_str(), robot.options.descriptionParam.c_str(), robot.colliders.size(),
           links.size(), names.str().c_str(),
           robot.options.excludeOverlapping ? "; links that start inside the object are left out"
                                            : "");
  for (const std::string& w : robot.warnings) ROS_WARN("flsm_node: %s", w.c_str());
}

void ColliderTopics::onCommand(const ros::MessageEvent<const ColliderCommand>& event) {
  const ColliderCommand::ConstPtr& msg = event.getMessage();
  countMissed(gaps_, *stats_, "~collider", event.getPublisherName(), msg->header.seq);
  CommandBody body;
  Rejection why;
  if (!validator_.check(*msg, body, why)) {
    stats_->reject(why.reason, why.detail);
    return;
  }
  // The follower learns of the change before the simulation does: a stray motion for an id
  // the simulation does not follow (yet, or any more) is ignored there.
  if (const auto* add = std::get_if<SetColliderCommand>(&body)) {
    if (add->followFrame.empty()) {
      follower_.forget(add->id);
    } else {
      startTfListener_();
      follower_.follow(add->id, add->followFrame, add->collider.pose);
      followTimer_.start();  // no-op when running
    }
  } else if (const auto* remove = std::get_if<RemoveColliderCommand>(&body)) {
    follower_.forget(remove->id);
  }
  send_(std::move(body));
}

void ColliderTopics::onFollowTimer(const ros::TimerEvent&) {
  if (follower_.empty()) return;
  report_.clear();
  follower_.sample(
      ros::Time::now(),
      [this](const std::string& id, const ColliderMotion& m) { loop_.setColliderMotion(id, m); },
      report_);
  if (!report_.waiting.empty()) {
    std::map<std::string, int> frames;  // frame -> colliders waiting for it
    for (const auto& w : report_.waiting) ++frames[w.second];
    std::vector<std::string> items;
    for (const auto& f : frames) items.push_back("'" + f.first + "' (" + std::to_string(f.second) + ")");
    postLog(LogLevel::Info, formatted("flsm_node: %zu collider(s) wait for their tf frames %s: each joins "
                                      "the simulation at its frame's first transform",
                                      report_.waiting.size(), list(items).c_str()));
  }
  if (!report_.excluded.empty()) {
    std::vector<std::string> links;
    for (const std::string& id : report_.excluded) {
      const auto g = robotLinks_.find(id);
      links.push_back(g == robotLinks_.end() ? id : "'" + g->second.frame + "' (" + id + ")");
      send_(RemoveColliderCommand{id});
    }
    postLog(LogLevel::Warn, "flsm_node: robot links left out because they start inside the object: " +
                                list(links) +
                                " (set ~robot_exclude_overlapping false to keep them, or move the object)");
  }
  if (!report_.jumped.empty()) {
    static LogThrottle throttle(kFrameWarnPeriod);
    if (throttle.ready())
      postLog(LogLevel::Warn,
              formatted("flsm_node: the tf frame of collider(s) %s jumped (faster than %.0f m/s "
                         "between two transforms): placed at the new pose at rest rather than swept "
                         "through the scene",
                         list(report_.jumped).c_str(), ColliderFollower::kJumpSpeed));
  }
  if (!report_.problems.empty()) {
    static LogThrottle throttle(kFrameWarnPeriod);
    if (throttle.ready())
      postLog(LogLevel::Warn, formatted("flsm_node: %s (%zu collider(s) affected; %llu misses so far, "
                                         "see ~state collider_frame_misses)",
                                         report_.problems.front().c_str(), report_.problems.size(),
                                         static_cast<unsigned long long>(follower_.misses())));
  }
}

void ColliderTopics::publishFrames(const Snapshot& s, const ros::Time& stamp, bool withTf) {
  fillContactWrenches(s.colliders, s.wrenches, robotLinks_, stamp, wrenches_);
  appendObjectWrenches(s.objectWrenches, simFrame_, stamp, wrenches_);
  appendDragWrenches(s.objects, simFrame_, stamp, wrenches_);
  wrenches_.header.frame_id = simFrame_;
  wrenchPub_.publish(wrenches_);
  if (withTf && !s.colliders.empty()) {
    colliderTransforms(s.colliders, simFrame_, stamp, transforms_);
    tfBroadcaster_.sendTransform(transforms_);
  }
}

void ColliderTopics::publishMarkers(const Snapshot& s, const ros::Time& stamp) {
  if (markers_.due(s, republishAtRest_)) {
    markers_.publish(s, stamp, markerArray_, [&](visualization_msgs::MarkerArray& m) {
      fillColliderMarkers(s.colliders, simFrame_, planeSize_, stamp, m);
    });
  }
}

}  // namespace deformable_flsm
