/// @file publish_queue_bound.h
/// How many of a topic's messages are still in roscpp's unbounded publish queue, so that a heavy
/// topic publishes only while that queue holds fewer than a bound and the node's memory stays
/// bounded by its queues' capacities however long roscpp's poll thread waits for a CPU.
#pragma once

#include <ros/forwards.h>

#include <cstdint>
#include <memory>
#include <mutex>

namespace ros {
class Publisher;
}

namespace deformable_flsm {

/// The count behind PublishQueueBound, apart from roscpp so that it can be tested without a
/// master. roscpp numbers a publication's messages (ros::Publication::getSequence()) as they
/// leave the publish queue: Publication::enqueueMessage(), run by the poll thread's
/// TopicManager::processPublishQueues(), increments the sequence once for each message it hands
/// on to the subscribers' outgoing queues; a publish without subscribers increments it at once
/// (TopicManager::publish()). Every message published has therefore left the queue once the
/// sequence has advanced by as many messages as were published, and the difference is what the
/// queue still holds.
class UnsentCount {
 public:
  /// @param[in] sequence  the publication's sequence when counting begins
  explicit UnsentCount(std::uint32_t sequence = 0) : baseline_(sequence) {}

  /// Call before each publish: a message handed on before it was counted would look like
  /// another publisher's and be lost from the count.
  void publishing() { ++published_; }

  /// Messages published but not yet handed on, given the publication's sequence now. The
  /// sequence is 32 bits and wraps; differences are taken modulo 2^32. Should the sequence run
  /// ahead of what was counted (a publisher this count does not see), the count starts again
  /// from there rather than holding the topic shut.
  std::uint32_t unsent(std::uint32_t sequence) {
    const std::uint32_t handedOn = sequence - baseline_;
    if (static_cast<std::int32_t>(handedOn - published_) > 0) baseline_ = sequence - published_;
    return published_ - (sequence - baseline_);
  }

 private:
  std::uint32_t baseline_;        ///< the publication's sequence when published_ was 0
  std::uint32_t published_ = 0;   ///< publishes counted, modulo 2^32
};

/// One advertised topic's messages in roscpp's publish queue, bounded. roscpp's
/// Publisher::publish() serializes a message into the publication's own queue
/// (ros::Publication::publish_queue_), which has no bound; only the poll thread, once per round,
/// moves the queued messages on to the subscribers' outgoing queues, which keep the newest
/// `queue_size`. While the poll thread waits for a CPU every message published stays there: a
/// 5 MB ~mesh at 30 Hz is 150 MB a second of stall. A topic that publishes only while
/// `full()` is false holds at most `capacity` serialized messages in that queue.
///
/// The capacity is counted in publish ticks, not one message: the poll thread is woken by each
/// publish (TopicManager::publish() signals the poll set) but may run a few milliseconds later,
/// and a tick skipped because the last message had not left yet would cost the topic its rate
/// on an idle machine. Two ticks lose no message a subscriber would have received: of the
/// messages one poll round hands on to a subscriber whose outgoing queue holds one
/// (TransportSubscriberLink::enqueueMessage() drops the oldest), at most two reach it, the
/// first (written at once when the link is idle) and the last (left in the queue).
class PublishQueueBound {
 public:
  /// Ticks of messages the publish queue may hold for one topic.
  static constexpr std::uint32_t kTicks = 2;

  /// The bound of `publisher`'s topic, shared by every publisher of that topic in this process
  /// (roscpp keeps one publication, one queue and one sequence per topic): `messagesPerTick`
  /// messages a tick, kTicks ticks. Call after advertising. A later call with more messages a
  /// tick (an object added at run time publishes its marker on `~mesh` too) raises the capacity.
  static std::shared_ptr<PublishQueueBound> of(const ros::Publisher& publisher,
                                               std::uint32_t messagesPerTick);

  /// Messages the queue may hold.
  std::uint32_t capacity() {
    std::lock_guard<std::mutex> lock(mutex_);
    return capacity_;
  }
  /// true while the queue holds `capacity()` messages or more: do not publish now.
  bool full();
  /// Call right before each Publisher::publish() on the topic: counted first, the poll thread
  /// cannot hand the message on before it is counted.
  void publishing();

  PublishQueueBound(ros::PublicationPtr publication, std::uint32_t capacity);

 private:
  ros::PublicationPtr publication_;
  std::uint32_t capacity_;
  std::mutex mutex_;  ///< the topic's publishers may publish from several threads
  UnsentCount count_;
};

}  // namespace deformable_flsm
