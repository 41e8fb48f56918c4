#include "deformable_flsm/ros/collider_follower.h"

#include <tf2/exceptions.h>
#include <tf2_eigen/tf2_eigen.h>

#include <utility>

namespace deformable_flsm {

ColliderFollower::ColliderFollower(const tf2::BufferCore& buffer, std::string simFrame)
    : buffer_(buffer), simFrame_(std::move(simFrame)) {}

void ColliderFollower::follow(const std::string& id, const std::string& frame,
                              const Eigen::Isometry3d& offset, Admit admit) {
  std::lock_guard<std::mutex> lock(mutex_);
  Entry e;
  e.frame = frame;
  e.offset = offset;
  e.admit = std::move(admit);
  entries_[id] = e;
}

void ColliderFollower::forget(const std::string& id) {
  std::lock_guard<std::mutex> lock(mutex_);
  entries_.erase(id);
}

bool ColliderFollower::empty() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return entries_.empty();
}

std::uint64_t ColliderFollower::misses() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return misses_;
}

std::size_t ColliderFollower::waiting() const {
  std::lock_guard<std::mutex> lock(mutex_);
  std::size_t n = 0;
  for (const auto& item : entries_) n += item.second.seen ? 0 : 1;
  return n;
}

std::string ColliderFollower::lookup(const ros::Time& now, const std::string& id, const Entry& e,
                                     geometry_msgs::TransformStamped& t) const {
  std::string problem;
  // Latest transform, no timeout: BufferCore never waits.
  std::string error;
  if (!buffer_.canTransform(simFrame_, e.frame, ros::Time(0), &error)) {
    problem = "collider '" + id + "': frame '" + e.frame + "' unknown (" + error + ")";
  } else {
    try {
      t = buffer_.lookupTransform(simFrame_, e.frame, ros::Time(0));
    } catch (const tf2::TransformException& ex) {
      problem = "collider '" + id + "': frame '" + e.frame + "': " + ex.what();
    }
  }
  // A static transform has stamp 0 and never goes stale.
  if (problem.empty() && !t.header.stamp.isZero() &&
      (now - t.header.stamp).toSec() > kStaleAfter) {
    problem = "collider '" + id + "': the newest transform of frame '" + e.frame + "' is " +
              std::to_string((now - t.header.stamp).toSec()) + " s old";
  }
  return problem;
}

void ColliderFollower::sample(const ros::Time& now, const Post& post, Report& report) {
  std::lock_guard<std::mutex> lock(mutex_);
  for (auto it = entries_.begin(); it != entries_.end();) {
    const std::string& id = it->first;
    Entry& e = it->second;
    geometry_msgs::TransformStamped t;
    const std::string problem = lookup(now, id, e, t);
    if (!problem.empty() && !e.seen) {
      // Not a miss: the frame has not appeared yet (a publisher still starting).
      if (!e.announced) {
        report.waiting.emplace_back(id, e.frame);
        e.announced = true;
      }
      ++it;
      continue;
    }
    if (!problem.empty()) {
      ++misses_;
      report.problems.push_back(problem + ": the collider holds still");
      if (!e.holding) {
        ColliderMotion hold;
        hold.pose = e.pose;
        post(id, hold);
        e.holding = true;
      }
      ++it;
      continue;
    }
    const Eigen::Isometry3d pose = tf2::transformToEigen(t) * e.offset;
    if (!pose.matrix().allFinite()) {
      if (e.seen) ++misses_;
      report.problems.push_back("collider '" + id + "': frame '" + e.frame + "' is not finite");
      ++it;
      continue;
    }
    if (!e.seen && e.admit && !e.admit(pose)) {
      report.excluded.push_back(id);
      it = entries_.erase(it);
      continue;
    }
    // Nothing new: the simulation moves on along the velocity. A static transform (stamp 0)
    // is posted every time, so that a collider (re)added on that frame always gets its pose;
    // an unchanged pose does not wake the simulation.
    if (e.seen && !e.holding && t.header.stamp == e.stamp && !t.header.stamp.isZero()) {
      ++it;
      continue;
    }
    ColliderMotion m;
    m.pose = pose;
    const double dt = (t.header.stamp - e.stamp).toSec();
    bool steady = false;  // the velocity posted now is one a next jump can be told from
    if (e.seen && !e.holding && dt > 0.0) {
      m.linearVelocity = (pose.translation() - e.pose.translation()) / dt;
      const Eigen::AngleAxisd turn(pose.linear() * e.pose.linear().transpose());
      m.angularVelocity = turn.axis() * (turn.angle() / dt);
      // Too fast, or too sudden a change of speed (a hand standing still, then 0.22 m further in
      // one sample): placed there at rest. Moving on along the jump's velocity would carry the
      // collider past the pose tf gives, into whatever lies beyond.
      const bool sudden = e.velocityKnown && (m.linearVelocity - e.velocity).norm() > kJumpAcceleration * dt;
      if (m.linearVelocity.norm() > kJumpSpeed || sudden) {
        m.linearVelocity.setZero();
        m.angularVelocity.setZero();
        report.jumped.push_back(id);
      } else {
        steady = true;
      }
    }
    e.velocity = m.linearVelocity;
    e.velocityKnown = steady;
    e.seen = true;
    e.holding = false;
    e.stamp = t.header.stamp;
    e.pose = pose;
    post(id, m);
    ++it;
  }
}

}  // namespace deformable_flsm
