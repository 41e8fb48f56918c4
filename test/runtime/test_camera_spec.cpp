/// @file test_camera_spec.cpp
/// Tests of runtime/camera_spec.h: a camera placed by where it looks, the Kinect noise model's
/// spread, and the checks that name what is wrong.
#include "deformable_flsm/runtime/camera_spec.h"

#include "deformable_flsm/runtime/node_params.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numeric>
#include <vector>

namespace deformable_flsm {
namespace {

TEST(CameraSpec, LookingDownIsHalfATurnAboutX) {
  const Eigen::Isometry3d T = opticalLookAt(Eigen::Vector3d(1, 2, 3), Eigen::Vector3d(1, 2, 0));
  Eigen::Matrix3d expected;
  expected << 1, 0, 0, 0, -1, 0, 0, 0, -1;
  EXPECT_TRUE(T.linear().isApprox(expected, 1e-12)) << T.linear();
  EXPECT_TRUE(T.translation().isApprox(Eigen::Vector3d(1, 2, 3)));
}

TEST(CameraSpec, LookingAcrossKeepsTheWorldUpInTheImage) {
  // looking along +x: the image's right is -y, its down -z
  const Eigen::Isometry3d T = opticalLookAt(Eigen::Vector3d::Zero(), Eigen::Vector3d(2, 0, 0));
  EXPECT_TRUE(T.linear().col(2).isApprox(Eigen::Vector3d::UnitX()));
  EXPECT_TRUE(T.linear().col(0).isApprox(-Eigen::Vector3d::UnitY()));
  EXPECT_TRUE(T.linear().col(1).isApprox(-Eigen::Vector3d::UnitZ()));
  EXPECT_NEAR(T.linear().determinant(), 1.0, 1e-12);
}

TEST(CameraSpec, KinectNoiseHasTheModelsSpreadAndLeavesNoReadingAlone) {
  EXPECT_DOUBLE_EQ(kinectSigma(0.4), 0.0012);
  EXPECT_NEAR(kinectSigma(2.4), 0.0012 + 0.0019 * 4.0, 1e-15);
  std::vector<float> depth(200000, 2.4f);
  depth[7] = std::numeric_limits<float>::quiet_NaN();
  std::mt19937 rng(3);
  addDepthNoise(CameraSpec::Noise::Kinect, rng, depth);
  EXPECT_TRUE(std::isnan(depth[7]));
  depth.erase(depth.begin() + 7);
  const double mean = std::accumulate(depth.begin(), depth.end(), 0.0) / depth.size();
  double var = 0.0;
  for (float z : depth) var += (z - mean) * (z - mean);
  const double sigma = std::sqrt(var / depth.size());
  // 200,000 samples: the spread within 1 % of the model's, the mean within a few of its errors
  EXPECT_NEAR(sigma, kinectSigma(2.4), 0.01 * kinectSigma(2.4));
  EXPECT_NEAR(mean, 2.4, 5.0 * kinectSigma(2.4) / std::sqrt(depth.size()));
  // seeded: the same noise again
  std::vector<float> a(10, 1.0f), b(10, 1.0f);
  std::mt19937 r1(5), r2(5);
  addDepthNoise(CameraSpec::Noise::Kinect, r1, a);
  addDepthNoise(CameraSpec::Noise::Kinect, r2, b);
  EXPECT_EQ(a, b);
}

TEST(CameraSpec, AWrongCameraIsNamedWithWhatToFix) {
  CameraSpec c;
  c.name = "top";
  c.frame = "top_optical";
  EXPECT_NO_THROW(validateCamera(c, "camera 'top'"));
  const auto message = [](const CameraSpec& bad) {
    try {
      validateCamera(bad, "camera 'top'");
    } catch (const ParamError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  CameraSpec bad = c;
  bad.intrinsics.far = 0.01;
  EXPECT_NE(message(bad).find("near"), std::string::npos) << message(bad);
  bad = c;
  bad.frame.clear();
  EXPECT_NE(message(bad).find("frame is empty"), std::string::npos) << message(bad);
  bad = c;
  bad.rate = 0.0;
  EXPECT_NE(message(bad).find("rate 0"), std::string::npos) << message(bad);
  bad = c;
  bad.name = "a/b";
  EXPECT_NE(message(bad).find("camera 'top': name 'a/b'"), std::string::npos) << message(bad);
}

}  // namespace
}  // namespace deformable_flsm
