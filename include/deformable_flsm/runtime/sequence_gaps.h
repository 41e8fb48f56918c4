/// @file sequence_gaps.h
/// Command messages that never reached the node, counted from the gaps in their header.seq.
#pragma once

#include "deformable_flsm/runtime/commands.h"

#include <cstdint>
#include <mutex>
#include <string>
#include <unordered_map>

namespace deformable_flsm {

/// roscpp and rospy number the messages each publisher sends on a topic 1, 2, 3, ... in
/// header.seq, and a full queue drops messages without a word: the subscriber's (roscpp keeps
/// the newest `queue_size` while the callback thread is held up) or the publisher's own (rospy's
/// `queue_size`). A gap in a publisher's numbers is what was lost between them.
class SequenceGaps {
 public:
  /// The messages missing before the one numbered `seq` from `publisher` (topic and node name):
  /// seq - last - 1. 0 for the first message heard from it (what it sent before this subscriber
  /// connected was not meant for it) and when seq does not follow the last one (a publisher that
  /// started again numbers from the start).
  std::uint64_t missed(const std::string& publisher, std::uint32_t seq) {
    std::lock_guard<std::mutex> lock(mutex_);
    auto it = last_.find(publisher);
    if (it == last_.end()) {
      last_.emplace(publisher, seq);
      return 0;
    }
    const std::uint32_t last = it->second;
    it->second = seq;
    return seq > last ? seq - last - 1 : 0;
  }

 private:
  std::mutex mutex_;
  std::unordered_map<std::string, std::uint32_t> last_;
};

/// Counts the messages `gaps` finds missing before this one as rejected for "queue_overflow".
inline void countMissed(SequenceGaps& gaps, CommandStats& stats, const std::string& topic,
                        const std::string& publisher, std::uint32_t seq) {
  const std::uint64_t missed = gaps.missed(topic + " " + publisher, seq);
  if (missed == 0) return;
  stats.reject("queue_overflow",
               std::to_string(missed) + " message(s) on " + topic + " from " + publisher +
                   " never arrived (numbers before " + std::to_string(seq) +
                   " missing): a full queue dropped them, this node's subscriber queue or the "
                   "publisher's own; send fewer",
               missed);
}

}  // namespace deformable_flsm
