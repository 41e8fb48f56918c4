#include "deformable_flsm/ros/publish_queue_bound.h"

#include <ros/publication.h>
#include <ros/publisher.h>
#include <ros/topic_manager.h>

#include <algorithm>
#include <map>
#include <stdexcept>
#include <string>

namespace deformable_flsm {

std::shared_ptr<PublishQueueBound> PublishQueueBound::of(const ros::Publisher& publisher,
                                                         std::uint32_t messagesPerTick) {
  static std::mutex registryMutex;
  static std::map<std::string, std::weak_ptr<PublishQueueBound>> registry;
  const std::string topic = publisher.getTopic();
  ros::PublicationPtr publication = ros::TopicManager::instance()->lookupPublication(topic);
  if (!publication)
    throw std::runtime_error("roscpp has no publication of topic '" + topic +
                             "' although it was advertised: is the node shutting down?");
  std::lock_guard<std::mutex> lock(registryMutex);
  std::shared_ptr<PublishQueueBound> bound = registry[topic].lock();
  if (!bound || bound->publication_ != publication) {
    bound = std::make_shared<PublishQueueBound>(std::move(publication), kTicks * messagesPerTick);
    registry[topic] = bound;
  } else {
    std::lock_guard<std::mutex> boundLock(bound->mutex_);
    bound->capacity_ = std::max(bound->capacity_, kTicks * messagesPerTick);
  }
  return bound;
}

PublishQueueBound::PublishQueueBound(ros::PublicationPtr publication, std::uint32_t capacity)
    : publication_(std::move(publication)),
      capacity_(capacity),
      count_(publication_->getSequence()) {}

bool PublishQueueBound::full() {
  // getSequence() reads, without roscpp's seq_mutex_, a 32-bit counter the poll thread writes
  // under it; roscpp offers no locked read. An aligned 32-bit read is not torn, and a value read
  // just before the poll thread's increment only holds the next publish back by one tick.
  std::lock_guard<std::mutex> lock(mutex_);
  return count_.unsent(publication_->getSequence()) >= capacity_;
}

void PublishQueueBound::publishing() {
  std::lock_guard<std::mutex> lock(mutex_);
  count_.publishing();
}

}  // namespace deformable_flsm
