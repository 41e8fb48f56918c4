/// @file to_eigen.h
/// Private to the adapter: tf2_eigen's conversions of point and vector messages, returned by
/// value so that a message's fields read as one expression.
#pragma once

#include <Eigen/Core>
#include <tf2_eigen/tf2_eigen.h>

namespace deformable_flsm {

/// A geometry_msgs::Point or geometry_msgs::Vector3 as an Eigen vector (tf2::fromMsg).
template <class Msg>
Eigen::Vector3d toEigen(const Msg& msg) {
  Eigen::Vector3d v;
  tf2::fromMsg(msg, v);
  return v;
}

}  // namespace deformable_flsm
