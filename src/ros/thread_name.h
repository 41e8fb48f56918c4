/// @file thread_name.h
/// Names the thread that serves a callback queue, so that a thread listing (top -H,
/// /proc/<pid>/task/*/comm, gdb, the soak's stall report) tells the node's threads apart.
#pragma once

#include <pthread.h>
#include <ros/callback_queue.h>

#include <boost/make_shared.hpp>
#include <string>

namespace deformable_flsm {

/// Queues a callback that names the thread calling it: the first callback of a queue served by
/// a one-thread spinner names that spinner's thread. `name` is cut to 15 characters (Linux's
/// limit).
inline void nameQueueThread(ros::CallbackQueue& queue, const std::string& name) {
  class NameThread final : public ros::CallbackInterface {
   public:
    explicit NameThread(std::string name) : name_(name.substr(0, 15)) {}
    CallResult call() override {
      pthread_setname_np(pthread_self(), name_.c_str());
      return Success;
    }

   private:
    std::string name_;
  };
  queue.addCallback(boost::make_shared<NameThread>(name));
}

}  // namespace deformable_flsm
