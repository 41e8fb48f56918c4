/// @file loop_clock.h
/// The clock the simulation loop paces itself by (SimulationLoop): the steady clock in the node,
/// a clock moved by hand in tests, so that pacing is checked step by step rather than against
/// the wall clock of a busy machine. No ROS.
#pragma once

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <mutex>
#include <thread>

namespace deformable_flsm {

/// What the loop asks of a clock: the time, and a wait that ends at a time of this clock or
/// when the loop is woken (a command, a stop).
class LoopClock {
 public:
  using Duration = std::chrono::steady_clock::duration;
  using TimePoint = std::chrono::steady_clock::time_point;

  virtual ~LoopClock() = default;
  virtual TimePoint now() const = 0;
  /// The calendar time now, which a state computed now is stamped with (the node's ~clock wall).
  virtual std::chrono::system_clock::time_point wallNow() const { return std::chrono::system_clock::now(); }
  /// Waits on `wake`, with `lock` held on its mutex, until `woken()` holds or this clock reaches
  /// `deadline`.
  virtual void waitUntil(std::unique_lock<std::mutex>& lock, std::condition_variable& wake,
                         TimePoint deadline, const std::function<bool()>& woken) = 0;
};

/// std::chrono::steady_clock: the node's clock.
class SteadyLoopClock final : public LoopClock {
 public:
  TimePoint now() const override { return std::chrono::steady_clock::now(); }
  void waitUntil(std::unique_lock<std::mutex>& lock, std::condition_variable& wake, TimePoint deadline,
                 const std::function<bool()>& woken) override {
    wake.wait_until(lock, deadline, woken);
  }
};

/// A clock that moves only when told to (tests): the loop steps exactly as often as the time
/// given to it asks, however busy the machine. Its waits look at the time again every
/// kPoll of real time, so that advance() needs no access to the waiter's condition variable.
class ManualLoopClock final : public LoopClock {
 public:
  /// How often a wait looks at the time again (real time).
  static constexpr std::chrono::milliseconds kPoll{1};
  /// How long the test helpers wait for the waiting thread (real time).
  static constexpr std::chrono::milliseconds kTimeout{5000};

  TimePoint now() const override { return TimePoint(Duration(ticks_.load())); }
  /// the calendar's epoch plus the time moved on so far
  std::chrono::system_clock::time_point wallNow() const override {
    return std::chrono::system_clock::time_point(
        std::chrono::duration_cast<std::chrono::system_clock::duration>(Duration(ticks_.load())));
  }
  void waitUntil(std::unique_lock<std::mutex>& lock, std::condition_variable& wake, TimePoint deadline,
                 const std::function<bool()>& woken) override {
    deadline_ = deadline.time_since_epoch().count();
    waiting_ = true;
    ++waits_;
    while (!woken() && now() < deadline) wake.wait_for(lock, kPoll);
    waiting_ = false;
  }

  /// Moves the time on by `d`.
  void advance(Duration d) { ticks_ += d.count(); }
  /// How many waits have begun on this clock.
  std::uint64_t waits() const { return waits_.load(); }
  /// Waits (real time, up to `timeout`) until more than `count` waits have begun and a thread
  /// is waiting: it has done what it was woken for. True if so.
  bool awaitWaitBeyond(std::uint64_t count, std::chrono::milliseconds timeout = kTimeout) const {
    return pollUntil([&] { return waits_.load() > count && waiting_.load(); }, timeout);
  }
  /// Once a thread waits on this clock: moves the time on by `d`, and if that reaches the end of
  /// its wait, waits (real time, up to `timeout`) until the thread has done what the time asked
  /// and waits again. True if so.
  bool advanceAndSettle(Duration d, std::chrono::milliseconds timeout = kTimeout) {
    if (!pollUntil([&] { return waiting_.load(); }, timeout)) return false;
    const std::uint64_t before = waits_.load();
    advance(d);
    if (ticks_.load() < deadline_.load()) return true;  // it waits on
    return awaitWaitBeyond(before, timeout);
  }

 private:
  template <class Condition>
  static bool pollUntil(Condition done, std::chrono::milliseconds timeout) {
    const auto end = std::chrono::steady_clock::now() + timeout;
    while (!done()) {
      if (std::chrono::steady_clock::now() > end) return false;
      std::this_thread::sleep_for(kPoll);
    }
    return true;
  }

  std::atomic<Duration::rep> ticks_{0};
  std::atomic<Duration::rep> deadline_{0};  // of the current wait
  std::atomic<bool> waiting_{false};
  std::atomic<std::uint64_t> waits_{0};
};

}  // namespace deformable_flsm
