/// @file collider_scene.h
/// A scene's colliders, kept once, with their poses over the step being taken: the one place a
/// sub-step's collider poses are worked out, and the one contact query every contact solver
/// (the explicit pass, the implicit solve, the object contact) asks of a collider.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/contact.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <string>
#include <vector>

namespace deformable_flsm {

/// One collider as a sub-step sees it: where it was at the step's start, and at the start
/// (before) and the end (now) of the sub-step along its velocities (advancePose()).
struct PosedCollider {
  const std::string* id = nullptr;
  const Collider* collider = nullptr;
  Eigen::Isometry3d start = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d before = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d now = Eigen::Isometry3d::Identity();
  /// its axis-aligned bounds at `now`; bounded false for an unbounded shape (the half-space)
  Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();
  bool bounded = false;

  /// False only where x is farther than `margin` from the collider (its bounds say so): a cheap
  /// test before gap().
  bool near(const Eigen::Vector3d& x, double margin) const {
    return !bounded || !((x.array() < lo.array() - margin).any() || (x.array() > hi.array() + margin).any());
  }
  /// The gap between a particle sphere of radius r centred at x and the collider at the end of
  /// the sub-step (m, negative when they overlap), and the outward normal there.
  double gap(const Eigen::Vector3d& x, double r, Eigen::Vector3d& normal) const {
    return colliderDistance(collider->shape, now, x, normal) - r;
  }
  /// The same gap for the sphere at `start` against the collider at the start of the sub-step.
  double startGap(const Eigen::Vector3d& start, double r, Eigen::Vector3d& normal) const {
    return colliderDistance(collider->shape, before, start, normal) - r;
  }
  /// The velocity of the collider's material at x (m/s).
  Eigen::Vector3d surfaceVelocity(const Eigen::Vector3d& x) const {
    return collider->linearVelocity + collider->angularVelocity.cross(x - now.translation());
  }
};

/// The colliders of a scene by id, kept once (by a World for all its objects, or by a lone
/// Solver), and posed over a step by their keeper: beginStep(), poseSubstep() for each sub-step,
/// endStep(). Every object and the object contact read the same posed() entries.
class ColliderScene {
 public:
  ColliderMap& map() { return map_; }
  const ColliderMap& map() const { return map_; }
  /// The colliders in id order (the map's), posed for the sub-step being taken.
  const std::vector<PosedCollider>& posed() const { return posed_; }
  /// After a collider was added or removed: the entries again, each at its pose.
  void changed();
  /// At the start of a step: each collider starts from its pose.
  void beginStep();
  /// Sub-step s of length H (from s H to (s + 1) H into the step): before, now and the bounds.
  void poseSubstep(int s, double H);
  /// At the end of a step of length T: each collider at its pose T after the start, written back
  /// into the map.
  void endStep(double T);

 private:
  ColliderMap map_;
  std::vector<PosedCollider> posed_;
};

}  // namespace deformable_flsm
