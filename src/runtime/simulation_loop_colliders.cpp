/// @file simulation_loop_colliders.cpp
/// SimulationLoop: colliders that follow tf frames: their sampled motion handed in by the node,
/// extrapolated between samples and held still when samples stop; and the drags attached to frames.
#include "deformable_flsm/runtime/simulation_loop.h"

#include <mutex>
#include <stdexcept>

namespace deformable_flsm {

namespace {

/// A pose moved along a constant velocity for dt: the origin by v dt, the axes turned by w dt.
Eigen::Isometry3d advance(const Eigen::Isometry3d& pose, const Eigen::Vector3d& v,
                          const Eigen::Vector3d& w, double dt) {
  Eigen::Isometry3d next = pose;
  next.translation() += v * dt;
  const double angle = w.norm() * dt;
  if (angle > 0.0) {
    next.linear() = (Eigen::AngleAxisd(angle, w.normalized()) * pose.linear()).eval();
  }
  return next;
}

/// Changes of a followed collider's pose below these do not wake a resting simulation (m, rad).
constexpr double kStillPoseChange = 1e-7;

}  // namespace

void SimulationLoop::addFollowedCollider(const std::string& id, const Collider& collider) {
  collider.validate();
  Followed f;
  f.collider = collider;
  followed_[id] = f;
}

void SimulationLoop::setColliderMotion(const std::string& id, const ColliderMotion& motion) {
  bool wake = false;
  {
    std::lock_guard<std::mutex> lock(motionMutex_);
    auto last = postedMotions_.find(id);
    wake = last == postedMotions_.end() || !motion.linearVelocity.isZero(0.0) ||
           !motion.angularVelocity.isZero(0.0) ||
           (motion.pose.translation() - last->second.pose.translation()).norm() >
               kStillPoseChange ||
           Eigen::AngleAxisd(motion.pose.linear().transpose() * last->second.pose.linear())
                   .angle() > kStillPoseChange;
    postedMotions_[id] = motion;
    motions_[id] = motion;
  }
  if (!wake) return;
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    wakeRequested_ = true;
  }
  wakeUp_.notify_one();
}

void SimulationLoop::followFrames() {
  if (!frameSource_) return;
  for (const auto& entry : attachedFrames_) {
    Eigen::Isometry3d pose;
    if (!frameSource_(entry.second, pose)) continue;  // unknown or stale: hold
    // The source gives rigid, finite frames; should one not be, holding beats a crash.
    try {
      entry.first.first->moveDrag(entry.first.second, pose);
    } catch (const std::invalid_argument&) {
    }
  }
}

void SimulationLoop::followColliders(double dt) {
  collidersMoving_ = false;
  if (followed_.empty()) return;
  {
    std::lock_guard<std::mutex> lock(motionMutex_);
    incomingMotions_.swap(motions_);
    motions_.clear();
  }
  for (auto& entry : followed_) {
    Followed& f = entry.second;
    const auto sample = incomingMotions_.find(entry.first);
    if (sample != incomingMotions_.end()) {
      f.motion = sample->second;
      f.sinceSample = 0.0;
    } else if (!f.inSolver) {
      continue;  // its frame has not been seen yet
    } else if (f.sinceSample > kMaxExtrapolation) {
      // No news for a while: hold still where the last sample led.
      f.motion.linearVelocity.setZero();
      f.motion.angularVelocity.setZero();
    }
    const ColliderMotion& m = f.motion;
    try {
      if (!f.inSolver) {
        Collider c = f.collider;
        c.pose = m.pose;
        c.linearVelocity = m.linearVelocity;
        c.angularVelocity = m.angularVelocity;
        world_->setCollider(entry.first, c);
        f.inSolver = true;
      } else {
        world_->moveCollider(entry.first, m.pose, m.linearVelocity, m.angularVelocity);
      }
    } catch (const std::invalid_argument&) {
      continue;  // a non-finite sample (the node sends none): the collider stays where it was
    }
    collidersMoving_ = collidersMoving_ || !m.linearVelocity.isZero(0.0) ||
                       !m.angularVelocity.isZero(0.0);
    // Where the next step starts if no sample comes before it.
    f.motion.pose = advance(m.pose, m.linearVelocity, m.angularVelocity, dt);
    f.sinceSample += dt;
  }
  incomingMotions_.clear();
}

}  // namespace deformable_flsm
