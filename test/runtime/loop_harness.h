/// @file loop_harness.h
/// What the tests of a running SimulationLoop share: hand it a command and wait for the outcome,
/// wait for a snapshot that satisfies a condition, read a refusal count.
#pragma once

#include "deformable_flsm/runtime/simulation_loop.h"

#include <gtest/gtest.h>

#include <chrono>
#include <functional>
#include <future>
#include <memory>
#include <string>
#include <thread>
#include <utility>

namespace deformable_flsm {
namespace test {

/// Submits `body` and waits (at most 5 s, a failure beyond) for its outcome; the loop must be
/// running.
inline CommandOutcome runCommand(SimulationLoop& loop, CommandBody body) {
  Command c{std::move(body), std::make_shared<std::promise<CommandOutcome>>(), std::string()};
  auto f = c.outcome->get_future();
  loop.submit(std::move(c));
  EXPECT_EQ(f.wait_for(std::chrono::seconds(5)), std::future_status::ready);
  return f.get();
}

/// Polls the loop's snapshots until `done` or `timeout` seconds; returns whether `done` held.
inline bool waitForSnapshot(SimulationLoop& loop, const std::function<bool(const Snapshot&)>& done,
                            double timeout) {
  using Clock = std::chrono::steady_clock;
  const Clock::time_point end =
      Clock::now() + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(timeout));
  while (Clock::now() < end) {
    if (done(loop.acquire())) return true;
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  return false;
}

/// Commands refused for `reason` so far.
inline std::uint64_t rejectedCount(const CommandStats& stats, const std::string& reason) {
  const auto c = stats.counts();
  const auto it = c.rejectedByReason.find(reason);
  return it == c.rejectedByReason.end() ? 0 : it->second;
}

}  // namespace test
}  // namespace deformable_flsm
