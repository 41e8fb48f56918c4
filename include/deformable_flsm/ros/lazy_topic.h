/// @file lazy_topic.h
/// A heavy topic that costs nothing while nobody listens: its message is built only while
/// subscribed and once per simulation state; at rest it is either resent at the rate (the cached
/// message with a new stamp) or sent once and then only to a new subscriber. It never has more
/// than PublishQueueBound::kTicks ticks of messages in roscpp's unbounded publish queue.
#pragma once

#include "deformable_flsm/ros/log_queue.h"
#include "deformable_flsm/ros/publish_queue_bound.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include <ros/advertise_options.h>
#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <ros/single_subscriber_publisher.h>
#include <ros/time.h>
#include <visualization_msgs/MarkerArray.h>

#include <atomic>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>

namespace deformable_flsm {

class LazyTopic {
 public:
  LazyTopic() = default;
  LazyTopic(const LazyTopic&) = delete;  // the connect callback holds `this`
  LazyTopic& operator=(const LazyTopic&) = delete;

  /// Advertises `name` (queue `queue`, 1 unless several publishers share the topic; not
  /// latched: a new subscriber is served by the connect callback with a fresh stamp) on `nh`.
  template <typename Msg>
  void advertise(ros::NodeHandle& nh, const std::string& name, std::uint32_t queue = 1) {
    ros::AdvertiseOptions options;
    options.template init<Msg>(name, queue, [this](const ros::SingleSubscriberPublisher&) { newSubscriber_ = true; });
    options.latch = false;
    pub_ = nh.advertise(options);
    queueBound_ = PublishQueueBound::of(pub_, queue);
  }

  /// true when the topic has subscribers and snapshot `s` should be sent now; false leaves it
  /// alone. While the simulation runs: every tick. At rest: the final state once, then only to
  /// new subscribers (what they missed); the others already show it. `republishAtRest` keeps the
  /// stream steady instead (the cached message goes out again with a new stamp). Never while
  /// roscpp's publish queue is full (PublishQueueBound): the tick is skipped, and the next one
  /// sends the newest state.
  bool due(const Snapshot& s, bool republishAtRest) {
    return due(s.sequence, s.diag.idle, republishAtRest);
  }
  /// The same for a state numbered `sequence` (equal sequence = identical content) that is at
  /// rest when `resting` (one object of several: ObjectSnapshot::version).
  bool due(std::uint64_t sequence, bool resting, bool republishAtRest) {
    if (pub_.getNumSubscribers() == 0) return false;
    const bool wanted =
        !resting || republishAtRest || publishedSequence_ != sequence || newSubscriber_.load();
    if (!wanted) return false;
    if (queueBound_->full()) {
      ++skippedTicks_;
      static LogThrottle throttle(kSkipWarnPeriod);  // one for every heavy topic, as before
      if (throttle.ready())  // through the log's own thread: this one publishes
        postLog(LogLevel::Warn,
                formatted("flsm_node: %s skipped a publish tick (%llu so far): roscpp's publish "
                          "queue still holds %u of its messages, because roscpp's poll thread "
                          "waits for a CPU (a busy machine); the next tick sends the newest state",
                          pub_.getTopic().c_str(), static_cast<unsigned long long>(skippedTicks_),
                          queueBound_->capacity()));
      return false;
    }
    newSubscriber_ = false;  // the publish that follows reaches the new subscriber too
    return true;
  }

  /// Whether the cached message shows another snapshot than `s` (build() would run).
  bool stale(const Snapshot& s) const { return stale(s.sequence); }
  bool stale(std::uint64_t sequence) const { return builtSequence_ != sequence; }

  /// Publishes `msg` for snapshot `s`, stamped `stamp`: build(msg) first when the cached message
  /// shows another snapshot.
  template <typename Msg, typename Build>
  void publish(const Snapshot& s, const ros::Time& stamp, Msg& msg, Build&& build) {
    publish(s.sequence, stamp, msg, std::forward<Build>(build));
  }
  template <typename Msg, typename Build>
  void publish(std::uint64_t sequence, const ros::Time& stamp, Msg& msg, Build&& build) {
    if (builtSequence_ != sequence) {
      build(msg);
      builtSequence_ = sequence;
    }
    setStamp(msg, stamp);
    queueBound_->publishing();
    pub_.publish(msg);
    publishedSequence_ = sequence;
  }

 private:
  template <typename Msg>
  static void setStamp(Msg& msg, const ros::Time& stamp) {
    msg.header.stamp = stamp;
  }
  static void setStamp(visualization_msgs::MarkerArray& msg, const ros::Time& stamp) {
    for (auto& m : msg.markers) m.header.stamp = stamp;
  }
  /// s between two warnings of skipped ticks (one throttle for every heavy topic: the warning
  /// names the topic and its count)
  static constexpr double kSkipWarnPeriod = 10.0;

  ros::Publisher pub_;
  std::uint64_t builtSequence_ = 0;      ///< snapshot the cached message shows
  std::uint64_t publishedSequence_ = 0;  ///< snapshot last published
  std::atomic<bool> newSubscriber_{false};
  std::shared_ptr<PublishQueueBound> queueBound_;  ///< shared by the topic's publishers
  std::uint64_t skippedTicks_ = 0;  ///< ticks skipped while the publish queue was full
};

}  // namespace deformable_flsm
