/// @file refusal.h
/// Private to the command validators: how a refused command's detail is worded.
#pragma once

#include "deformable_flsm/ros/command_validator.h"

#include <Eigen/Core>

#include <sstream>
#include <string>
#include <utility>

namespace deformable_flsm {
namespace refusal {

/// A number in a refusal's detail: four significant digits.
inline std::string str(double v) {
  std::ostringstream os;
  os.precision(4);
  os << v;
  return os.str();
}

/// A vector in a refusal's detail: "(x, y, z)".
inline std::string str(const Eigen::Vector3d& v) {
  return "(" + str(v.x()) + ", " + str(v.y()) + ", " + str(v.z()) + ")";
}

/// Fills `why` and returns false, for `return refuse(why, "reason", "detail");`.
inline bool refuse(Rejection& why, const char* reason, std::string detail) {
  why.reason = reason;
  why.detail = std::move(detail);
  return false;
}

}  // namespace refusal
}  // namespace deformable_flsm
