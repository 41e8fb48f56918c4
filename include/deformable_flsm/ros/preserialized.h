/// @file preserialized.h
/// A message serialized before Publisher::publish(), so that roscpp copies its bytes under its
/// process-wide publish lock instead of serializing it there.
#pragma once

#include <ros/message_traits.h>
#include <ros/serialization.h>

#include <cstdint>
#include <cstring>
#include <vector>

namespace deformable_flsm {

/// roscpp's TopicManager::publish() serializes a message while it holds advertised_topics_mutex_,
/// which every publish of the process needs. A 5 MB ~mesh marker serialized there by a thread the
/// scheduler keeps waiting holds ~state's publish back as long. Serialized beforehand
/// (serialize()), the message is published as this view, whose serialization under the lock is a
/// copy of its bytes. It is the same message on the wire: type, MD5 sum, definition and bytes
/// are Msg's.
template <typename Msg>
struct PreSerialized {
  const std::vector<std::uint8_t>* bytes;  ///< Msg serialized, without roscpp's length prefix

  /// Serializes `msg` into `bytes` (reusing its storage) and returns the view to publish.
  static PreSerialized serialize(const Msg& msg, std::vector<std::uint8_t>& bytes) {
    const std::uint32_t length = ros::serialization::serializationLength(msg);
    bytes.resize(length);
    ros::serialization::OStream stream(bytes.data(), length);
    ros::serialization::serialize(stream, msg);
    return PreSerialized{&bytes};
  }
};

}  // namespace deformable_flsm

namespace ros {
namespace message_traits {

template <typename Msg>
struct IsMessage<deformable_flsm::PreSerialized<Msg>> : IsMessage<Msg> {};
template <typename Msg>
struct HasHeader<deformable_flsm::PreSerialized<Msg>> : HasHeader<Msg> {};

template <typename Msg>
struct MD5Sum<deformable_flsm::PreSerialized<Msg>> {
  static const char* value() { return MD5Sum<Msg>::value(); }
  static const char* value(const deformable_flsm::PreSerialized<Msg>&) { return value(); }
};
template <typename Msg>
struct DataType<deformable_flsm::PreSerialized<Msg>> {
  static const char* value() { return DataType<Msg>::value(); }
  static const char* value(const deformable_flsm::PreSerialized<Msg>&) { return value(); }
};
template <typename Msg>
struct Definition<deformable_flsm::PreSerialized<Msg>> {
  static const char* value() { return Definition<Msg>::value(); }
  static const char* value(const deformable_flsm::PreSerialized<Msg>&) { return value(); }
};

}  // namespace message_traits

namespace serialization {

template <typename Msg>
struct Serializer<deformable_flsm::PreSerialized<Msg>> {
  template <typename Stream>
  static void write(Stream& stream, const deformable_flsm::PreSerialized<Msg>& m) {
    const auto length = static_cast<std::uint32_t>(m.bytes->size());
    if (length > 0) std::memcpy(stream.advance(length), m.bytes->data(), length);
  }
  static std::uint32_t serializedLength(const deformable_flsm::PreSerialized<Msg>& m) {
    return static_cast<std::uint32_t>(m.bytes->size());
  }
};

}  // namespace serialization
}  // namespace ros
