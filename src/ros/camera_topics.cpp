#include "deformable_flsm/ros/camera_topics.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/ros/log_queue.h"
#include "deformable_flsm/ros/mesh_messages.h"

#include "image_fill.h"
#include "thread_name.h"

#include <ros/console.h>
#include <sensor_msgs/image_encodings.h>
#include <sensor_msgs/point_cloud2_iterator.h>
#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <mutex>

namespace deformable_flsm {

namespace {

constexpr double kWarnPeriod = 5.0;  // s between two warnings of the same kind
/// 16UC1 depth: millimetres, 0 where there is no reading (REP 118).
constexpr double kMillimetres = 1000.0;
constexpr double kMaxMillimetres = 65535.0;

void fillInfo(const CameraIntrinsics& k, const std::string& frame, const ros::Time& stamp,
              sensor_msgs::CameraInfo& out) {
  out.header.stamp = stamp;
  out.header.frame_id = frame;
  out.width = static_cast<std::uint32_t>(k.width);
  out.height = static_cast<std::uint32_t>(k.height);
  out.distortion_model = "plumb_bob";
  out.D.assign(5, 0.0);
  out.K = {k.fx, 0.0, k.cx, 0.0, k.fy, k.cy, 0.0, 0.0, 1.0};
  out.R = {1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0};
  out.P = {k.fx, 0.0, k.cx, 0.0, 0.0, k.fy, k.cy, 0.0, 0.0, 0.0, 1.0, 0.0};
}

}  // namespace

/// One camera: its settings, publishers, timer and noise.
struct CameraTopics::Camera {
  CameraSpec spec;
  ros::Publisher depth, depthInfo, rgb, rgbInfo, points, mask;
  ros::Timer timer;
  std::mt19937 rng;
  sensor_msgs::Image depthImage, rgbImage, maskImage;
  sensor_msgs::CameraInfo info;
  sensor_msgs::PointCloud2 cloud;
  std::vector<std::uint16_t> millimetres;

  bool watched() const {
    for (const ros::Publisher* p : {&depth, &depthInfo, &rgb, &rgbInfo, &points, &mask})
      if (p->getNumSubscribers() > 0) return true;
    return false;
  }
};

CameraTopics::CameraTopics(ros::NodeHandle& pnh, const std::vector<CameraSpec>& cameras,
                           std::string simFrame, const SimulationLoop& loop,
                           const std::deque<SceneObject>& objects, std::shared_mutex& objectsMutex,
                           const tf2_ros::Buffer& tfBuffer, const std::function<void()>& startTfListener,
                           StampOf stampOf)
    : simFrame_(std::move(simFrame)), loop_(loop), objects_(objects), objectsMutex_(objectsMutex),
      tfBuffer_(tfBuffer), stampOf_(std::move(stampOf)), nh_(pnh) {
  nh_.setCallbackQueue(&queue_);
  if (!cameras.empty()) startTfListener();
  // cameras placed in the scene: their frames, once (latched)
  std::vector<geometry_msgs::TransformStamped> placed;
  for (const CameraSpec& spec : cameras) {
    if (!spec.placed) continue;
    geometry_msgs::TransformStamped t = tf2::eigenToTransform(spec.pose);
    t.header.frame_id = simFrame_;
    t.child_frame_id = spec.frame;
    placed.push_back(t);
  }
  if (!placed.empty()) staticFrames_.sendTransform(placed);
  for (const CameraSpec& spec : cameras) {
    auto c = std::make_unique<Camera>();
    c->spec = spec;
    c->rng.seed(spec.seed);
    ros::NodeHandle ns(nh_, spec.name);
    c->depth = ns.advertise<sensor_msgs::Image>("depth/image_raw", 1);
    c->depthInfo = ns.advertise<sensor_msgs::CameraInfo>("depth/camera_info", 1);
    c->rgb = ns.advertise<sensor_msgs::Image>("rgb/image_raw", 1);
    c->rgbInfo = ns.advertise<sensor_msgs::CameraInfo>("rgb/camera_info", 1);
    c->points = ns.advertise<sensor_msgs::PointCloud2>("depth/points", 1);
    c->mask = ns.advertise<sensor_msgs::Image>("mask", 1);
    Camera* raw = c.get();
    c->timer = nh_.createTimer(ros::Duration(1.0 / spec.rate),
                               [this, raw](const ros::TimerEvent&) { onTimer(*raw); });
    cameras_.push_back(std::move(c));
  }
  nameQueueThread(queue_, "flsm_cameras");
  spinner_ = std::make_unique<ros::AsyncSpinner>(1, &queue_);
  spinner_->start();
}

CameraTopics::~CameraTopics() {
  for (auto& c : cameras_) c->timer.stop();
  spinner_->stop();
}

void CameraTopics::updateScene() {
  loop_.copyState(state_);
  if (state_.sequence == sceneSequence_) return;
  sceneSequence_ = state_.sequence;
  std::vector<SceneRenderer::Object> drawn;
  {
    std::shared_lock<std::shared_mutex> lock(objectsMutex_);
    vertices_.resize(state_.objects.size());
    for (std::size_t k = 0; k < state_.objects.size(); ++k) {
      const ObjectSnapshot& o = state_.objects[k];
      // the newest object of that name (one removed earlier may share it)
      const SceneObject* found = nullptr;
      for (const SceneObject& s : objects_)
        if (s.name == o.name) found = &s;
      // added a moment ago (or removed and added again, its lattice not yet the node's): in the
      // next frame
      if (found == nullptr || found->lattice->size() != o.positions.size()) continue;
      found->embedding->deform(o.positions, o.rotations, vertices_[k]);
      // as ~surface and ~mesh show it: not dipping below a collider the particles rest on
      projectOutOfColliders(vertices_[k], state_.colliders, 0.0);
      const std::array<float, 4> color = objectColor(k);
      drawn.push_back({&found->renderMesh.triangles, &vertices_[k], Eigen::Vector3f(color[0], color[1], color[2])});
    }
  }
  renderer_.setObjects(drawn);
  renderer_.setColliders(state_.colliders);
}

void CameraTopics::onTimer(Camera& camera) {
  if (!camera.watched()) return;
  try {
    render(camera);
  } catch (const std::exception& e) {  // a frame lost, never the node
    static LogThrottle throttle(kWarnPeriod);
    if (throttle.ready())
      postLog(LogLevel::Error,
              formatted("flsm_node: camera '%s' could not render: %s", camera.spec.name.c_str(), e.what()));
  }
}

void CameraTopics::render(Camera& camera) {
  updateScene();
  ros::Time stamp;
  if (state_.sequence == 0 || !stampOf_(state_, stamp)) return;
  const CameraSpec& spec = camera.spec;
  Eigen::Isometry3d pose;
  try {
    // at the state's stamp when tf has it, else the newest (a camera that does not move)
    const ros::Time when = tfBuffer_.canTransform(simFrame_, spec.frame, stamp) ? stamp : ros::Time(0);
    pose = tf2::transformToEigen(tfBuffer_.lookupTransform(simFrame_, spec.frame, when));
  } catch (const tf2::TransformException& e) {
    static LogThrottle throttle(kWarnPeriod);
    if (throttle.ready())
      postLog(LogLevel::Warn, formatted("flsm_node: camera '%s': its frame '%s' is not known in '%s' (%s): no image",
                                        spec.name.c_str(), spec.frame.c_str(), simFrame_.c_str(), e.what()));
    return;
  }
  renderer_.render(spec.intrinsics, pose, view_);
  addDepthNoise(spec.noise, camera.rng, view_.depth);
  publish(camera, stamp, view_);
}

void CameraTopics::publish(Camera& c, const ros::Time& stamp, const RenderedView& view) {
  const CameraSpec& spec = c.spec;
  const CameraIntrinsics& k = spec.intrinsics;
  fillInfo(k, spec.frame, stamp, c.info);
  if (c.depth.getNumSubscribers() > 0) {
    if (spec.encoding == CameraSpec::DepthEncoding::Float32Metres) {
      fillImage(sensor_msgs::image_encodings::TYPE_32FC1, view.depth, 1, k.height, k.width, spec.frame, stamp, c.depthImage);
    } else {
      c.millimetres.resize(view.depth.size());
      for (std::size_t p = 0; p < view.depth.size(); ++p) {
        const float z = view.depth[p];
        const double mm = std::round(z * kMillimetres);
        // 0: no reading (REP 118), also for what 16 bits cannot hold
        c.millimetres[p] = std::isfinite(z) && mm > 0.0 && mm <= kMaxMillimetres ? static_cast<std::uint16_t>(mm) : 0;
      }
      fillImage(sensor_msgs::image_encodings::TYPE_16UC1, c.millimetres, 1, k.height, k.width, spec.frame, stamp, c.depthImage);
    }
    c.depth.publish(c.depthImage);
  }
  c.depthInfo.publish(c.info);
  c.rgbInfo.publish(c.info);
  if (c.rgb.getNumSubscribers() > 0) {
    fillImage(sensor_msgs::image_encodings::RGB8, view.rgb, 3, k.height, k.width, spec.frame, stamp, c.rgbImage);
    c.rgb.publish(c.rgbImage);
  }
  if (c.mask.getNumSubscribers() > 0) {
    fillImage(sensor_msgs::image_encodings::TYPE_16UC1, view.label, 1, k.height, k.width, spec.frame, stamp, c.maskImage);
    c.mask.publish(c.maskImage);
  }
  if (c.points.getNumSubscribers() > 0) {
    sensor_msgs::PointCloud2& cloud = c.cloud;
    cloud.header.stamp = stamp;
    cloud.header.frame_id = spec.frame;
    sensor_msgs::PointCloud2Modifier modifier(cloud);
    modifier.setPointCloud2FieldsByString(1, "xyz");
    cloud.width = static_cast<std::uint32_t>(k.width);
    cloud.height = static_cast<std::uint32_t>(k.height);
    cloud.is_dense = false;
    modifier.resize(static_cast<std::size_t>(k.width) * k.height);
    cloud.width = static_cast<std::uint32_t>(k.width);
    cloud.height = static_cast<std::uint32_t>(k.height);
    cloud.row_step = cloud.point_step * cloud.width;
    sensor_msgs::PointCloud2Iterator<float> x(cloud, "x"), y(cloud, "y"), z(cloud, "z");
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (int v = 0; v < k.height; ++v)
      for (int u = 0; u < k.width; ++u, ++x, ++y, ++z) {
        const float d = view.depth[static_cast<std::size_t>(v) * k.width + u];
        if (!std::isfinite(d)) {
          *x = *y = *z = nan;
          continue;
        }
        *x = static_cast<float>((u - k.cx) * d / k.fx);
        *y = static_cast<float>((v - k.cy) * d / k.fy);
        *z = d;
      }
    c.points.publish(cloud);
  }
}

}  // namespace deformable_flsm
