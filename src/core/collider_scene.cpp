// A scene's colliders and their poses over a step (collider_scene.h).
#include "deformable_flsm/core/collider_scene.h"

#include <stdexcept>

namespace deformable_flsm {

namespace {

void placeAt(PosedCollider& p, const Eigen::Isometry3d& pose) {
  p.start = p.before = p.now = pose;
  p.bounded = colliderBounds(p.collider->shape, pose, p.lo, p.hi);
}

}  // namespace

void ColliderScene::changed() {
  posed_.clear();
  posed_.reserve(map_.size());
  for (const auto& entry : map_) {
    PosedCollider p;
    p.id = &entry.first;
    p.collider = &entry.second;
    placeAt(p, entry.second.pose);
    posed_.push_back(p);
  }
}

void ColliderScene::beginStep() {
  for (PosedCollider& p : posed_) placeAt(p, p.collider->pose);
}

void ColliderScene::poseSubstep(int s, double H) {
  for (PosedCollider& p : posed_) {
    const Collider& c = *p.collider;
    p.before = advancePose(p.start, c.linearVelocity, c.angularVelocity, s * H);
    p.now = advancePose(p.start, c.linearVelocity, c.angularVelocity, (s + 1) * H);
    p.bounded = colliderBounds(c.shape, p.now, p.lo, p.hi);
  }
}

void ColliderScene::endStep(double T) {
  if (posed_.size() != map_.size()) throw std::logic_error("collider scene: changed() not called after a change");
  auto it = map_.begin();
  for (PosedCollider& p : posed_) {
    Collider& c = (it++)->second;
    p.before = p.now = advancePose(p.start, c.linearVelocity, c.angularVelocity, T);
    c.pose = p.now;
  }
}

}  // namespace deformable_flsm
