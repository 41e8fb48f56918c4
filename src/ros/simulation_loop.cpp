#include "deformable_flsm/ros/simulation_loop.h"

#include <algorithm>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace deformable_flsm {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

bool allFinite(const std::vector<Eigen::Vector3d>& xs) {
  for (const Eigen::Vector3d& x : xs)
    if (!x.allFinite()) return false;
  return true;
}

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

SimulationLoop::SimulationLoop(std::unique_ptr<Solver> solver, const LoopSettings& settings,
                               std::shared_ptr<CommandStats> stats)
    : solver_(std::move(solver)), settings_(settings), stats_(std::move(stats)),
      realTimeFactor_(settings.realTimeFactor) {
  if (!solver_) throw std::invalid_argument("SimulationLoop: no solver");
  if (!stats_) throw std::invalid_argument("SimulationLoop: no command statistics");
  if (!(settings_.realTimeFactor > 0.0) || settings_.maxCatchUpSteps < 1)
    throw std::invalid_argument("SimulationLoop: real-time factor must be > 0 and catch-up >= 1");
  lattice_ = &solver_->lattice();  // immutable, owned through the solver
  const Lattice& L = solver_->lattice();
  for (std::size_t i = 0; i < L.size(); ++i)
    restCenterOfMass_ += L.masses()[i] * L.restPositions()[i];
  restCenterOfMass_ /= L.totalMass();
  centerOfMass_ = restCenterOfMass_;
  diag_.requestedRealTimeFactor = settings_.realTimeFactor;
  queue_.reserve(CommandLimits::kQueueCapacity);
}

SimulationLoop::~SimulationLoop() { stop(); }

void SimulationLoop::start() {
  if (thread_.joinable()) return;
  ensureFinite();
  writeSnapshot();  // the rest state, so that readers have something before the first step
  thread_ = std::thread(&SimulationLoop::run, this);
}

void SimulationLoop::stop() {
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    stopRequested_ = true;
  }
  wakeUp_.notify_all();
  if (thread_.joinable()) thread_.join();
  // Nobody will apply what is left: answer whoever waits.
  std::vector<Command> left;
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    left.swap(queue_);
  }
  for (Command& c : left) {
    if (c.outcome) {
      CommandOutcome o;
      o.message = "the simulation is shutting down";
      c.outcome->set_value(o);
    }
  }
}

bool SimulationLoop::submit(Command command) {
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    if (!stopRequested_ && queue_.size() < CommandLimits::kQueueCapacity) {
      queue_.push_back(std::move(command));
      wakeUp_.notify_one();
      return true;
    }
  }
  const CommandOutcome o =
      reject("queue_full", "command queue full (" + std::to_string(CommandLimits::kQueueCapacity) +
                               " waiting): commands arrive faster than the simulation steps; "
                               "send fewer (one per step is plenty)");
  if (command.outcome) command.outcome->set_value(o);
  return false;
}

void SimulationLoop::setRealTimeFactor(double realTimeFactor) {
  if (!(realTimeFactor > 0.0) || !std::isfinite(realTimeFactor))
    throw std::invalid_argument("real-time factor must be finite and > 0");
  realTimeFactor_.store(realTimeFactor);
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    wakeRequested_ = true;
  }
  wakeUp_.notify_one();
}

const Snapshot& SimulationLoop::acquire() {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  if (fresh_) {
    std::swap(front_, ready_);
    fresh_ = false;
  }
  return buffers_[front_];
}

Eigen::Vector3d SimulationLoop::centerOfMass() const {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  return centerOfMass_;
}

void SimulationLoop::run() {
  Clock::time_point last = Clock::now();
  restartWindow(last);
  double owed = 0.0;  // simulated seconds due but not yet stepped
  std::vector<Command> batch;
  batch.reserve(CommandLimits::kQueueCapacity);
  for (;;) {
    bool woken = false;
    {
      std::unique_lock<std::mutex> lock(queueMutex_);
      if (idle_) {
        wakeUp_.wait(lock, [&] { return stopRequested_ || wakeRequested_ || !queue_.empty(); });
      }
      if (stopRequested_) break;
      batch.swap(queue_);
      woken = wakeRequested_;
      wakeRequested_ = false;
    }
    bool acted = false;
    for (Command& c : batch) acted = apply(c) || acted;
    batch.clear();

    const double rtf = realTimeFactor_.load();
    if (rtf != diag_.requestedRealTimeFactor) {
      // A new pace: measure it afresh rather than average it with the old one.
      diag_.requestedRealTimeFactor = rtf;
      restartWindow(Clock::now());
    }
    if (idle_) {
      if (!acted && !woken) continue;  // only rejected commands: rest on
      // Awake: the time spent resting is not owed.
      idle_ = false;
      stillFor_ = 0.0;
      last = Clock::now();
      owed = 0.0;
      restartWindow(last);
      diag_.idle = false;
      writeSnapshot();
    } else if (acted) {
      stillFor_ = 0.0;
    }

    const Clock::time_point now = Clock::now();
    owed += seconds(now - last) * rtf;
    last = now;
    const double dt = solver_->params().timeStep;
    auto steps = static_cast<std::int64_t>(std::floor(owed / dt));
    if (steps > settings_.maxCatchUpSteps) {
      diag_.droppedSteps += static_cast<std::uint64_t>(steps - settings_.maxCatchUpSteps);
      steps = settings_.maxCatchUpSteps;
      owed = steps * dt;  // drop the debt: only what is stepped now is still owed
    }
    if (steps == 0 && acted) {
      // A command took effect between steps (0 <= owed < dt): step now rather than at the next
      // step's time, up to a whole step later, borrowing that step. The next one then comes a
      // step later than it would have: simulated time leads the clock by at most one step (until
      // it is paid back, owed < 0 and steps < 0: no second early step), and the pace is kept.
      steps = 1;
    }
    for (std::int64_t s = 0; s < steps; ++s) {
      timedStep();
      owed -= dt;
    }
    if (steps > 0) {
      updateStillness(steps * dt);
      writeSnapshot();
    }

    // Sleep until the next step is due, or until a command arrives.
    const double wait = std::max(0.0, (dt - owed) / rtf);
    std::unique_lock<std::mutex> lock(queueMutex_);
    wakeUp_.wait_for(lock, std::chrono::duration<double>(wait),
                     [&] { return stopRequested_ || wakeRequested_ || !queue_.empty(); });
  }
}

void SimulationLoop::ensureFinite() {
  if (allFinite(solver_->positions()) && allFinite(solver_->velocities())) return;
  // It should not happen (the solver is unconditionally stable for finite input and every
  // command is range-checked); if it does, never let NaN reach a subscriber.
  solver_->reset();
  ++diag_.solverResets;
  stillFor_ = 0.0;
}

void SimulationLoop::timedStep() {
  const Clock::time_point t0 = Clock::now();
  solver_->step();
  const Clock::time_point t1 = Clock::now();
  ++diag_.steps;
  const double dt = solver_->params().timeStep;
  ensureFinite();
  windowSteps_ += 1.0;
  windowStepSeconds_ += seconds(t1 - t0);
  windowSimulated_ += dt;
  const double wall = seconds(t1 - windowStart_);
  if (wall >= settings_.statsWindow || !windowComplete_) {
    // Until the first full window after a (re)start, report what there is rather than a
    // figure of the old pace.
    diag_.stepSeconds = windowStepSeconds_ / windowSteps_;
    diag_.achievedRealTimeFactor = wall > 0.0 ? windowSimulated_ / wall : 0.0;
  }
  if (wall >= settings_.statsWindow) {
    windowStart_ = t1;
    windowSteps_ = windowStepSeconds_ = windowSimulated_ = 0.0;
    windowComplete_ = true;
  }
}

void SimulationLoop::restartWindow(Clock::time_point now) {
  windowStart_ = now;
  windowSteps_ = windowStepSeconds_ = windowSimulated_ = 0.0;
  windowComplete_ = false;
}

void SimulationLoop::updateStillness(double simulated) {
  double maxSpeed2 = 0.0;
  for (const Eigen::Vector3d& v : solver_->velocities()) maxSpeed2 = std::max(maxSpeed2, v.squaredNorm());
  diag_.maxSpeed = std::sqrt(maxSpeed2);
  diag_.kineticEnergy = solver_->kineticEnergy();
  const double vIdle = settings_.idleSpeed;
  const bool still = diag_.maxSpeed < vIdle &&
                     diag_.kineticEnergy < 0.5 * lattice_->totalMass() * vIdle * vIdle &&
                     !solver_->hasPendingCommands();
  stillFor_ = still ? stillFor_ + simulated : 0.0;
  if (settings_.idleHold > 0.0 && stillFor_ >= settings_.idleHold) {
    std::lock_guard<std::mutex> lock(queueMutex_);
    // A command that came in during the step keeps the loop awake.
    if (queue_.empty() && !wakeRequested_) idle_ = true;
  }
  diag_.idle = idle_;
}

void SimulationLoop::writeSnapshot() {
  Snapshot& s = buffers_[back_];
  const Solver& solver = *solver_;
  const std::size_t n = solver.positions().size();
  s.sequence = ++sequence_;
  s.positions = solver.positions();  // same size every time: copies, no allocation
  s.rotations = solver.regionRotations();
  s.pinned.resize(n);
  for (std::size_t i = 0; i < n; ++i) s.pinned[i] = solver.isPinned(static_cast<std::uint32_t>(i));
  s.drags.clear();
  for (const auto& entry : solver.drags()) {
    DragView d;
    d.id = entry.first;
    for (std::uint32_t p : entry.second.particles) d.centroid += s.positions[p];
    d.centroid /= static_cast<double>(entry.second.particles.size());
    d.target = entry.second.target;
    s.drags.push_back(std::move(d));
  }
  const Eigen::Isometry3d rigid = solver.rigidFrame();
  s.objectFrame = rigid * Eigen::Translation3d(restCenterOfMass_);

  // Diagnostics that need the whole state, computed once here for every reader.
  const auto& x0 = lattice_->restPositions();
  double shape2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) shape2 += (s.positions[i] - rigid * x0[i]).squaredNorm();
  diag_.shapeError = n > 0 ? std::sqrt(shape2 / static_cast<double>(n)) : 0.0;
  diag_.maxDisplacement = solver.maxDisplacement();
  diag_.kineticEnergy = solver.kineticEnergy();
  diag_.simTime = solver.time();
  diag_.pinned = solver.pinnedCount();
  diag_.drags = solver.drags().size();
  diag_.forces = solver.activeForces().size();
  diag_.stiffnessSaturated = solver.stiffnessSaturated();
  diag_.alpha = solver.alpha();
  diag_.idle = idle_;
  s.diag = diag_;

  std::lock_guard<std::mutex> lock(snapshotMutex_);
  centerOfMass_ = s.objectFrame.translation();
  std::swap(back_, ready_);
  fresh_ = true;
}

bool SimulationLoop::apply(Command& command) {
  CommandOutcome outcome = std::visit(
      [&](const auto& c) -> CommandOutcome {
        using T = std::decay_t<decltype(c)>;
        if constexpr (std::is_same_v<T, GrabCommand>) {
          return grab(c);
        } else if constexpr (std::is_same_v<T, MoveCommand>) {
          return move(c);
        } else if constexpr (std::is_same_v<T, ReleaseCommand>) {
          return release(c);
        } else if constexpr (std::is_same_v<T, ApplyForceCommand>) {
          return force(c);
        } else if constexpr (std::is_same_v<T, ResetCommand>) {
          solver_->reset();
          stillFor_ = 0.0;
          return accepted("reset to rest; pins kept, drags and forces released");
        } else if constexpr (std::is_same_v<T, ReleaseAllCommand>) {
          const std::size_t n = solver_->drags().size();
          solver_->releaseAll();
          return accepted("released " + std::to_string(n) + " drag(s)");
        } else if constexpr (std::is_same_v<T, PinBoxCommand>) {
          return pinBox(c);
        } else {
          return setParams(c);
        }
      },
      command.body);
  if (outcome.accepted) stats_->accept();
  outcome.pinnedTotal = solver_->pinnedCount();
  if (command.outcome) command.outcome->set_value(outcome);
  return outcome.accepted;
}

CommandOutcome SimulationLoop::reject(const std::string& reason, const std::string& detail) {
  stats_->reject(reason, detail);
  CommandOutcome o;
  o.message = detail;
  return o;
}

double SimulationLoop::massOf(const std::vector<std::uint32_t>& particles) const {
  double m = 0.0;
  for (std::uint32_t p : particles) m += lattice_->masses()[p];
  return m;
}

CommandOutcome SimulationLoop::grab(const GrabCommand& c) {
  const std::size_t n = lattice_->size();
  if (c.particle >= static_cast<std::int64_t>(n))
    return reject("bad_index", "drag '" + c.id + "': particle " + std::to_string(c.particle) +
                                   " out of range [0, " + std::to_string(n) + ")");
  if (solver_->drags().count(c.id) == 0 && solver_->drags().size() >= CommandLimits::kMaxDrags)
    return reject("too_many_drags", "drag '" + c.id + "': already " +
                                        std::to_string(CommandLimits::kMaxDrags) +
                                        " drags; release one first");
  const std::vector<std::uint32_t> particles =
      c.particle >= 0 ? std::vector<std::uint32_t>{static_cast<std::uint32_t>(c.particle)}
                      : solver_->nearestParticles(c.point, c.count);
  if (c.stiffness > 0.0) {
    const double h = solver_->params().substepLength();
    const double limit = CommandLimits::kMaxSpringRate * massOf(particles) / (h * h);
    if (c.stiffness > limit)
      return reject("spring_too_stiff",
                    "drag '" + c.id + "': spring stiffness " + num(c.stiffness) +
                        " N/m is unstable on " + num(massOf(particles)) +
                        " kg of particles at sub-step " + num(h) + " s: at most " + num(limit) +
                        " N/m (or 0 for a hard drag)");
  }
  solver_->grab(c.id, particles, c.target, c.stiffness);
  return accepted("drag '" + c.id + "' holds " + std::to_string(particles.size()) +
                      " particle(s)",
                  particles.size());
}

CommandOutcome SimulationLoop::move(const MoveCommand& c) {
  if (!solver_->moveDrag(c.id, c.target))
    return reject("unknown_drag", "move of drag '" + c.id + "': no such drag (grab first)");
  return accepted("drag '" + c.id + "' moved");
}

CommandOutcome SimulationLoop::release(const ReleaseCommand& c) {
  if (!solver_->release(c.id))
    return reject("unknown_drag", "release of drag '" + c.id + "': no such drag");
  return accepted("drag '" + c.id + "' released");
}

CommandOutcome SimulationLoop::force(const ApplyForceCommand& c) {
  const std::size_t n = lattice_->size();
  if (c.particle >= static_cast<std::int64_t>(n))
    return reject("bad_index", "force: particle " + std::to_string(c.particle) +
                                   " out of range [0, " + std::to_string(n) + ")");
  if (!c.impulse && solver_->activeForces().size() >= CommandLimits::kMaxForces)
    return reject("too_many_forces", "force: already " +
                                         std::to_string(CommandLimits::kMaxForces) +
                                         " forces acting; wait for some to end");
  std::vector<std::uint32_t> particles;
  if (c.particle >= 0)
    particles.push_back(static_cast<std::uint32_t>(c.particle));
  else if (c.radius > 0.0)
    particles = solver_->particlesWithin(c.point, c.radius);
  else
    particles = solver_->nearestParticles(c.point, 1);
  if (particles.empty())
    return reject("empty_selection", "force: no particle within " + num(c.radius) +
                                         " m of the point; aim at the object or widen the radius");
  const double mass = massOf(particles);
  const double size = lattice_->objectSize();
  const double magnitude = c.force.norm();
  if (c.impulse) {
    const double limit = CommandLimits::kMaxSpeedChange * size * mass;
    if (magnitude > limit)
      return reject("too_large", "impulse " + num(magnitude) + " N s on " + num(mass) +
                                     " kg would change their speed by more than " +
                                     num(CommandLimits::kMaxSpeedChange * size) +
                                     " m/s: at most " + num(limit) + " N s");
    solver_->applyImpulse(particles, c.force);
  } else {
    const double limit = CommandLimits::kMaxAcceleration * size * mass;
    if (magnitude > limit)
      return reject("too_large", "force " + num(magnitude) + " N on " + num(mass) +
                                     " kg would accelerate them by more than " +
                                     num(CommandLimits::kMaxAcceleration * size) +
                                     " m/s^2: at most " + num(limit) + " N");
    solver_->applyForce(particles, c.force, c.duration);
  }
  return accepted(std::string(c.impulse ? "impulse" : "force") + " on " +
                      std::to_string(particles.size()) + " particle(s)",
                  particles.size());
}

CommandOutcome SimulationLoop::pinBox(const PinBoxCommand& c) {
  const std::size_t count = solver_->pinBox(c.lo, c.hi, c.pin);
  return accepted(std::string(c.pin ? "pinned " : "freed ") + std::to_string(count) +
                      " particle(s) in the box",
                  count);
}

CommandOutcome SimulationLoop::setParams(const ParamsCommand& c) {
  try {
    solver_->setParams(c.params);
  } catch (const std::invalid_argument& e) {
    return reject("invalid_params", e.what());
  }
  return accepted("solver parameters set");
}

}  // namespace deformable_flsm
