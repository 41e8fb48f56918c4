// flsm_node: reads ~parameters and the mesh, builds the scene, hands it to SimulatorNode.
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/ros/scene.h"
#include "deformable_flsm/ros/simulator_node.h"

#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "flsm_node");
  ros::NodeHandle nh, pnh("~");
  try {
    using namespace deformable_flsm;
    const ParamLoader loader(pnh);
    const NodeParams params = loader.loadNodeParams();
    for (const std::string& name : loader.unknownParams()) {
      ROS_WARN("flsm_node: ~%s is not a parameter of flsm_node (misspelt?); ignored", name.c_str());
    }
    Scene scene = buildScene(params, loadMeshParam(params));
    ROS_INFO_STREAM("flsm_node: mesh '" << params.mesh << "'\n" << describeScene(scene.info, params));
    const std::string clamped = regionClampWarning(scene.info, params);
    if (!clamped.empty()) ROS_WARN("flsm_node: %s", clamped.c_str());
    const std::string thin = sectionWarning(scene.info, params);
    if (!thin.empty()) ROS_WARN("flsm_node: %s", thin.c_str());
    SimulatorNode node(nh, pnh, params, std::move(scene));
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("flsm_node cannot start: %s", e.what());
    return 1;
  }
  return 0;
}
