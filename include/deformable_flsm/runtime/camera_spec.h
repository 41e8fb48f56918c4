/// @file camera_spec.h
/// A simulated depth camera as the node is configured with it (~cameras): where it is (a tf
/// frame), what it sees (a pinhole model), how often and in which encoding it publishes, and
/// its noise. Plain values and their checks; reading them from the parameter server is
/// ros/camera_params.h, rendering runtime/scene_renderer.h.
#pragma once

#include "deformable_flsm/runtime/scene_renderer.h"

#include <Eigen/Geometry>

#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace deformable_flsm {

struct CameraSpec {
  /// its topics live under ~<name>/
  std::string name;
  /// the tf frame of its optical frame (REP 103: z forward, x right, y down)
  std::string frame;
  /// placed: the node itself publishes `frame` (static tf) at `pose` in ~frame_id (a camera
  /// fixed in the scene, given by where it is and what it looks at); else another node does
  bool placed = false;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  CameraIntrinsics intrinsics;
  /// images a second (Hz, of the node's time)
  double rate = 15.0;
  /// depth/image_raw's encoding: 32FC1 metres (REP 118) or 16UC1 millimetres (0 = no reading)
  enum class DepthEncoding { Float32Metres, UInt16Millimetres };
  DepthEncoding encoding = DepthEncoding::Float32Metres;
  /// noise on the depth: none, or the Kinect's axial model (kinectSigma()), seeded
  enum class Noise { None, Kinect };
  Noise noise = Noise::None;
  std::uint32_t seed = 0;

  static constexpr int kMaxPixels = 4096;      ///< width and height at most
  static constexpr double kMaxRate = 100.0;     ///< Hz
  static constexpr double kMaxFar = 1000.0;     ///< m
};

/// The optical frame (z forward, x right, y down) of a camera at `eye` looking at `at`, with
/// `up` (the simulation frame's +z unless given) up in its image; a camera looking straight
/// along `up` has +y up in its image.
Eigen::Isometry3d opticalLookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& at,
                                const Eigen::Vector3d& up = Eigen::Vector3d::UnitZ());

/// "32FC1" or "16UC1".
const char* toString(CameraSpec::DepthEncoding encoding);

/// The Kinect's axial depth noise (Nguyen, Izadi and Lovell 2012): sigma = 0.0012 + 0.0019
/// (z - 0.4)^2 m at depth z (m).
double kinectSigma(double z);

/// Adds the camera's noise to the finite depths of `depth` (m), drawing from `rng`.
void addDepthNoise(CameraSpec::Noise noise, std::mt19937& rng, std::vector<float>& depth);

/// @throws ParamError naming the camera (`label`) and the key that is wrong.
void validateCamera(const CameraSpec& camera, const std::string& label);

}  // namespace deformable_flsm
