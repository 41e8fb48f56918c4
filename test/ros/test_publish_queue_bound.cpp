// The count that bounds a heavy topic's messages in roscpp's publish queue: a message counts as
// unsent until roscpp's sequence of the publication has passed it (the poll thread handed it on,
// or it was published without subscribers), whatever the order of ticks and poll rounds.
#include "deformable_flsm/ros/publish_queue_bound.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>

using namespace deformable_flsm;

TEST(UnsentCount, AMessageIsUnsentUntilTheSequencePassesIt) {
  const std::uint32_t start = 41;  // the publication may have sent messages before counting
  UnsentCount count(start);
  EXPECT_EQ(count.unsent(start), 0u);
  count.publishing();
  count.publishing();
  EXPECT_EQ(count.unsent(start), 2u) << "the poll thread has not run: both still queued";
  EXPECT_EQ(count.unsent(start + 1), 1u) << "the first handed on";
  EXPECT_EQ(count.unsent(start + 2), 0u) << "both handed on";
}

TEST(UnsentCount, AStalledPollThreadKeepsEveryPublishCounted) {
  UnsentCount count(0);
  for (std::uint32_t tick = 1; tick <= 1000; ++tick) {
    count.publishing();
    EXPECT_EQ(count.unsent(0), tick) << "no message leaves while the poll thread waits";
  }
  EXPECT_EQ(count.unsent(1000), 0u) << "one round hands them all on";
}

TEST(UnsentCount, TheSequenceWrapsAround) {
  const std::uint32_t start = std::numeric_limits<std::uint32_t>::max() - 1;
  UnsentCount count(start);
  for (int i = 0; i < 4; ++i) count.publishing();
  EXPECT_EQ(count.unsent(start), 4u);
  EXPECT_EQ(count.unsent(start + 3), 1u) << "the sequence wrapped past 2^32 - 1 to 1";
  EXPECT_EQ(count.unsent(start + 4), 0u);
}

TEST(UnsentCount, AnotherPublisherNeverHoldsTheTopicShut) {
  // Messages this count did not see (another publisher of the topic in the process) advance
  // the sequence too; the count must not read them as its own sent, nor wrap to 2^32 unsent.
  UnsentCount count(0);
  count.publishing();
  EXPECT_EQ(count.unsent(5), 0u) << "four foreign messages and ours handed on";
  count.publishing();
  EXPECT_EQ(count.unsent(5), 1u) << "ours after them is still queued";
  EXPECT_EQ(count.unsent(6), 0u);
}
