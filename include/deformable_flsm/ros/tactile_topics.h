/// @file tactile_topics.h
/// ~tactile: tactile sensors on box colliders' faces (runtime/tactile.h). Their images go out
/// with each publish tick, only while subscribed, under ~tactile/<name>/: pressure (32FC1, N/m^2
/// per taxel, positive into the face) and shear (32FC2, N/m^2 along the face's u and v axes), in
/// the collider's tf frame (flsm_collider/<id>), with the state's stamp.
#pragma once

#include "deformable_flsm/runtime/simulation_loop.h"
#include "deformable_flsm/runtime/tactile.h"

#include <ros/node_handle.h>
#include <ros/publisher.h>
#include <sensor_msgs/Image.h>
#include <xmlrpcpp/XmlRpcValue.h>

#include <string>
#include <vector>

namespace deformable_flsm {

struct NodeParams;

/// Parses ~tactile: each entry has `name`, `collider` (a box collider's id: one of ~colliders, or
/// a robot link's "robot/<link>/<k>"), `face` ('+x' ... '-z' of the collider's frame) and
/// optionally `rows`, `cols` (16 each).
/// @throws ParamError naming the entry and the key that is wrong, or a collider that is not a box
/// of the scene.
std::vector<TactileSpec> parseTactileList(XmlRpc::XmlRpcValue& list, const NodeParams& params);

class TactileTopics {
 public:
  TactileTopics(ros::NodeHandle& pnh, std::vector<TactileSpec> sensors);
  /// The sensors' images of snapshot `s` (the main thread's publish tick).
  void publish(const Snapshot& s, const ros::Time& stamp);

 private:
  struct Sensor {
    TactileSpec spec;
    ros::Publisher pressure, shear;
    TactileImage image;
    sensor_msgs::Image pressureMsg, shearMsg;
  };
  std::vector<Sensor> sensors_;
};

}  // namespace deformable_flsm
