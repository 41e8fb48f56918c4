#include "deformable_flsm/ros/reconfigure.h"

#include <utility>

namespace deformable_flsm {

Reconfigure::Reconfigure(const ros::NodeHandle& pnh, const NodeParams& params, OnChange onChange)
    : onChange_(std::move(onChange)) {
  // Start from the loaded parameters, then listen. The first callback (setCallback calls it at
  // once) only echoes them and is skipped.
  server_ = std::make_unique<dynamic_reconfigure::Server<FlsmConfig>>(mutex_, pnh);
  current_ = configFrom(params);
  server_->updateConfig(current_);
  server_->setCallback([this](FlsmConfig& c, std::uint32_t /*level*/) {
    if (!ready_) return;
    if (onChange_(c)) {
      current_ = c;
    } else {
      c = current_;  // what the server keeps and answers with
    }
  });
  ready_ = true;
}

FlsmConfig Reconfigure::configFrom(const NodeParams& params) {
  FlsmConfig config;
  config.material = toString(params.material);
  config.youngs_modulus = params.youngsModulus;
  config.poissons_ratio = params.poissonsRatio;
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

bool Reconfigure::apply(const FlsmConfig& config, NodeParams& params) {
  if (!parseMaterial(config.material, params.material)) return false;
  params.youngsModulus = config.youngs_modulus;
  params.poissonsRatio = config.poissons_ratio;
  SolverParams& s = params.solver;
  s.stiffness = config.stiffness;
  s.damping = config.damping;
  s.ambientDamping = config.ambient_damping;
  s.gravity = Eigen::Vector3d(config.gravity_x, config.gravity_y, config.gravity_z);
  params.applyMaterial();
  return true;
}

}  // namespace deformable_flsm
