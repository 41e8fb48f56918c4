/// @file log_queue.cpp
/// LogQueue: log lines written by a thread of their own.
#include "deformable_flsm/ros/log_queue.h"

#include <pthread.h>
#include <ros/console.h>

#include <stdexcept>

namespace deformable_flsm {

LogQueue::LogQueue(Sink sink, std::size_t capacity) : sink_(std::move(sink)), capacity_(capacity) {
  if (!sink_ || capacity_ == 0) throw std::invalid_argument("LogQueue: a sink and a capacity > 0 are needed");
  thread_ = std::thread([this] { run(); });
  pthread_setname_np(thread_.native_handle(), "flsm_log");
}

LogQueue::~LogQueue() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stopping_ = true;
  }
  wake_.notify_one();
  thread_.join();
}

bool LogQueue::post(LogLevel level, std::string line) {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    if (lines_.size() >= capacity_) {
      dropped_.fetch_add(1, std::memory_order_relaxed);
      return false;
    }
    lines_.emplace_back(level, std::move(line));
  }
  wake_.notify_one();
  return true;
}

void LogQueue::run() {
  std::unique_lock<std::mutex> lock(mutex_);
  for (;;) {
    wake_.wait(lock, [this] { return stopping_ || !lines_.empty(); });
    if (lines_.empty()) return;  // stopping, and everything written (a drop has a line after it)
    std::pair<LogLevel, std::string> line = std::move(lines_.front());
    lines_.pop_front();
    lock.unlock();  // the sink may take long: posting goes on meanwhile
    reportDropped();
    sink_(line.first, line.second);
    lock.lock();
  }
}

void LogQueue::reportDropped() {
  const std::uint64_t dropped = dropped_.load(std::memory_order_relaxed);
  if (dropped > reported_) {
    sink_(LogLevel::Warn, "flsm_node: " + std::to_string(dropped - reported_) +
                              " log line(s) dropped while the log was held up");
    reported_ = dropped;
  }
}

bool LogThrottle::ready() {
  const std::int64_t now = std::chrono::steady_clock::now().time_since_epoch().count();
  std::int64_t next = next_.load(std::memory_order_relaxed);
  if (now < next) return false;
  return next_.compare_exchange_strong(next, now + period_.count(), std::memory_order_relaxed);
}

namespace {

std::atomic<LogQueue*> installed{nullptr};

}  // namespace

void writeToRosconsole(LogLevel level, const std::string& line) {
  switch (level) {
    case LogLevel::Info: ROS_INFO_STREAM(line); break;
    case LogLevel::Warn: ROS_WARN_STREAM(line); break;
    case LogLevel::Error: ROS_ERROR_STREAM(line); break;
  }
}

InstalledLogQueue::InstalledLogQueue(LogQueue* queue) : queue_(queue) { installed.store(queue); }

InstalledLogQueue::~InstalledLogQueue() {
  LogQueue* mine = queue_;
  installed.compare_exchange_strong(mine, nullptr);
}

void postLog(LogLevel level, std::string line) {
  if (LogQueue* q = installed.load()) {
    q->post(level, std::move(line));
    return;
  }
  writeToRosconsole(level, line);
}

}  // namespace deformable_flsm
