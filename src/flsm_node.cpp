// flsm_node: reads ~parameters and the mesh, builds the scene, hands it to SimulatorNode.
#include "deformable_flsm/ros/object_params.h"
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/runtime/scene.h"
#include "deformable_flsm/ros/simulator_node.h"

#include <ros/ros.h>

#include <malloc.h>

namespace {

/// Allocations from this size on are mapped on their own and unmapped when freed (B).
constexpr int kMmapThreshold = 128 * 1024;
/// Free memory at the top of a heap beyond this goes back to the system (B).
constexpr int kTrimThreshold = 1024 * 1024;

}  // namespace

int main(int argc, char** argv) {
  // glibc raises its mmap threshold to the largest block freed (up to 32 MiB) and its trim
  // threshold to twice that (mallopt(3)): after the state messages and the colliders' distance
  // fields have come and gone, each heap may keep tens of MiB it no longer uses, more the more
  // threads allocate at once. Fixed thresholds keep the node's memory what it holds: the
  // scene, its queues and its colliders (scripts/soak checks it against that bound).
  mallopt(M_MMAP_THRESHOLD, kMmapThreshold);
  mallopt(M_TRIM_THRESHOLD, kTrimThreshold);
  ros::init(argc, argv, "flsm_node");
  ros::NodeHandle nh, pnh("~");
  try {
    using namespace deformable_flsm;
    const ParamLoader loader(pnh);
    NodeParams params = loader.loadNodeParams();
    std::vector<ObjectSpec> objects = loader.loadObjects(params);
    for (const std::string& name : loader.unknownParams()) {
      ROS_WARN("flsm_node: ~%s is not a parameter of flsm_node (misspelt?); ignored", name.c_str());
    }
    WorldScene scene = buildNodeScene(params, objects, loadMeshParam);
    for (const SceneObject& o : scene.objects) {
      const std::string who = objects.empty() ? "" : "object '" + o.name + "': ";
      ROS_INFO_STREAM("flsm_node: " << who << "mesh '" << o.params.mesh << "'\n"
                                    << describeScene(o.info, o.params));
      const std::string clamped = regionClampWarning(o.info, o.params);
      if (!clamped.empty()) ROS_WARN("flsm_node: %s%s", who.c_str(), clamped.c_str());
      const std::string thin = sectionWarning(o.info, o.params);
      if (!thin.empty()) ROS_WARN("flsm_node: %s%s", who.c_str(), thin.c_str());
      const std::string stiff = stiffContactWarning(o.info, o.params);
      if (!stiff.empty()) ROS_WARN("flsm_node: %s%s", who.c_str(), stiff.c_str());
      // (the first object's is ProblemReporter's, as for the single object)
      const std::string saturated = &o == &scene.objects.front() ? "" : saturationWarning(o.info, o.params);
      if (!saturated.empty()) ROS_WARN("flsm_node: %s%s", who.c_str(), saturated.c_str());
    }
    SimulatorNode node(nh, pnh, params, std::move(scene), !objects.empty());
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("flsm_node cannot start: %s", e.what());
    return 1;
  }
  return 0;
}
