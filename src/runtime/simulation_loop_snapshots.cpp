/// @file simulation_loop_snapshots.cpp
/// SimulationLoop: what the loop hands out: snapshots of every object (positions, frames, drags,
/// contact wrenches) under one stamp, and the idling that stops stepping a scene at rest.
#include "deformable_flsm/runtime/simulation_loop.h"

#include <algorithm>
#include <cmath>
#include <mutex>

namespace deformable_flsm {

const Snapshot& SimulationLoop::acquire() {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  if (fresh_) {
    std::swap(front_, ready_);
    fresh_ = false;
  }
  return buffers_[front_];
}

void SimulationLoop::copySummary(Snapshot& out) const {
  // The newest complete buffer: ready_ while fresh, else the one acquire() handed out. The
  // simulation thread writes only back_, and indices move only under the lock.
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  const Snapshot& s = buffers_[fresh_ ? ready_ : front_];
  out.sequence = s.sequence;
  out.time = s.time;
  out.timeStarted = s.timeStarted;
  out.wallTime = s.wallTime;
  out.objects.resize(s.objects.size());
  for (std::size_t k = 0; k < s.objects.size(); ++k) {
    const ObjectSnapshot& from = s.objects[k];
    ObjectSnapshot& to = out.objects[k];
    to.name = from.name;
    to.version = from.version;
    to.drags = from.drags;
    to.objectFrame = from.objectFrame;
    to.diag = from.diag;
  }
  out.colliders = s.colliders;
  out.diag = s.diag;
}

void SimulationLoop::copyState(Snapshot& out) const {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  const Snapshot& s = buffers_[fresh_ ? ready_ : front_];
  if (out.sequence == s.sequence) return;  // it has this one: no copy under the lock
  out.sequence = s.sequence;
  out.time = s.time;
  out.timeStarted = s.timeStarted;
  out.wallTime = s.wallTime;
  out.objects = s.objects;  // the sizes of the last copy: no allocation while they stay
  out.colliders = s.colliders;
  out.diag = s.diag;
}

Eigen::Vector3d SimulationLoop::centerOfMass(std::size_t object) const {
  return centerOfMass(startNames_.at(object));
}

Eigen::Vector3d SimulationLoop::centerOfMass(const std::string& name) const {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  const auto it = centerOfMass_.find(name);
  return it == centerOfMass_.end() ? Eigen::Vector3d::Zero() : it->second;
}

void SimulationLoop::updateStillness(double simulated) {
  double maxSpeed2 = 0.0, energy = 0.0;
  bool moving = collidersMoving_;
  for (std::size_t k = 0; k < solvers_.size(); ++k) {
    const Solver& solver = *solvers_[k];
    for (const Eigen::Vector3d& v : solver.velocities()) maxSpeed2 = std::max(maxSpeed2, v.squaredNorm());
    energy += solver.kineticEnergy();
    // each object against its own size: a small object among large ones rests as precisely
    const std::vector<Eigen::Vector3d>& x = solver.positions();
    const std::vector<Eigen::Vector3d>& from = stillFrom_[k];
    double moved2 = 0.0;
    for (std::size_t i = 0; i < x.size(); ++i) moved2 = std::max(moved2, (x[i] - from[i]).squaredNorm());
    const double limit = settings_.restFraction * lattices_[k]->objectSize();
    moving = moving || moved2 > limit * limit || solver.hasPendingCommands();
  }
  diag_.maxSpeed = std::sqrt(maxSpeed2);
  diag_.kineticEnergy = energy;
  if (moving) {
    restartStillness();
  } else {
    stillFor_ += simulated;
  }
  // As fast as the machine can (a real-time factor of 0) never rests: the time is the steps.
  if (settings_.idleHold > 0.0 && stillFor_ >= settings_.idleHold && realTimeFactor_.load() > 0.0) {
    std::lock_guard<std::mutex> lock(queueMutex_);
    // A command that came in during the step keeps the loop awake.
    if (queue_.empty() && !wakeRequested_) idle_ = true;
  }
  diag_.idle = idle_;
}

void SimulationLoop::restartStillness() {
  stillFor_ = 0.0;
  for (std::size_t k = 0; k < solvers_.size(); ++k)
    std::copy(solvers_[k]->positions().begin(), solvers_[k]->positions().end(), stillFrom_[k].begin());
}

void SimulationLoop::writeObject(const Solver& solver, std::size_t k, ObjectSnapshot& o) {
  const std::size_t n = solver.positions().size();
  o.name = names_[k];
  o.positions = solver.positions();  // same size every time: copies, no allocation
  o.rotations = solver.regionRotations();
  o.pinned.resize(n);
  for (std::size_t i = 0; i < n; ++i) o.pinned[i] = solver.isPinned(static_cast<std::uint32_t>(i));
  o.drags.clear();
  for (const auto& entry : solver.drags()) {
    DragView d;
    d.id = entry.first;
    for (std::uint32_t p : entry.second.particles) d.centroid += o.positions[p];
    d.centroid /= static_cast<double>(entry.second.particles.size());
    d.target = entry.second.centroidTarget();
    // finite with a finite state (ensureFinite()); never handed out otherwise
    const bool finite = entry.second.force.allFinite() && entry.second.torque.allFinite();
    d.force = finite ? entry.second.force : Eigen::Vector3d::Zero();
    d.torque = finite ? entry.second.torque : Eigen::Vector3d::Zero();
    d.particles = entry.second.particles.size();
    o.drags.push_back(std::move(d));
  }
  const Eigen::Isometry3d rigid = solver.rigidFrame();
  o.objectFrame = rigid * Eigen::Translation3d(restCenterOfMass_[k]);

  // A new version when the object moved visibly (the rest threshold) or its pins or drags
  // changed since the last one; the first snapshot is the first version.
  Version& v = versions_[k];
  bool changed = v.sequence == 0 || v.pinned != solver.pinnedCount() || v.drags != o.drags.size();
  const double limit = settings_.restFraction * lattices_[k]->objectSize();
  for (std::size_t i = 0; i < n && !changed; ++i)
    changed = (o.positions[i] - v.positions[i]).squaredNorm() > limit * limit;
  if (changed) {
    v.sequence = sequence_;
    v.positions = o.positions;  // same size every time: copies, no allocation after the first
    v.pinned = solver.pinnedCount();
    v.drags = o.drags.size();
  }
  o.version = v.sequence;

  // Figures that need the whole state, computed once here for every reader.
  LoopDiagnostics& d = o.diag;
  d = diag_;  // the loop's pace and counts
  d.idle = d.idle || world_->asleep(names_[k]);  // the world does not step it
  const auto& x0 = lattices_[k]->restPositions();
  double shape2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) shape2 += (o.positions[i] - rigid * x0[i]).squaredNorm();
  d.shapeError = n > 0 ? std::sqrt(shape2 / static_cast<double>(n)) : 0.0;
  d.maxDisplacement = solver.maxDisplacement();
  d.kineticEnergy = solver.kineticEnergy();
  double maxSpeed2 = 0.0;
  for (const Eigen::Vector3d& v : solver.velocities()) maxSpeed2 = std::max(maxSpeed2, v.squaredNorm());
  d.maxSpeed = std::sqrt(maxSpeed2);
  d.pinned = solver.pinnedCount();
  d.drags = solver.drags().size();
  d.forces = solver.activeForces().size();
  d.stiffnessSaturated = solver.stiffnessSaturated();
  d.alpha = solver.alpha();
}

void SimulationLoop::writeSnapshot() {
  Snapshot& s = buffers_[back_];
  s.sequence = ++sequence_;
  s.time = clockTime();
  s.timeStarted = settings_.time != LoopTime::Followed || clockStarted_;
  diag_.simTime = world_->time() - timeOrigin_;
  diag_.idle = idle_;
  diag_.paused = paused_;
  s.objects.resize(solvers_.size());
  LoopDiagnostics whole = diag_;
  whole.shapeError = whole.maxDisplacement = whole.kineticEnergy = whole.maxSpeed = 0.0;
  whole.pinned = whole.drags = whole.forces = 0;
  whole.stiffnessSaturated = false;
  for (std::size_t k = 0; k < solvers_.size(); ++k) {
    ObjectSnapshot& o = s.objects[k];
    writeObject(*solvers_[k], k, o);
    whole.shapeError = std::max(whole.shapeError, o.diag.shapeError);
    whole.maxDisplacement = std::max(whole.maxDisplacement, o.diag.maxDisplacement);
    whole.maxSpeed = std::max(whole.maxSpeed, o.diag.maxSpeed);
    whole.kineticEnergy += o.diag.kineticEnergy;
    whole.pinned += o.diag.pinned;
    whole.drags += o.diag.drags;
    whole.forces += o.diag.forces;
    whole.stiffnessSaturated = whole.stiffnessSaturated || o.diag.stiffnessSaturated;
  }
  whole.alpha = s.objects.front().diag.alpha;
  diag_ = whole;
  s.diag = diag_;
  // The colliders are the world's, the same in every object.
  s.colliders = solvers_.front()->colliders();
  s.wrenches.clear();
  for (const auto& entry : s.colliders) s.wrenches[entry.first] = world_->contactWrench(entry.first);
  s.objectWrenches = world_->objectWrenches();
  for (const std::string& id : world_->recordedColliders()) {
    std::vector<ParticleContact>& all = s.contacts[id];
    all.clear();
    for (const Solver* solver : solvers_) {
      const std::vector<ParticleContact>& one = solver->recordedContacts(id);
      all.insert(all.end(), one.begin(), one.end());
    }
  }

  s.wallTime = clock_->wallNow();  // as it is handed out: no reader stamps later before it
  {
    std::lock_guard<std::mutex> lock(snapshotMutex_);
    for (const ObjectSnapshot& o : s.objects) centerOfMass_[o.name] = o.objectFrame.translation();
    std::swap(back_, ready_);
    fresh_ = true;
  }
  appliedKinds_.fill(0);
  // The buffer just written stays ready_ or front_ until the next writeSnapshot(): reading it
  // here, on the only thread that writes, races with nobody. The state before the thread
  // starts is no tick: the time has not begun.
  if (tickObserver_ && running_ && s.time > observed_) {
    observed_ = s.time;
    tickObserver_(s.time, &s);
  }
}

}  // namespace deformable_flsm
