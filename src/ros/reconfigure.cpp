#include "deformable_flsm/ros/reconfigure.h"

#include <utility>

namespace deformable_flsm {

Reconfigure::Reconfigure(const ros::NodeHandle& pnh, const NodeParams& params, OnChange onChange)
    : onChange_(std::move(onChange)) {
  // Start from the loaded parameters, then listen. The first callback (setCallback calls it at
  // once) only echoes them and is skipped.
  server_ = std::make_unique<dynamic_reconfigure::Server<FlsmConfig>>(mutex_, pnh);
  FlsmConfig config = configFrom(params);
  server_->updateConfig(config);
  server_->setCallback([this](FlsmConfig& c, std::uint32_t /*level*/) {
    if (ready_) onChange_(c);
  });
  ready_ = true;
}

FlsmConfig Reconfigure::configFrom(const NodeParams& params) {
  FlsmConfig config;
  config.youngs_modulus = params.solver.youngsModulus;
  config.poissons_ratio = params.solver.poissonsRatio;
  config.stiffness = params.solver.stiffness;
  config.damping = params.solver.damping;
  config.ambient_damping = params.solver.ambientDamping;
  config.gravity_x = params.solver.gravity.x();
  config.gravity_y = params.solver.gravity.y();
  config.gravity_z = params.solver.gravity.z();
  config.publish_rate = params.publishRate;
  config.real_time_factor = params.realTimeFactor;
  return config;
}

SolverParams Reconfigure::solverParams(const FlsmConfig& config, SolverParams base) {
  base.youngsModulus = config.youngs_modulus;
  base.poissonsRatio = config.poissons_ratio;
  base.stiffness = config.stiffness;
  base.damping = config.damping;
  base.ambientDamping = config.ambient_damping;
  base.gravity = Eigen::Vector3d(config.gravity_x, config.gravity_y, config.gravity_z);
  return base;
}

}  // namespace deformable_flsm
