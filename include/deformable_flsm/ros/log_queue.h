/// @file log_queue.h
/// Log lines handed to a thread of their own, so that no thread that simulates or publishes ever
/// waits for a log write. rosconsole writes each line to the terminal (under roslaunch, often a
/// file), the node's log file and /rosout, holding a process-wide lock, and a disk that stalls for
/// seconds holds every thread that logs for as long; a thread that posts here only takes a short
/// lock of its own.
#pragma once

#include "deformable_flsm/runtime/format.h"  // formatted(), for the lines posted

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <limits>
#include <mutex>
#include <string>
#include <thread>

namespace deformable_flsm {

enum class LogLevel { Info, Warn, Error };

/// A bounded queue of log lines and the thread that writes them with `sink`, in order. When the
/// queue is full (the sink is held up) a line is dropped and counted, and the sink is told how
/// many were dropped before the next line it writes.
class LogQueue {
 public:
  using Sink = std::function<void(LogLevel, const std::string&)>;

  /// @param[in] sink      writes a line (rosconsole in the node); called on the queue's thread only
  /// @param[in] capacity  lines held while the sink is busy (> 0)
  explicit LogQueue(Sink sink, std::size_t capacity = 256);
  /// Writes what is queued, then stops the thread.
  ~LogQueue();
  LogQueue(const LogQueue&) = delete;
  LogQueue& operator=(const LogQueue&) = delete;

  /// Queues `line`; never waits for the sink. False (and counted) when the queue is full.
  bool post(LogLevel level, std::string line);
  /// Lines dropped so far because the queue was full.
  std::uint64_t dropped() const { return dropped_.load(std::memory_order_relaxed); }

 private:
  void run();
  /// Tells the sink how many lines were dropped since it was last told (queue thread only).
  void reportDropped();

  Sink sink_;
  std::size_t capacity_;
  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::pair<LogLevel, std::string>> lines_;
  bool stopping_ = false;
  std::atomic<std::uint64_t> dropped_{0};
  std::uint64_t reported_ = 0;  // dropped lines the sink has been told of (queue thread only)
  std::thread thread_;
};

/// At most one `ready()` per period, from any thread (ROS_WARN_THROTTLE's rule for one call site).
class LogThrottle {
 public:
  explicit LogThrottle(double periodSeconds)
      : period_(std::chrono::duration_cast<std::chrono::steady_clock::duration>(
            std::chrono::duration<double>(periodSeconds))) {}
  bool ready();

 private:
  std::chrono::steady_clock::duration period_;
  std::atomic<std::int64_t> next_{std::numeric_limits<std::int64_t>::min()};
};

/// Writes `line` with rosconsole at `level` (the node's sink).
void writeToRosconsole(LogLevel level, const std::string& line);

/// Lines posted with postLog() go to the installed queue (the node's, for its lifetime) and
/// straight to rosconsole while none is.
void postLog(LogLevel level, std::string line);

/// Installs a queue for postLog() while it lives; uninstalls it when destroyed (unless another
/// was installed since). Declared right after the queue it installs, so that a constructor that
/// throws leaves no queue installed that is gone.
class InstalledLogQueue {
 public:
  explicit InstalledLogQueue(LogQueue* queue);
  ~InstalledLogQueue();
  InstalledLogQueue(const InstalledLogQueue&) = delete;
  InstalledLogQueue& operator=(const InstalledLogQueue&) = delete;

 private:
  LogQueue* queue_;
};

}  // namespace deformable_flsm
