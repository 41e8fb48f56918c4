/// @file simulation_loop_guard.cpp
/// SimulationLoop: the last resort: a state that became non-finite or grew beyond any simulated
/// scene is reset to rest, and what led to it is described for the log.
#include "deformable_flsm/runtime/simulation_loop.h"

#include "deformable_flsm/core/contact.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

namespace deformable_flsm {

namespace {

/// Beyond this (m, m/s) a coordinate or speed means the state has blown up: subscribers get
/// float32, and a state that grows without bound passes it within a few steps of overflowing
/// that (or double) to infinity. Far beyond any simulated scene (free fall takes days to get
/// there).
constexpr double kBlownUp = 1e12;

/// true when every vector is finite and within kBlownUp.
bool allBounded(const std::vector<Eigen::Vector3d>& xs) {
  for (const Eigen::Vector3d& x : xs)
    if (!x.allFinite() || x.cwiseAbs().maxCoeff() > kBlownUp) return false;
  return true;
}

bool allFinite(const std::vector<Eigen::Quaterniond>& qs) {
  for (const Eigen::Quaterniond& q : qs)
    if (!q.coeffs().allFinite()) return false;
  return true;
}

}  // namespace

void SimulationLoop::ensureFinite() {
  for (std::size_t k = 0; k < solvers_.size(); ++k) {
    Solver* solver = solvers_[k];
    if (allBounded(solver->positions()) && allBounded(solver->velocities()) &&
        allFinite(solver->regionRotations()))
      continue;
    // It should not happen (the solver is unconditionally stable for finite input and every
    // command is range-checked); if it does, never let NaN, infinity (a float32 overflow) or a
    // rotation of NaN reach a subscriber.
    {
      std::string why = describeBlowUp(k);
      std::lock_guard<std::mutex> lock(snapshotMutex_);
      lastReset_ = std::move(why);
    }
    solver->reset();
    for (auto it = attachedFrames_.begin(); it != attachedFrames_.end();)
      it = it->first.first == solver ? attachedFrames_.erase(it) : std::next(it);
    ++diag_.solverResets;
    if (solvers_.size() == 1) timeOrigin_ = world_->time();  // the scene is back at its start
    restartStillness();
  }
}

void SimulationLoop::resetAll() {
  for (Solver* solver : solvers_) solver->reset();
  timeOrigin_ = world_->time();
  attachedFrames_.clear();
  restartStillness();
}

std::string SimulationLoop::lastResetCause() const {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  return lastReset_;
}

// What a user (or a bug report) needs to tell where a blown-up state came from: the first
// particle out of bounds, the colliders by their distance from it, the drags and forces
// acting, the material and the commands the loop applied since its last snapshot.
std::string SimulationLoop::describeBlowUp(std::size_t k) const {
  const Solver& solver = *solvers_[k];
  const auto& x = solver.positions();
  const auto& v = solver.velocities();
  std::ostringstream out;
  out.precision(3);
  out << "object '" << names_[k] << "': ";
  std::size_t bad = x.size();
  for (std::size_t i = 0; i < x.size() && bad == x.size(); ++i) {
    const bool ok = x[i].allFinite() && v[i].allFinite() && x[i].cwiseAbs().maxCoeff() <= kBlownUp &&
                    v[i].cwiseAbs().maxCoeff() <= kBlownUp;
    if (!ok) bad = i;
  }
  if (bad < x.size()) {
    out << "particle " << bad << " at (" << x[bad].transpose() << ") m with velocity ("
        << v[bad].transpose() << ") m/s";
  } else {
    out << "a region rotation is not finite";
  }
  const Eigen::Vector3d at = bad < x.size() ? lattices_[k]->restPositions()[bad] : Eigen::Vector3d::Zero();
  out << "; colliders (distance from that particle's rest position, m):";
  for (const auto& entry : solver.colliders()) {
    Eigen::Vector3d normal;
    const double d = colliderDistance(entry.second.shape, entry.second.pose, at, normal);
    out << ' ' << entry.first << " (" << toString(entry.second.shape.type) << ", " << d << ")";
  }
  out << "; " << solver.drags().size() << " drag(s), " << solver.activeForces().size()
      << " timed force(s), " << solver.pinnedCount() << " pinned";
  const SolverParams& p = solver.params();
  out << "; alpha " << solver.alpha() << ", E " << p.youngsModulus << " Pa, damping " << p.damping
      << ", ambient " << p.ambientDamping << ", gravity (" << p.gravity.transpose() << ")";
  out << "; commands applied since the last snapshot:";
  static const char* const kNames[] = {"grab", "attach", "move", "release", "force", "reset",
                                       "release_all", "pin_box", "params", "set_collider",
                                       "move_collider", "remove_collider", "add_object",
                                       "remove_object", "pause", "step"};
  static_assert(sizeof(kNames) / sizeof(kNames[0]) == std::variant_size_v<CommandBody>,
                "a name for every command");
  bool any = false;
  for (std::size_t k = 0; k < appliedKinds_.size(); ++k) {
    if (appliedKinds_[k] == 0) continue;
    out << ' ' << kNames[k] << ' ' << appliedKinds_[k];
    any = true;
  }
  if (!any) out << " none";
  return out.str();
}

}  // namespace deformable_flsm
