// LogQueue: a thread that posts a log line never waits for the write, whatever the sink does.
#include "deformable_flsm/ros/log_queue.h"

#include <gtest/gtest.h>

#include <chrono>
#include <future>
#include <mutex>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

/// A sink that records its lines and can be held (as a disk that stalls holds a write).
struct HeldSink {
  std::mutex mutex;
  std::vector<std::string> lines;
  std::promise<void> entered, release;
  std::shared_future<void> released = release.get_future().share();
  bool hold = false;
  bool first = true;

  void operator()(LogLevel, const std::string& line) {
    bool wait = false;
    {
      std::lock_guard<std::mutex> lock(mutex);
      lines.push_back(line);
      if (hold && first) {
        first = false;
        wait = true;
      }
    }
    if (wait) {
      entered.set_value();
      released.wait();
    }
  }
};

}  // namespace

TEST(LogQueue, WritesEveryLineInOrderAndDrainsWhenDestroyed) {
  HeldSink sink;
  {
    LogQueue q([&](LogLevel l, const std::string& s) { sink(l, s); }, 8);
    for (int k = 0; k < 5; ++k) EXPECT_TRUE(q.post(LogLevel::Warn, "line " + std::to_string(k)));
  }
  ASSERT_EQ(sink.lines.size(), 5u);
  for (int k = 0; k < 5; ++k) EXPECT_EQ(sink.lines[k], "line " + std::to_string(k));
}

TEST(LogQueue, PostingNeverWaitsForAHeldSinkAndCountsWhatItDrops) {
  HeldSink sink;
  sink.hold = true;
  const std::size_t capacity = 16, extra = 10;
  {
    LogQueue q([&](LogLevel l, const std::string& s) { sink(l, s); }, capacity);
    q.post(LogLevel::Warn, "held");
    sink.entered.get_future().wait();  // the sink now holds the queue's thread
    // Posting while the sink is held: a post that waited would hang here, so it runs apart and
    // the test fails instead if it has not returned long after it should.
    auto posting = std::async(std::launch::async, [&] {
      std::size_t accepted = 0;
      for (std::size_t k = 0; k < capacity + extra; ++k)
        accepted += q.post(LogLevel::Warn, "after " + std::to_string(k)) ? 1 : 0;
      return accepted;
    });
    const bool returned = posting.wait_for(std::chrono::seconds(30)) == std::future_status::ready;
    sink.release.set_value();  // before any check: a failed one then ends the test, not hangs it
    ASSERT_TRUE(returned) << "post() waited for the held sink";
    EXPECT_EQ(posting.get(), capacity);
    EXPECT_EQ(q.dropped(), extra);
  }
  // the held line, the count of the dropped ones, then the queued lines in order
  ASSERT_EQ(sink.lines.size(), 2 + capacity);
  EXPECT_EQ(sink.lines[0], "held");
  EXPECT_EQ(sink.lines[1], "flsm_node: " + std::to_string(extra) + " log line(s) dropped while the log was held up");
  for (std::size_t k = 0; k < capacity; ++k) EXPECT_EQ(sink.lines[2 + k], "after " + std::to_string(k));
}

TEST(LogQueue, RefusesNoSinkOrNoCapacity) {
  EXPECT_THROW(LogQueue(LogQueue::Sink(), 4), std::invalid_argument);
  EXPECT_THROW(LogQueue([](LogLevel, const std::string&) {}, 0), std::invalid_argument);
}

TEST(LogThrottle, OnceAPeriod) {
  LogThrottle hour(3600.0);
  EXPECT_TRUE(hour.ready());
  EXPECT_FALSE(hour.ready());
  EXPECT_FALSE(hour.ready());
  LogThrottle none(0.0);
  EXPECT_TRUE(none.ready());
  EXPECT_TRUE(none.ready());
}
