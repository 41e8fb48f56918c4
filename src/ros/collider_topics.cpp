#include "deformable_flsm/ros/collider_topics.h"

#include "deformable_flsm/ros/collider_messages.h"

#include <ros/console.h>

#include <utility>

namespace deformable_flsm {

namespace {

/// Incoming ~collider commands between two drains of the command thread.
constexpr std::uint32_t kCommandQueue = 100;
/// The ground is drawn as a square this many object sizes wide.
constexpr double kPlaneSizePerObject = 4.0;
/// s between two warnings about followed frames.
constexpr double kFrameWarnPeriod = 5.0;

}  // namespace

ColliderTopics::ColliderTopics(ros::NodeHandle& pnh, ros::NodeHandle& commandNh,
                               const NodeParams& params, SimulationLoop& loop,
                               std::shared_ptr<CommandStats> stats,
                               const tf2_ros::Buffer& tfBuffer,
                               std::function<void()> startTfListener,
                               CommandValidator::TransformLookup lookup, Send send,
                               double objectSize)
    : simFrame_(params.frameId), loop_(loop), stats_(std::move(stats)),
      startTfListener_(std::move(startTfListener)),
      validator_(params.frameId, std::move(lookup)), send_(std::move(send)),
      planeSize_(kPlaneSizePerObject * objectSize), republishAtRest_(params.republishAtRest),
      follower_(tfBuffer, params.frameId) {
  for (const ColliderSpec& spec : params.colliders) {
    if (spec.followFrame.empty()) continue;
    loop_.addFollowedCollider(spec.id, spec.collider);
    follower_.follow(spec.id, spec.followFrame, spec.collider.pose);
  }
  if (!follower_.empty()) startTfListener_();

  markers_.advertise<visualization_msgs::MarkerArray>(pnh, "colliders");
  wrenchPub_ = pnh.advertise<ContactWrenches>("contact_wrenches", 1);
  commandSub_ = commandNh.subscribe("collider", kCommandQueue, &ColliderTopics::onCommand, this);
  // Followed frames are sampled once per simulation step; the timer runs from the first
  // followed collider on (a node without any does not wake for it).
  followTimer_ = pnh.createTimer(
      ros::Duration(params.solver.timeStep / params.realTimeFactor), &ColliderTopics::onFollowTimer,
      this, false, !follower_.empty());
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
  problems_.clear();
  follower_.sample(
      ros::Time::now(),
      [this](const std::string& id, const ColliderMotion& m) { loop_.setColliderMotion(id, m); },
      problems_);
  if (!problems_.empty()) {
    ROS_WARN_THROTTLE(kFrameWarnPeriod, "flsm_node: %s (%zu collider(s) affected; %llu misses so "
                      "far, see ~state collider_frame_misses)",
                      problems_.front().c_str(), problems_.size(),
                      static_cast<unsigned long long>(follower_.misses()));
  }
}

void ColliderTopics::publish(const Snapshot& s, const ros::Time& stamp) {
  fillContactWrenches(s.colliders, s.wrenches, stamp, wrenches_);
  wrenches_.header.frame_id = simFrame_;
  wrenchPub_.publish(wrenches_);
  if (!s.colliders.empty()) {
    colliderTransforms(s.colliders, simFrame_, stamp, transforms_);
    tfBroadcaster_.sendTransform(transforms_);
  }
  if (markers_.due(s, republishAtRest_)) {
    markers_.publish(s, stamp, markerArray_, [&](visualization_msgs::MarkerArray& m) {
      fillColliderMarkers(s.colliders, simFrame_, planeSize_, stamp, m);
    });
  }
}

}  // namespace deformable_flsm
