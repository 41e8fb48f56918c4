// The gate that keeps a heavy topic to one message in roscpp's unbounded publish queue: a
// message published during a poll-thread round may have missed that round's processing of the
// queues, so it has left them only once the next round has run too.
#include "deformable_flsm/ros/delivery_gate.h"

#include <gtest/gtest.h>

using namespace deformable_flsm;

TEST(DeliveryGate, AMessageHasLeftOnlyAfterARoundThatBeganAfterIt) {
  DeliveryGate gate;
  gate.roundDone();
  const std::uint64_t published = gate.round();
  EXPECT_FALSE(gate.handedOn(published)) << "no round since";
  gate.roundDone();
  EXPECT_FALSE(gate.handedOn(published))
      << "the round under way at publishing may have processed the queues before the message";
  gate.roundDone();
  EXPECT_TRUE(gate.handedOn(published)) << "the next round began after it and processed them";
}

TEST(DeliveryGate, AStalledPollThreadKeepsTheGateShut) {
  DeliveryGate gate;
  const std::uint64_t published = gate.round();
  for (int tick = 0; tick < 1000; ++tick)
    EXPECT_FALSE(gate.handedOn(published)) << "no round, however many publish ticks pass";
  gate.roundDone();
  gate.roundDone();
  EXPECT_TRUE(gate.handedOn(published));
  EXPECT_TRUE(gate.handedOn(published - 1)) << "an older message has left too";
}

TEST(DeliveryGate, APublishAsksForTheRoundsThatHandItOn) {
  int requested = 0;
  const DeliveryGate gate([&requested] { ++requested; });
  gate.published();
  EXPECT_EQ(requested, 1) << "else the second round waits for poll()'s timeout";
}
