#include "deformable_flsm/runtime/camera_spec.h"

#include "deformable_flsm/runtime/node_params.h"

#include <cmath>
#include <sstream>

namespace deformable_flsm {

const char* toString(CameraSpec::DepthEncoding encoding) {
  return encoding == CameraSpec::DepthEncoding::Float32Metres ? "32FC1" : "16UC1";
}

Eigen::Isometry3d opticalLookAt(const Eigen::Vector3d& eye, const Eigen::Vector3d& at,
                                const Eigen::Vector3d& up) {
  const Eigen::Vector3d z = (at - eye).normalized();
  // image down: against `up`, across the view; looking along `up`, the image's up is +y
  Eigen::Vector3d down = -(up - up.dot(z) * z);
  if (std::abs(up.normalized().dot(z)) > 1.0 - 1e-12) down = -Eigen::Vector3d::UnitY();
  const Eigen::Vector3d y = down.normalized();
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear().col(0) = y.cross(z);
  T.linear().col(1) = y;
  T.linear().col(2) = z;
  T.translation() = eye;
  return T;
}

double kinectSigma(double z) { return 0.0012 + 0.0019 * (z - 0.4) * (z - 0.4); }

void addDepthNoise(CameraSpec::Noise noise, std::mt19937& rng, std::vector<float>& depth) {
  if (noise == CameraSpec::Noise::None) return;
  std::normal_distribution<double> unit(0.0, 1.0);
  for (float& z : depth)
    if (std::isfinite(z)) z = static_cast<float>(std::max(0.0, z + kinectSigma(z) * unit(rng)));
}

void validateCamera(const CameraSpec& c, const std::string& label) {
  const CameraIntrinsics& k = c.intrinsics;
  std::ostringstream why;
  if (!isTopicLevel(c.name)) {
    why << "name '" << c.name << "' must be a non-empty topic name without '/', '~' or spaces";
  } else if (c.frame.empty()) {
    why << "frame is empty: give the tf frame of the camera's optical frame (z forward)";
  } else if (k.width < 1 || k.height < 1 || k.width > CameraSpec::kMaxPixels || k.height > CameraSpec::kMaxPixels) {
    why << "width " << k.width << " and height " << k.height << " must be 1 to " << CameraSpec::kMaxPixels << " pixels";
  } else if (!(k.fx > 0.0) || !(k.fy > 0.0) || !std::isfinite(k.fx) || !std::isfinite(k.fy)) {
    why << "fx " << k.fx << " and fy " << k.fy << " must be finite focal lengths > 0 (pixels)";
  } else if (!std::isfinite(k.cx) || !std::isfinite(k.cy)) {
    why << "cx and cy must be finite (pixels)";
  } else if (!(k.near > 0.0) || !(k.far > k.near) || !(k.far <= CameraSpec::kMaxFar)) {
    why << "near " << k.near << " and far " << k.far << " must satisfy 0 < near < far <= "
        << CameraSpec::kMaxFar << " (m)";
  } else if (!(c.rate > 0.0) || c.rate > CameraSpec::kMaxRate) {
    why << "rate " << c.rate << " must be in (0, " << CameraSpec::kMaxRate << "] Hz";
  } else {
    return;
  }
  throw ParamError(label + ": " + why.str());
}

}  // namespace deformable_flsm
