/// @file delivery_gate.h
/// Whether a message published earlier has left roscpp's unbounded publish queue, so that a
/// heavy topic publishes its next message only then and the node's memory stays bounded by its
/// subscribers' queues however long its threads wait for a CPU.
#pragma once

#include <atomic>
#include <cstdint>
#include <functional>
#include <utility>

namespace deformable_flsm {

/// roscpp's Publisher::publish() serializes the message and appends it to the publication's own
/// queue (ros::Publication::publish_queue_), which has no bound; only the poll thread, once per
/// round (ros::PollManager::threadFunc(): TopicManager::processPublishQueues(), then the other
/// poll-thread listeners, then poll() for at most 100 ms), moves the queued messages into the
/// subscribers' outgoing queues, which keep the newest `queue_size` (the advertised size). When
/// the poll thread waits for a CPU (a busy machine; the kernel's autogroup scheduling gives the
/// node's threads one session's share), every publish until it runs again stays in that queue:
/// a 5 MB ~mesh at 30 Hz is 150 MB a second of stall. A heavy topic therefore publishes its next
/// message only once its last one has been handed on: once two rounds have begun after it was
/// published (the round under way when it was published may have processed the queues before
/// the message entered them; the next one begins after it and processes them).
class DeliveryGate {
 public:
  /// @param[in] requestRound  makes the poll thread begin another round soon (empty: nothing)
  explicit DeliveryGate(std::function<void()> requestRound = {})
      : requestRound_(std::move(requestRound)) {}

  /// The number of poll-thread rounds so far; a publish stamps itself with it (published()).
  std::uint64_t round() const { return rounds_.load(std::memory_order_acquire); }

  /// Call once per poll-thread round, after roscpp has processed its publish queues.
  void roundDone() { rounds_.fetch_add(1, std::memory_order_acq_rel); }

  /// true when a message published at round() == `publishedAt` has left the publish queue.
  bool handedOn(std::uint64_t publishedAt) const { return round() >= publishedAt + kRoundsAfter; }

  /// After a publish: roscpp wakes the poll thread for the round that hands the message on, but
  /// the gate needs the round after it too, which would otherwise wait for the next socket event
  /// or poll()'s 100 ms timeout, longer than a publish period.
  void published() const {
    if (requestRound_) requestRound_();
  }

  /// The gate of this process's roscpp poll thread: registers roundDone() as a poll-thread
  /// listener on first use (after ros::start(), so that it runs after roscpp's own listener,
  /// which processes the publish queues). Never destroyed: the poll thread may call it until the
  /// process ends.
  static DeliveryGate& pollThread();

 private:
  /// Rounds that must have begun after a publish: the one under way may have processed the
  /// queues before the message entered them.
  static constexpr std::uint64_t kRoundsAfter = 2;
  std::function<void()> requestRound_;
  std::atomic<std::uint64_t> rounds_{0};
};

}  // namespace deformable_flsm
