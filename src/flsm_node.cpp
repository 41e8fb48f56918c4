// flsm_node: reads ~parameters and the mesh, then hands everything to SimulatorNode.
#include "deformable_flsm/ros/param_loader.h"
#include "deformable_flsm/ros/simulator_node.h"

#include <ros/ros.h>

int main(int argc, char** argv) {
  ros::init(argc, argv, "flsm_node");
  ros::NodeHandle nh, pnh("~");
  try {
    const deformable_flsm::NodeParams params = deformable_flsm::ParamLoader(pnh).loadNodeParams();
    deformable_flsm::SimulatorNode node(nh, pnh, params, deformable_flsm::loadMeshParam(params));
    ros::spin();
  } catch (const std::exception& e) {
    ROS_FATAL("flsm_node cannot start: %s", e.what());
    return 1;
  }
  return 0;
}
