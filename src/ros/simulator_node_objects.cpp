/// @file simulator_node_objects.cpp
/// SimulatorNode: objects added and removed at run time (a node with ~objects).
#include "deformable_flsm/ros/simulator_node.h"

#include "deformable_flsm/ros/object_params.h"

#include <ros/console.h>

namespace deformable_flsm {

// --------------------------------------------------------------------------------------------
// Objects added and removed at run time (a node with ~objects)

template <class Response>
bool SimulatorNode::refuseObject(const std::string& reason, const std::string& why, Response& res) {
  stats_->reject(reason, why);
  res.success = false;
  res.message = why;
  return true;
}

bool SimulatorNode::onAddObject(AddObject::Request& req, AddObject::Response& res) {
  if (req.param.empty())
    return refuseObject("invalid_object", "~add_object: param is empty: name the parameter that "
                        "holds the object (one ~objects entry, a dictionary)", res);
  const std::string label = "parameter '" + pnh_.resolveName(req.param) + "'";
  XmlRpc::XmlRpcValue entry;
  if (!pnh_.getParam(req.param, entry))
    return refuseObject("invalid_object", label + " is not set: set it to one ~objects entry "
                        "(a dictionary with at least a name) before calling ~add_object", res);
  NodeParams defaults;
  {
    std::lock_guard<std::mutex> lock(paramsMutex_);
    defaults = params_;
  }
  ObjectSpec spec;
  try {
    spec = parseObjectEntry(entry, defaults, label);
  } catch (const ParamError& e) {
    return refuseObject("invalid_object", e.what(), res);
  }
  {
    std::shared_lock<std::shared_mutex> lock(objectsMutex_);
    for (std::size_t k = 0; k < objects_.size(); ++k)
      if (!commands_[k].removed && objects_[k].name == spec.name)
        return refuseObject("invalid_object", label + ": object '" + spec.name + "' is already in "
                            "the scene: choose another name", res);
  }
  // Here, on the service thread: the simulation steps on while the mesh loads and voxelizes.
  PreparedObject prepared;
  try {
    prepared = prepareObject(spec, loadMeshParam);
  } catch (const ParamError& e) {
    return refuseObject("invalid_object", e.what(), res);
  }
  const std::shared_ptr<const Lattice> lattice = prepared.object.lattice;
  // its RViz handle too: simplifying the render mesh is no work for the main thread's tick
  visualization_msgs::InteractiveMarker handle = InteractiveDrag::makeHandle(
      {spec.name, lattice.get(), &prepared.object.renderMesh}, defaults.frameId);
  const CommandOutcome o = sendAndWaitForTheAnswer(AddObjectCommand{spec.name, lattice, prepared.solverParams});
  res.success = o.accepted;
  res.message = o.message;  // a refusal is counted by the simulation thread
  if (!o.accepted) return true;
  res.particles = static_cast<std::uint32_t>(lattice->size());

  std::unique_lock<std::shared_mutex> lock(objectsMutex_);
  objects_.push_back(std::move(prepared.object));
  const std::size_t k = objects_.size() - 1;
  commands_.emplace_back();
  ObjectCommands& c = commands_.back();
  const std::string name = spec.name;
  c.validator = std::make_unique<CommandValidator>(
      lattice->size(), lattice->objectSize(), defaults.frameId,
      [this](const std::string& frame, const ros::Time& stamp, Eigen::Isometry3d& T, std::string& why) {
        return lookupTransform(frame, stamp, T, why);
      },
      [this, name] { return loop_->centerOfMass(name); });
  subscribeCommands(k, "objects/" + name + "/", c.dragSub, c.forceSub, c.pinBoxSrv);
  publisher_->addObject(objects_.back());
  {
    std::lock_guard<std::mutex> handlesLock(handlesMutex_);
    handlesToAdd_.emplace_back(k, std::move(handle));
  }
  postLog(LogLevel::Info, "flsm_node: " + o.message);
  return true;
}

bool SimulatorNode::onRemoveObject(RemoveObject::Request& req, RemoveObject::Response& res) {
  std::size_t k = 0;
  {
    std::shared_lock<std::shared_mutex> lock(objectsMutex_);
    while (k < objects_.size() && (commands_[k].removed || objects_[k].name != req.name)) ++k;
    if (k == objects_.size())
      return refuseObject("unknown_object", "~remove_object: object '" + req.name + "' is not in "
                          "the scene: nothing removed", res);
  }
  const CommandOutcome o = sendAndWaitForTheAnswer(RemoveObjectCommand{req.name});
  res.success = o.accepted;
  res.message = o.message;  // a refusal is counted by the simulation thread
  if (!o.accepted) return true;
  ros::Subscriber dragSub, forceSub;
  ros::ServiceServer pinBoxSrv;
  {
    std::unique_lock<std::shared_mutex> lock(objectsMutex_);
    ObjectCommands& c = commands_[k];
    c.removed = true;
    std::swap(dragSub, c.dragSub);
    std::swap(forceSub, c.forceSub);
    std::swap(pinBoxSrv, c.pinBoxSrv);
    publisher_->removeObject(req.name, ros::Time::now());
    std::lock_guard<std::mutex> handlesLock(handlesMutex_);
    handlesToRemove_.push_back(k);
  }
  // Shut down outside the lock: roscpp's shutdown waits for the subscription's running callback,
  // and onDrag / onForce / the pin box service wait for objectsMutex_ (shared): under the lock the
  // two would wait for each other whenever a command stream to this object was arriving.
  dragSub.shutdown();
  forceSub.shutdown();
  pinBoxSrv.shutdown();
  postLog(LogLevel::Info, "flsm_node: " + o.message);
  return true;
}

}  // namespace deformable_flsm
