#include "deformable_flsm/ros/delivery_gate.h"

#include <ros/poll_manager.h>

namespace deformable_flsm {

DeliveryGate& DeliveryGate::pollThread() {
  // Leaked on purpose: roscpp's poll thread holds the listener until the process ends.
  static DeliveryGate* const gate = [] {
    auto* g = new DeliveryGate([] { ros::PollManager::instance()->getPollSet().signal(); });
    // boost::signals2 calls listeners in the order they were connected: roscpp's
    // TopicManager::processPublishQueues() (connected in ros::start()) runs before this one.
    ros::PollManager::instance()->addPollThreadListener([g] { g->roundDone(); });
    return g;
  }();
  return *gate;
}

}  // namespace deformable_flsm
