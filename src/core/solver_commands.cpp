// The solver's command API: pins, drags (grab, attach, move, release) and their frames through
// the sub-steps, timed forces and impulses, and the accelerations they add in a sub-step.
#include "deformable_flsm/core/solver.h"

#include "number_text.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <stdexcept>
#include <string>
#include <unordered_map>
#include <vector>

namespace deformable_flsm {

namespace {

/// A rigid transform's rotation is orthonormal with determinant 1 up to round-off; looser than
/// this is a scaled, sheared or mirrored frame, which a rigid body cannot have.
constexpr double kRigidTolerance = 1e-6;

bool isRigid(const Eigen::Isometry3d& T) {
  const Eigen::Matrix3d R = T.linear();
  return T.matrix().allFinite() && (R.transpose() * R - Eigen::Matrix3d::Identity()).norm() < kRigidTolerance &&
         std::abs(R.determinant() - 1.0) < kRigidTolerance;
}

Eigen::Vector3d centroidOf(const std::vector<Eigen::Vector3d>& x,
                           const std::vector<std::uint32_t>& particles) {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::uint32_t p : particles) c += x[p];
  return c / static_cast<double>(particles.size());
}

}  // namespace

Eigen::Vector3d Drag::centroidTarget() const {
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (const Eigen::Vector3d& o : offsets) c += o;
  if (!offsets.empty()) c /= static_cast<double>(offsets.size());
  return pose * c;
}

std::size_t Solver::pinBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, bool pinned) {
  const auto& x0 = lattice_->restPositions();
  std::size_t count = 0;
  for (std::size_t i = 0; i < x0.size(); ++i) {
    if ((x0[i].array() >= lo.array()).all() && (x0[i].array() <= hi.array()).all()) {
      setPinned(static_cast<std::uint32_t>(i), pinned);
      ++count;
    }
  }
  return count;
}

void Solver::setPinned(std::uint32_t particle, bool pinned) {
  if (particle >= pinned_.size()) throw std::out_of_range("solver: particle index out of range");
  if (pinned && !pinned_[particle]) {
    pinPosition_[particle] = x_[particle];
    v_[particle].setZero();
  }
  if (pinned != (pinned_[particle] != 0)) {
    pinned ? ++pinnedCount_ : --pinnedCount_;
    ++stateVersion_;
  }
  pinned_[particle] = pinned ? 1 : 0;
  pinnedListStale_ = true;
}

std::size_t Solver::pinnedCount() const {
  return static_cast<std::size_t>(std::count(pinned_.begin(), pinned_.end(), 1));
}

void Solver::grab(const std::string& id, const std::vector<std::uint32_t>& particles,
                  const Eigen::Vector3d& target, double stiffness) {
  if (!target.allFinite()) throw std::invalid_argument("solver: drag target must be finite");
  if (particles.empty()) throw std::invalid_argument("solver: a drag needs at least one particle");
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  // The drag frame sits at the centroid, unrotated: offsets are relative to the centroid, and
  // the frame glides from there to `target` over the first step.
  const Eigen::Isometry3d frame(Eigen::Translation3d(centroidOf(x_, particles)));
  addDrag(id, particles, frame, Eigen::Isometry3d(Eigen::Translation3d(target)), stiffness);
}

void Solver::attach(const std::string& id, const std::vector<std::uint32_t>& particles,
                    const Eigen::Isometry3d& frame, double stiffness) {
  if (!isRigid(frame))
    throw std::invalid_argument("solver: the frame to attach to must be finite and rigid (a rotation "
                                "and a translation)");
  addDrag(id, particles, frame, frame, stiffness);
}

void Solver::addDrag(const std::string& id, const std::vector<std::uint32_t>& particles,
                     const Eigen::Isometry3d& frame, const Eigen::Isometry3d& pose, double stiffness) {
  if (particles.empty()) throw std::invalid_argument("solver: a drag needs at least one particle");
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  if (!std::isfinite(stiffness) || stiffness < 0.0)
    throw std::invalid_argument("solver: drag stiffness must be finite and >= 0");
  if (stiffness > 0.0) {
    const SpringLimit limit = springLimit(id, particles);
    if (stiffness > limit.stiffness)
      throw std::invalid_argument(
          "solver: drag '" + id + "': spring stiffness " + numberText(stiffness) + " N/m is unstable on " +
          numberText(limit.mass) + " kg of particles at sub-step " + numberText(limit.substep) +
          " s: at most " + numberText(limit.stiffness) +
          " N/m (k h^2 / M <= " + numberText(kMaxSpringRate) +
          " summed over the spring drags on a particle; or 0 for a hard drag)");
  }
  Drag drag;
  drag.particles = particles;
  const Eigen::Isometry3d toFrame = frame.inverse(Eigen::Isometry);
  drag.offsets.reserve(particles.size());
  for (std::uint32_t p : particles) drag.offsets.push_back(toFrame * x_[p]);
  drag.pose = pose;
  drag.reached = frame;
  drag.frame = frame;
  drag.stiffness = stiffness;
  drags_[id] = std::move(drag);
  markHardDrags();
  reserveForcedParticles();
}

// Linearised, a spring of stiffness k on mass M adds (omega h)^2 = k h^2 / M to the modes of the
// particles it holds, and the springs on one particle add up; with shape matching's share it must
// stay below symplectic Euler's 4 (see kMaxSpringRate).
SpringLimit Solver::springLimit(const std::string& id, const std::vector<std::uint32_t>& particles) const {
  const auto& m = lattice_->masses();
  auto massOf = [&](const std::vector<std::uint32_t>& set) {
    double M = 0.0;
    for (std::uint32_t p : set) M += m[p];
    return M;
  };
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  SpringLimit limit;
  const double h = params_.substepLength();
  limit.substep = h;
  std::unordered_map<std::uint32_t, double> rate;
  for (std::uint32_t p : particles) rate[p] = 0.0;
  for (const auto& entry : drags_) {
    const Drag& d = entry.second;
    if (entry.first == id || d.stiffness <= 0.0) continue;
    const double r = d.stiffness * h * h / massOf(d.particles);
    for (std::uint32_t p : d.particles) {
      auto it = rate.find(p);
      if (it != rate.end()) limit.taken = std::max(limit.taken, it->second += r);
    }
  }
  limit.mass = massOf(particles);
  // The implicit step has the springs' stiffness in its system matrix: stable at any stiffness.
  limit.stiffness = params_.integrator == Integrator::Implicit
                        ? std::numeric_limits<double>::infinity()
                        : std::max(0.0, kMaxSpringRate - limit.taken) * limit.mass / (h * h);
  return limit;
}

// accumulateForces() lists the particles it touches; reserving here, when a command arrives,
// keeps the step itself free of allocation.
void Solver::reserveForcedParticles() {
  std::size_t total = 0;
  for (const TimedForce& f : forces_) total += f.particles.size();
  for (const auto& entry : drags_) total += entry.second.particles.size();
  forcedParticles_.reserve(total);
}

bool Solver::moveDrag(const std::string& id, const Eigen::Isometry3d& pose) {
  auto it = drags_.find(id);
  if (it == drags_.end()) return false;
  if (!isRigid(pose))
    throw std::invalid_argument("solver: a drag pose must be finite and rigid (a rotation and a "
                                "translation)");
  it->second.pose = pose;
  return true;
}

bool Solver::moveDrag(const std::string& id, const Eigen::Vector3d& target) {
  auto it = drags_.find(id);
  if (it == drags_.end()) return false;
  if (!target.allFinite()) throw std::invalid_argument("solver: drag target must be finite");
  it->second.pose.translation() = target;
  return true;
}

bool Solver::release(const std::string& id) {
  const bool found = drags_.erase(id) > 0;
  markHardDrags();
  return found;
}

void Solver::releaseAll() {
  drags_.clear();
  markHardDrags();
}

void Solver::markHardDrags() {
  std::fill(hardDragged_.begin(), hardDragged_.end(), 0);
  for (const auto& entry : drags_)
    if (entry.second.stiffness <= 0.0)
      for (std::uint32_t p : entry.second.particles) hardDragged_[p] = 1;
}

void Solver::applyImpulse(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& impulse) {
  if (particles.empty()) throw std::invalid_argument("solver: an impulse needs at least one particle");
  if (!impulse.allFinite()) throw std::invalid_argument("solver: impulse must be finite");
  const auto& m = lattice_->masses();
  double M = 0.0;
  for (std::uint32_t p : particles) {
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
    M += m[p];
  }
  for (std::uint32_t p : particles) impulseDv_[p] += impulse / M;
  impulsePending_ = true;
}

void Solver::applyForce(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& force,
                        double duration) {
  if (particles.empty()) throw std::invalid_argument("solver: a force needs at least one particle");
  if (!force.allFinite()) throw std::invalid_argument("solver: force must be finite");
  if (!(duration > 0.0) || !std::isfinite(duration))
    throw std::invalid_argument("solver: force duration must be finite and > 0");
  for (std::uint32_t p : particles)
    if (p >= x_.size()) throw std::out_of_range("solver: particle index out of range");
  forces_.push_back(TimedForce{particles, force, duration});
  reserveForcedParticles();
}

// A drag frame moved by moveDrag() between two steps goes there over the sub-steps of the next
// step: translation linearly and rotation along the shortest arc (slerp), i.e. at a constant
// linear and angular velocity, the velocity a body moving from one pose to the next has.
void Solver::interpolateDragFrames(double s) {
  for (auto& entry : drags_) {
    Drag& drag = entry.second;
    Eigen::Isometry3d& frame = drag.frame;
    if (s >= 1.0) {
      frame = drag.pose;
      continue;
    }
    const Eigen::Quaterniond from(drag.reached.linear()), to(drag.pose.linear());
    frame.linear() = from.slerp(s, to).toRotationMatrix();
    frame.translation() = drag.reached.translation() + s * (drag.pose.translation() - drag.reached.translation());
  }
}

void Solver::accumulateForces(double h) {
  // Clear only what the last sub-step wrote: with no force and no spring drag (the usual case)
  // this costs nothing.
  for (std::uint32_t p : forcedParticles_) forceAccel_[p].setZero();
  forcedParticles_.clear();
  const auto& m = lattice_->masses();
  for (const TimedForce& f : forces_) {
    double M = 0.0;
    for (std::uint32_t p : f.particles) M += m[p];
    // The last sub-step of a force applies only its remaining fraction, so that the delivered
    // impulse is exactly force * duration.
    const Eigen::Vector3d a = f.force / M * std::min(1.0, f.remaining / h);
    for (std::uint32_t p : f.particles) forceAccel_[p] += a;
    forcedParticles_.insert(forcedParticles_.end(), f.particles.begin(), f.particles.end());
  }
  for (auto& entry : drags_) {
    Drag& drag = entry.second;
    const Eigen::Isometry3d& frame = drag.frame;
    if (drag.stiffness <= 0.0) continue;
    double M = 0.0;
    for (std::uint32_t p : drag.particles) M += m[p];
    // total stiffness k shared by mass: particle force k m_i / M (target_i - x_i)
    const double k = drag.stiffness / M;
    for (std::size_t e = 0; e < drag.particles.size(); ++e) {
      const std::uint32_t p = drag.particles[e];
      const Eigen::Vector3d a = k * (frame * drag.offsets[e] - x_[p]);
      forceAccel_[p] += a;
      countDragImpulse(drag, x_[p], h * m[p] * a);
    }
    forcedParticles_.insert(forcedParticles_.end(), drag.particles.begin(), drag.particles.end());
  }
}

void Solver::applyPendingImpulses() {
  if (!impulsePending_) return;
  for (std::size_t i = 0; i < v_.size(); ++i) v_[i] += impulseDv_[i];
  std::fill(impulseDv_.begin(), impulseDv_.end(), Eigen::Vector3d::Zero());
  impulsePending_ = false;
}

bool Solver::hasPendingCommands() const { return !drags_.empty() || !forces_.empty() || impulsePending_; }

}  // namespace deformable_flsm
