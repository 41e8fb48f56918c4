/// @file reconfigure.h
/// dynamic_reconfigure on flsm_node's private namespace (cfg/Flsm.cfg): the material, gravity,
/// ~publish_rate and ~real_time_factor while the simulation runs.
#pragma once

#include "deformable_flsm/core/solver_params.h"
#include "deformable_flsm/ros/param_loader.h"

#include <deformable_flsm/FlsmConfig.h>
#include <dynamic_reconfigure/server.h>
#include <ros/node_handle.h>

#include <boost/thread/recursive_mutex.hpp>
#include <cstdint>
#include <functional>
#include <memory>

namespace deformable_flsm {

/// The server, started from the loaded parameters; calls `onChange` for every change a client
/// makes (not for the initial echo of the parameters). Callbacks run on the thread that serves
/// `pnh`'s callback queue (flsm_node gives it a queue and a thread of its own). When
/// `onChange` refuses a change (returns false), the server keeps and reports the configuration
/// it had: a client reading back its parameters sees that nothing changed.
class Reconfigure {
 public:
  using OnChange = std::function<bool(const FlsmConfig&)>;

  Reconfigure(const ros::NodeHandle& pnh, const NodeParams& params, OnChange onChange);

  /// The configuration that shows `params`.
  static FlsmConfig configFrom(const NodeParams& params);
  /// `params` with the material and gravity of `config` (not validated); false when
  /// config.material names no material.
  static bool apply(const FlsmConfig& config, NodeParams& params);

 private:
  boost::recursive_mutex mutex_;
  OnChange onChange_;
  bool ready_ = false;
  FlsmConfig current_;  ///< the last configuration accepted
  std::unique_ptr<dynamic_reconfigure::Server<FlsmConfig>> server_;
};

}  // namespace deformable_flsm
