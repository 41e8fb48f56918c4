#include "deformable_flsm/ros/tactile_topics.h"

#include "deformable_flsm/ros/collider_messages.h"
#include "deformable_flsm/ros/log_queue.h"
#include "deformable_flsm/runtime/node_params.h"

#include "entry_reader.h"
#include "image_fill.h"

#include <ros/console.h>
#include <sensor_msgs/image_encodings.h>

#include <cmath>
#include <set>

namespace deformable_flsm {

namespace {

const std::vector<std::string> kFields = {"name", "collider", "face", "rows", "cols"};
constexpr double kWarnPeriod = 5.0;  // s between two warnings of the same kind

/// The box collider of id `id` among the node's colliders, or nullptr.
const Collider* colliderNamed(const NodeParams& params, const std::string& id) {
  for (const ColliderSpec& c : params.colliders)
    if (c.id == id) return &c.collider;
  for (const RobotCollider& c : params.robot.colliders)
    if (c.spec.id == id) return &c.spec.collider;
  return nullptr;
}

}  // namespace

std::vector<TactileSpec> parseTactileList(XmlRpc::XmlRpcValue& list, const NodeParams& params) {
  if (list.getType() != XmlRpc::XmlRpcValue::TypeArray)
    throw ParamError("~tactile is " + describe(list) + ": it must be a list of sensors (dictionaries)");
  std::vector<TactileSpec> out;
  std::set<std::string> names;
  for (int i = 0; i < list.size(); ++i) {
    XmlRpc::XmlRpcValue& entry = list[i];
    EntryReader r(entry, "~tactile", i, kFields);
    if (entry.getType() != XmlRpc::XmlRpcValue::TypeStruct)
      r.fail("it is " + describe(entry) + ": each sensor is a dictionary (name, collider, face, rows, cols)");
    TactileSpec t;
    t.name = r.string("name", "");
    r.setId(t.name);
    r.checkFields();
    if (!isTopicLevel(t.name))
      r.fail("name '" + t.name + "' must be a non-empty topic name without '/', '~' or spaces");
    if (!names.insert(t.name).second) r.fail("name is taken by an earlier sensor: each needs its own");
    t.collider = r.string("collider", "");
    const Collider* c = colliderNamed(params, t.collider);
    if (c == nullptr)
      r.fail("collider '" + t.collider + "' is not one of ~colliders nor a robot link's collider");
    if (c->shape.type != ColliderType::Box)
      r.fail("collider '" + t.collider + "' is a " + std::string(toString(c->shape.type)) +
             ": a tactile sensor covers a face of a box");
    const std::string face = r.string("face", "");
    if (!parseFace(face, t.axis, t.sign))
      r.fail("face is '" + face + "': it must be '+x', '-x', '+y', '-y', '+z' or '-z' (of the collider's frame)");
    t.rows = r.integer("rows", t.rows, 1, TactileSpec::kMaxTaxels);
    t.cols = r.integer("cols", t.cols, 1, TactileSpec::kMaxTaxels);
    out.push_back(t);
  }
  return out;
}

TactileTopics::TactileTopics(ros::NodeHandle& pnh, std::vector<TactileSpec> sensors) {
  for (TactileSpec& spec : sensors) {
    Sensor s;
    ros::NodeHandle ns(pnh, "tactile/" + spec.name);
    s.pressure = ns.advertise<sensor_msgs::Image>("pressure", 1);
    s.shear = ns.advertise<sensor_msgs::Image>("shear", 1);
    s.spec = std::move(spec);
    sensors_.push_back(std::move(s));
  }
}

void TactileTopics::publish(const Snapshot& snapshot, const ros::Time& stamp) {
  static const std::vector<ParticleContact> kNone;
  for (Sensor& s : sensors_) {
    if (s.pressure.getNumSubscribers() == 0 && s.shear.getNumSubscribers() == 0) continue;
    const auto collider = snapshot.colliders.find(s.spec.collider);
    if (collider == snapshot.colliders.end()) continue;  // a followed frame not seen yet
    if (collider->second.shape.type != ColliderType::Box) {  // replaced through ~collider
      static LogThrottle throttle(kWarnPeriod);
      if (throttle.ready())
        postLog(LogLevel::Warn, formatted("flsm_node: tactile sensor '%s': collider '%s' is no longer a box: no image",
                                          s.spec.name.c_str(), s.spec.collider.c_str()));
      continue;
    }
    const auto contacts = snapshot.contacts.find(s.spec.collider);
    tactileImage(s.spec, collider->second, contacts == snapshot.contacts.end() ? kNone : contacts->second, s.image);
    const std::string frame = colliderFrameId(s.spec.collider);
    fillImage(sensor_msgs::image_encodings::TYPE_32FC1, s.image.pressure, 1, s.image.rows, s.image.cols, frame,
              stamp, s.pressureMsg);
    fillImage(sensor_msgs::image_encodings::TYPE_32FC2, s.image.shear, 2, s.image.rows, s.image.cols, frame,
              stamp, s.shearMsg);
    s.pressure.publish(s.pressureMsg);
    s.shear.publish(s.shearMsg);
  }
}

}  // namespace deformable_flsm
