/// @file simulation_loop_commands.cpp
/// SimulationLoop: the command rules that depend on the state: each command applied to the world
/// between two steps, accepted or refused with a reason (a spring too stiff for its particles, a
/// selection that is empty, an impulse or force too large for the mass it acts on, an unknown
/// collider).
#include "deformable_flsm/runtime/simulation_loop.h"

#include "deformable_flsm/runtime/collider_spec.h"
#include "deformable_flsm/runtime/object_spec.h"
#include "deformable_flsm/runtime/scene.h"

#include <algorithm>
#include <cmath>
#include <iterator>
#include <stdexcept>
#include <sstream>
#include <string>
#include <utility>
#include <variant>

namespace deformable_flsm {

namespace {

std::string num(double v) {
  std::ostringstream os;
  os.precision(3);
  os << v;
  return os.str();
}

CommandOutcome accepted(std::string message, std::size_t particles = 0) {
  CommandOutcome o;
  o.accepted = true;
  o.message = std::move(message);
  o.particles = particles;
  return o;
}

}  // namespace

bool SimulationLoop::apply(Command& command) {
  CommandOutcome outcome;
  // Adding and removing an object concern the scene: their body names the object.
  const bool sceneCommand = std::holds_alternative<AddObjectCommand>(command.body) ||
                            std::holds_alternative<RemoveObjectCommand>(command.body);
  target_ = command.object.empty() || sceneCommand ? solvers_.front() : world_->object(command.object);
  if (target_ == nullptr) {
    outcome = reject("unknown_object", "object '" + command.object +
                                           "' is not in the scene (removed): command refused");
  } else {
    outcome = applyBody(command);
  }
  if (outcome.accepted) stats_->accept();
  if (sceneCommand) target_ = solvers_.front();  // the first may have been removed
  outcome.pinnedTotal = target_ != nullptr ? target_->pinnedCount() : 0;
  if (outcome.accepted && std::holds_alternative<StepCommand>(command.body)) {
    // answered once its steps are taken (stepOnRequest())
    stepAnswer_ = std::move(command.outcome);
    return false;  // nothing has changed yet
  }
  if (command.outcome) command.outcome->set_value(outcome);
  // Pausing changes no state; it is no reason to wake or step.
  return outcome.accepted && !std::holds_alternative<PauseCommand>(command.body);
}

CommandOutcome SimulationLoop::applyBody(Command& command) {
  return std::visit(
      [&](const auto& c) -> CommandOutcome {
        using T = std::decay_t<decltype(c)>;
        if constexpr (std::is_same_v<T, GrabCommand>) {
          return grab(c);
        } else if constexpr (std::is_same_v<T, AttachCommand>) {
          return grab(c.grab, &c);
        } else if constexpr (std::is_same_v<T, MoveCommand>) {
          return move(c);
        } else if constexpr (std::is_same_v<T, ReleaseCommand>) {
          return release(c);
        } else if constexpr (std::is_same_v<T, ApplyForceCommand>) {
          return force(c);
        } else if constexpr (std::is_same_v<T, PauseCommand>) {
          return pause(c);
        } else if constexpr (std::is_same_v<T, StepCommand>) {
          return stepWhilePaused(c);
        } else if constexpr (std::is_same_v<T, ResetCommand>) {
          resetAll();
          return accepted("reset to rest; pins kept, drags and forces released");
        } else if constexpr (std::is_same_v<T, ReleaseAllCommand>) {
          std::size_t n = 0;
          for (Solver* solver : solvers_) {
            n += solver->drags().size();
            solver->releaseAll();
          }
          attachedFrames_.clear();
          return accepted("released " + std::to_string(n) + " drag(s)");
        } else if constexpr (std::is_same_v<T, PinBoxCommand>) {
          return pinBox(c);
        } else if constexpr (std::is_same_v<T, ParamsCommand>) {
          return setParams(c);
        } else if constexpr (std::is_same_v<T, SetColliderCommand>) {
          return setCollider(c);
        } else if constexpr (std::is_same_v<T, MoveColliderCommand>) {
          return moveCollider(c);
        } else if constexpr (std::is_same_v<T, AddObjectCommand>) {
          return addObject(c);
        } else if constexpr (std::is_same_v<T, RemoveObjectCommand>) {
          return removeObject(c);
        } else {
          static_assert(std::is_same_v<T, RemoveColliderCommand>, "a command is not handled");
          return removeCollider(c);
        }
      },
      command.body);
}

CommandOutcome SimulationLoop::reject(const std::string& reason, const std::string& detail) {
  stats_->reject(reason, detail);
  CommandOutcome o;
  o.message = detail;
  return o;
}

double SimulationLoop::massOf(const std::vector<std::uint32_t>& particles) const {
  double m = 0.0;
  for (std::uint32_t p : particles) m += target_->lattice().masses()[p];
  return m;
}

CommandOutcome SimulationLoop::grab(const GrabCommand& c, const AttachCommand* attach) {
  const std::size_t n = target_->lattice().size();
  if (c.particle >= static_cast<std::int64_t>(n))
    return reject("bad_index", "drag '" + c.id + "': particle " + std::to_string(c.particle) +
                                   " out of range [0, " + std::to_string(n) + ")");
  if (target_->drags().count(c.id) == 0 && target_->drags().size() >= CommandLimits::kMaxDrags)
    return reject("too_many_drags", "drag '" + c.id + "': already " +
                                        std::to_string(CommandLimits::kMaxDrags) +
                                        " drags; release one first");
  const std::vector<std::uint32_t> particles =
      c.particle >= 0 ? std::vector<std::uint32_t>{static_cast<std::uint32_t>(c.particle)}
                      : target_->nearestParticles(c.point, c.count);
  if (c.stiffness > 0.0) {
    // the core's rule (Solver::springLimit()), refused here with its reason and counted
    const SpringLimit limit = target_->springLimit(c.id, particles);
    if (c.stiffness > limit.stiffness)
      return reject("spring_too_stiff",
                    "drag '" + c.id + "': spring stiffness " + num(c.stiffness) +
                        " N/m is unstable on " + num(limit.mass) +
                        " kg of particles at sub-step " + num(limit.substep) + " s" +
                        (limit.taken > 0.0 ? " with the other spring drags on them (" +
                                                 num(100.0 * limit.taken / kMaxSpringRate) +
                                                 " % of the limit taken)"
                                           : std::string()) +
                        ": at most " + num(limit.stiffness) + " N/m (or 0 for a hard drag)");
  }
  if (attach == nullptr) {
    target_->grab(c.id, particles, c.target, c.stiffness);
    attachedFrames_.erase({target_, c.id});
    return accepted("drag '" + c.id + "' holds " + std::to_string(particles.size()) +
                        " particle(s)",
                    particles.size());
  }
  try {
    target_->attach(c.id, particles, attach->pose, c.stiffness);
  } catch (const std::invalid_argument& e) {
    return reject("bad_frame", "attach '" + c.id + "' to frame '" + attach->frame + "': " + e.what());
  }
  if (attach->frame.empty())
    attachedFrames_.erase({target_, c.id});
  else
    attachedFrames_[{target_, c.id}] = attach->frame;
  return accepted("drag '" + c.id + "' holds " + std::to_string(particles.size()) +
                      " particle(s)" +
                      (attach->frame.empty() ? std::string(" where they are")
                                             : " attached to frame '" + attach->frame + "'"),
                  particles.size());
}

CommandOutcome SimulationLoop::move(const MoveCommand& c) {
  const auto attached = attachedFrames_.find({target_, c.id});
  if (attached != attachedFrames_.end())
    return reject("attached_drag", "move of drag '" + c.id + "': it follows frame '" +
                                       attached->second +
                                       "'; RELEASE it, or ATTACH it to another frame");
  if (!target_->moveDrag(c.id, c.target))
    return reject("unknown_drag", "move of drag '" + c.id + "': no such drag (grab first)");
  return accepted("drag '" + c.id + "' moved");
}

CommandOutcome SimulationLoop::release(const ReleaseCommand& c) {
  attachedFrames_.erase({target_, c.id});
  if (!target_->release(c.id))
    return reject("unknown_drag", "release of drag '" + c.id + "': no such drag");
  return accepted("drag '" + c.id + "' released");
}

CommandOutcome SimulationLoop::force(const ApplyForceCommand& c) {
  const std::size_t n = target_->lattice().size();
  if (c.particle >= static_cast<std::int64_t>(n))
    return reject("bad_index", "force: particle " + std::to_string(c.particle) +
                                   " out of range [0, " + std::to_string(n) + ")");
  if (!c.impulse && target_->activeForces().size() >= CommandLimits::kMaxForces)
    return reject("too_many_forces", "force: already " +
                                         std::to_string(CommandLimits::kMaxForces) +
                                         " forces acting; wait for some to end");
  std::vector<std::uint32_t> particles;
  if (c.particle >= 0)
    particles.push_back(static_cast<std::uint32_t>(c.particle));
  else if (c.radius > 0.0)
    particles = target_->particlesWithin(c.point, c.radius);
  else
    particles = target_->nearestParticles(c.point, 1);
  if (particles.empty())
    return reject("empty_selection", "force: no particle within " + num(c.radius) +
                                         " m of the point; aim at the object or widen the radius");
  const double mass = massOf(particles);
  const double size = target_->lattice().objectSize();
  const double magnitude = c.force.norm();
  if (c.impulse) {
    const double limit = CommandLimits::kMaxSpeedChange * size * mass;
    if (magnitude > limit)
      return reject("too_large", "impulse " + num(magnitude) + " N s on " + num(mass) +
                                     " kg would change their speed by more than " +
                                     num(CommandLimits::kMaxSpeedChange * size) +
                                     " m/s: at most " + num(limit) + " N s");
    target_->applyImpulse(particles, c.force);
  } else {
    const double limit = CommandLimits::kMaxAcceleration * size * mass;
    if (magnitude > limit)
      return reject("too_large", "force " + num(magnitude) + " N on " + num(mass) +
                                     " kg would accelerate them by more than " +
                                     num(CommandLimits::kMaxAcceleration * size) +
                                     " m/s^2: at most " + num(limit) + " N");
    target_->applyForce(particles, c.force, c.duration);
  }
  return accepted(std::string(c.impulse ? "impulse" : "force") + " on " +
                      std::to_string(particles.size()) + " particle(s)",
                  particles.size());
}

CommandOutcome SimulationLoop::pinBox(const PinBoxCommand& c) {
  const std::size_t count = target_->pinBox(c.lo, c.hi, c.pin);
  return accepted(std::string(c.pin ? "pinned " : "freed ") + std::to_string(count) +
                      " particle(s) in the box",
                  count);
}

CommandOutcome SimulationLoop::setParams(const ParamsCommand& c) {
  try {
    target_->setParams(c.params);
  } catch (const std::invalid_argument& e) {
    return reject("invalid_params", e.what());
  }
  return accepted("solver parameters set");
}

CommandOutcome SimulationLoop::setCollider(const SetColliderCommand& c) {
  const bool known = target_->colliders().count(c.id) > 0 || followed_.count(c.id) > 0;
  std::size_t count = target_->colliders().size();
  for (const auto& entry : followed_) count += entry.second.inSolver ? 0 : 1;
  if (!known && count >= ColliderLimits::kMaxColliders)
    return reject("too_many_colliders", "collider '" + c.id + "': already " +
                                            std::to_string(ColliderLimits::kMaxColliders) +
                                            " colliders; remove one first");
  try {
    c.collider.validate();
    if (c.followFrame.empty()) {
      world_->setCollider(c.id, c.collider);
    } else {
      // In the solver from its first sampled pose on (followColliders()).
      world_->removeCollider(c.id);
    }
  } catch (const std::exception& e) {  // invalid_argument, or MeshError for an open mesh
    return reject("bad_collider", "collider '" + c.id + "': " + e.what());
  }
  if (c.followFrame.empty()) {
    followed_.erase(c.id);
    return accepted("collider '" + c.id + "' " + (known ? "replaced" : "added"));
  }
  // Its motions come from the node's follower, which learnt of the new frame and offset before
  // this command was sent: a motion already waiting is this collider's.
  Followed f;
  f.collider = c.collider;
  followed_[c.id] = f;
  return accepted("collider '" + c.id + "' follows frame '" + c.followFrame +
                  "' from its first transform on");
}

CommandOutcome SimulationLoop::moveCollider(const MoveColliderCommand& c) {
  if (followed_.count(c.id) > 0)
    return reject("collider_follows_frame",
                  "move of collider '" + c.id + "': it follows a tf frame; move the frame, or "
                  "ADD it again without follow_frame");
  try {
    if (!world_->moveCollider(c.id, c.pose, c.linearVelocity, c.angularVelocity))
      return reject("unknown_collider",
                    "move of collider '" + c.id + "': no such collider (ADD it first)");
  } catch (const std::invalid_argument& e) {
    return reject("non_finite", "move of collider '" + c.id + "': " + e.what());
  }
  return accepted("collider '" + c.id + "' moved");
}

CommandOutcome SimulationLoop::removeCollider(const RemoveColliderCommand& c) {
  const bool followed = followed_.erase(c.id) > 0;
  if (!world_->removeCollider(c.id) && !followed)
    return reject("unknown_collider", "removal of collider '" + c.id + "': no such collider");
  return accepted("collider '" + c.id + "' removed");
}

CommandOutcome SimulationLoop::addObject(const AddObjectCommand& c) {
  if (!c.lattice) return reject("invalid_object", "object '" + c.name + "': no lattice");
  if (world_->objectCount() >= ObjectLimits::kMaxObjects)
    return reject("too_many_objects", "object '" + c.name + "': the scene has " +
                                          std::to_string(world_->objectCount()) + " objects, the most it may hold");
  try {
    world_->addObject(c.name, c.lattice, c.params);
  } catch (const std::invalid_argument& e) {  // a duplicate name, objects inside each other
    return reject("invalid_object", std::string("object '") + c.name + "' cannot be added: " + e.what());
  }
  trackObject(c.name);
  restartStillness();
  return accepted("added object '" + c.name + "' (" + std::to_string(c.lattice->size()) + " particles)",
                  c.lattice->size());
}

CommandOutcome SimulationLoop::removeObject(const RemoveObjectCommand& c) {
  const auto it = std::find(names_.begin(), names_.end(), c.name);
  if (it == names_.end())
    return reject("unknown_object", "object '" + c.name + "' is not in the scene: nothing removed");
  if (names_.size() == 1)
    return reject("invalid_object", "object '" + c.name + "' is the scene's last object: a scene "
                                    "keeps at least one (add another first)");
  const std::size_t k = static_cast<std::size_t>(it - names_.begin());
  const std::size_t particles = lattices_[k]->size();
  untrackObject(k);
  world_->removeObject(c.name);
  restartStillness();
  return accepted("removed object '" + c.name + "'", particles);
}

void SimulationLoop::trackObject(const std::string& name) {
  Solver* solver = world_->object(name);
  const Lattice& L = solver->lattice();  // immutable, owned through the solver
  Eigen::Vector3d com = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < L.size(); ++i) com += L.masses()[i] * L.restPositions()[i];
  com /= L.totalMass();
  names_.push_back(name);
  solvers_.push_back(solver);
  lattices_.push_back(&L);
  restCenterOfMass_.push_back(com);
  stillFrom_.push_back(solver->positions());
  versions_.emplace_back();
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  centerOfMass_[name] = com;
}

void SimulationLoop::untrackObject(std::size_t k) {
  Solver* solver = solvers_[k];
  for (auto it = attachedFrames_.begin(); it != attachedFrames_.end();)
    it = it->first.first == solver ? attachedFrames_.erase(it) : std::next(it);
  const auto at = [k](auto& list) { list.erase(list.begin() + static_cast<std::ptrdiff_t>(k)); };
  at(names_);
  at(solvers_);
  at(lattices_);
  at(restCenterOfMass_);
  at(stillFrom_);
  at(versions_);
}

CommandOutcome SimulationLoop::pause(const PauseCommand& c) {
  const bool was = paused_;
  paused_ = c.pause;
  diag_.paused = paused_;
  if (was && !paused_) resumed_ = true;
  if (!paused_ && stepAnswer_) {
    // steps asked for and not all taken: the answer says how far they got
    CommandOutcome o;
    o.accepted = true;
    o.message = "unpaused with " + std::to_string(stepsRequested_) + " of the steps asked for not taken";
    stepAnswer_->set_value(o);
    stepAnswer_.reset();
    stepsRequested_ = 0;
  }
  if (was == paused_) return accepted(paused_ ? "already paused" : "already running");
  writeSnapshot();  // the same state, now paused or running: readers see it at once
  return accepted(paused_ ? "paused" : "running");
}

CommandOutcome SimulationLoop::stepWhilePaused(const StepCommand& c) {
  if (!paused_)
    return reject("not_paused", "a step was asked for while the simulation runs: pause it first "
                                "(~pause), or start it paused (~start_paused)");
  if (settings_.time == LoopTime::Followed)
    return reject("not_paused", "a step was asked for while the simulation follows another clock "
                                "(~clock follow): that clock paces the steps; step the simulator "
                                "that serves it, or use ~clock sim for lockstep");
  if (c.steps < 1 || c.steps > CommandLimits::kMaxSteps)
    return reject("invalid_steps", "steps is " + std::to_string(c.steps) + ": it must be 1 to " +
                                       std::to_string(CommandLimits::kMaxSteps));
  if (stepsRequested_ > 0)
    return reject("step_pending", "the steps asked for before are not taken yet: ask again once "
                                  "they are answered");
  stepsRequested_ = c.steps;
  return accepted("stepping " + std::to_string(c.steps) + " step(s)");
}

}  // namespace deformable_flsm
