// Sleeping: a World's objects at rest are not stepped until something reaches them (see
// sleeping.h, SleepParams in world.h).
#include "deformable_flsm/core/sleeping.h"

#include "deformable_flsm/core/contact.h"
#include "number_text.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace deformable_flsm {

void SleepParams::validate() const {
  if (!std::isfinite(fraction) || fraction < 0.0)
    throw std::invalid_argument("sleep: fraction must be finite and >= 0 (got " + numberText(fraction) + "; 0 never sleeps)");
  if (!std::isfinite(hold) || !(hold > 0.0))
    throw std::invalid_argument("sleep: hold must be finite and > 0 s (got " + numberText(hold) + ")");
}

void Sleeping::setParams(const SleepParams& params, const std::vector<Solver*>& objects) {
  params.validate();
  params_ = params;
  if (params_.fraction == 0.0) wakeAll(objects);
}

void Sleeping::add(const Solver& object) {
  objects_.emplace_back();
  bound(objects_.size() - 1, object);
  wake(objects_.size() - 1, object);
}

void Sleeping::remove(std::size_t o) { objects_.erase(objects_.begin() + static_cast<std::ptrdiff_t>(o)); }

void Sleeping::wake(std::size_t o, const Solver& object) {
  Rest& r = objects_[o];
  r.asleep = false;
  r.heldFor = 0.0;
  r.step = 0.0;
  r.anchor = object.positions();
}

void Sleeping::wakeAll(const std::vector<Solver*>& objects) {
  for (std::size_t o = 0; o < objects.size(); ++o) wake(o, *objects[o]);
}

std::size_t Sleeping::count() const {
  std::size_t n = 0;
  for (const Rest& r : objects_) n += r.asleep ? 1 : 0;
  return n;
}

void Sleeping::disturb(const Collider& collider) {
  if (enabled()) disturbances_.push_back({collider, 0.0});
}

void Sleeping::bound(std::size_t o, const Solver& object) {
  const auto& x = object.positions();
  Rest& r = objects_[o];
  r.lo = r.hi = x[0];
  for (const Eigen::Vector3d& p : x) {
    r.lo = r.lo.cwiseMin(p);
    r.hi = r.hi.cwiseMax(p);
  }
}

void Sleeping::beforeStep(const std::vector<Solver*>& objects, const std::map<std::string, Collider>& colliders,
                          double timeStep) {
  const std::size_t N = objects.size();
  asleepThisStep_.assign(N, 0);
  if (!enabled()) {
    disturbances_.clear();
    return;
  }
  // colliders that move within the step: swept over it
  for (const auto& entry : colliders) {
    const Collider& c = entry.second;
    if (c.linearVelocity.isZero(0.0) && c.angularVelocity.isZero(0.0)) continue;
    double radius = std::numeric_limits<double>::infinity();  // a turning plane reaches everything
    Eigen::Vector3d lo, hi;
    if (colliderBounds(c.shape, c.pose, lo, hi)) radius = 0.5 * (hi - lo).norm() + (c.pose.translation() - 0.5 * (lo + hi)).norm();
    const double sweep = timeStep * (c.linearVelocity.norm() + (c.angularVelocity.isZero(0.0) ? 0.0 : c.angularVelocity.norm() * radius));
    disturbances_.push_back({c, sweep});
  }
  for (std::size_t o = 0; o < N; ++o) {
    Rest& r = objects_[o];
    const Solver& s = *objects[o];
    bool disturbed = s.hasPendingCommands() || (r.asleep && s.stateVersion() != r.version);
    const double reach = 2.0 * s.contactRadius();
    for (std::size_t d = 0; d < disturbances_.size() && !disturbed; ++d) {
      const Disturbance& dist = disturbances_[d];
      disturbed = boxNearCollider(dist.collider.shape, dist.collider.pose, r.lo, r.hi, dist.margin + reach);
    }
    if (disturbed) wake(o, s);
    asleepThisStep_[o] = r.asleep ? 1 : 0;
  }
  disturbances_.clear();
}

void Sleeping::afterStep(const std::vector<Solver*>& objects, const std::vector<ObjectPairWrench>& wrenches,
                         const std::vector<std::pair<std::uint32_t, std::uint32_t>>& wrenchObjects,
                         const std::vector<PairImpulse>& pairs, double timeStep) {
  if (!enabled()) return;
  measure(objects, timeStep);
  wakeTouched(objects, wrenches, wrenchObjects, pairs);
  for (std::size_t o = 0; o < objects.size(); ++o) {
    Rest& r = objects_[o];
    if (asleepThisStep_[o] || r.asleep || r.heldFor < params_.hold * (1.0 - 1e-9)) continue;
    r.asleep = true;
    Solver& s = *objects[o];
    std::fill(s.substepVelocities().begin(), s.substepVelocities().end(), Eigen::Vector3d::Zero());
    r.version = s.stateVersion();
    r.load = load_[o];
  }
}

void Sleeping::measure(const std::vector<Solver*>& objects, double timeStep) {
  for (std::size_t o = 0; o < objects.size(); ++o) {
    if (asleepThisStep_[o]) continue;
    Rest& r = objects_[o];
    const Solver& s = *objects[o];
    const auto& x = s.positions();
    const auto& v = s.velocities();
    const double limit = params_.fraction * s.lattice().objectSize();
    // mass-weighted RMS: a particle's chatter in a contact is not the object's motion
    const auto& m = s.lattice().masses();
    double moved = 0.0, speed = 0.0, mass = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      moved += m[i] * (x[i] - r.anchor[i]).squaredNorm();
      speed += m[i] * v[i].squaredNorm();
      mass += m[i];
    }
    bound(o, s);
    r.step = timeStep * std::sqrt(speed / mass);
    if (!(moved <= limit * limit * mass) || s.hasPendingCommands()) {  // a non-finite state never rests
      r.anchor = x;
      r.heldFor = 0.0;
    } else {
      r.heldFor += timeStep;
    }
  }
}

void Sleeping::wakeTouched(const std::vector<Solver*>& objects, const std::vector<ObjectPairWrench>& wrenches,
                           const std::vector<std::pair<std::uint32_t, std::uint32_t>>& wrenchObjects,
                           const std::vector<PairImpulse>& pairs) {
  const std::size_t N = objects.size();
  load_.assign(N, Eigen::Vector3d::Zero());
  for (std::size_t i = 0; i < wrenches.size(); ++i) load_[wrenchObjects[i].second] += wrenches[i].wrench.force;
  for (const PairImpulse& p : pairs) {
    if (p.contacts == 0 && p.impulse.isZero(0.0)) continue;
    const std::uint32_t ends[2][2] = {{p.a, p.b}, {p.b, p.a}};
    for (const auto& e : ends)
      if (asleepThisStep_[e[0]] && !asleepThisStep_[e[1]] &&
          objects_[e[1]].step > kWakeMotion * objects[e[1]]->contactRadius())
        wake(e[0], *objects[e[0]]);
  }
  for (std::size_t o = 0; o < N; ++o) {
    Rest& r = objects_[o];
    if (!asleepThisStep_[o] || !r.asleep) continue;
    const Solver& s = *objects[o];
    const double weight = s.lattice().totalMass() * s.params().gravity.norm();
    if ((load_[o] - r.load).norm() > kWakeLoad * weight) wake(o, s);
  }
}

}  // namespace deformable_flsm
