// Messages lost before they reached the node, counted from the gaps in each publisher's
// header.seq: what the soak's accounting relies on (every message sent is counted as accepted,
// refused, or lost with the reason queue_overflow).
#include "deformable_flsm/runtime/sequence_gaps.h"

#include <gtest/gtest.h>

using namespace deformable_flsm;

TEST(SequenceGaps, CountsTheNumbersMissingBetweenTwoMessagesOfAPublisher) {
  SequenceGaps gaps;
  EXPECT_EQ(gaps.missed("~drag /client", 7), 0u) << "what came before the first message heard was not for us";
  EXPECT_EQ(gaps.missed("~drag /client", 8), 0u);
  EXPECT_EQ(gaps.missed("~drag /client", 12), 3u) << "9, 10 and 11 never arrived";
  EXPECT_EQ(gaps.missed("~drag /client", 13), 0u);
}

TEST(SequenceGaps, PublishersAreCountedApart) {
  SequenceGaps gaps;
  gaps.missed("~drag /a", 1);
  gaps.missed("~drag /b", 100);
  EXPECT_EQ(gaps.missed("~drag /a", 2), 0u);
  EXPECT_EQ(gaps.missed("~drag /b", 105), 4u);
  EXPECT_EQ(gaps.missed("~force /a", 50), 0u) << "another topic of the same node numbers its own";
}

TEST(SequenceGaps, APublisherThatStartsAgainIsNotALoss) {
  SequenceGaps gaps;
  gaps.missed("~collider /client", 500);
  EXPECT_EQ(gaps.missed("~collider /client", 1), 0u) << "restarted under the same name: numbers from 1";
  EXPECT_EQ(gaps.missed("~collider /client", 3), 1u);
}

TEST(SequenceGaps, LossesAreRejectionsWithTheirReason) {
  SequenceGaps gaps;
  CommandStats stats;
  countMissed(gaps, stats, "~force", "/client", 1);
  countMissed(gaps, stats, "~force", "/client", 2);
  countMissed(gaps, stats, "~force", "/client", 7);
  const CommandStats::Counts c = stats.counts();
  EXPECT_EQ(c.rejected, 4u);
  EXPECT_EQ(c.rejectedByReason.at("queue_overflow"), 4u);
  EXPECT_NE(c.lastRejection.find("/client"), std::string::npos) << c.lastRejection;
}
