#include "deformable_flsm/runtime/simulation_loop.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/runtime/collider_spec.h"

#include <algorithm>
#include <iterator>
#include <cmath>
#include <sstream>
#include <stdexcept>
#include <utility>
#include <variant>

namespace deformable_flsm {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

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

std::string num(double v) {
  std::ostringstream os;
  os.precision(3);
  os << v;
  return os.str();
}

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

CommandOutcome accepted(std::string message, std::size_t particles = 0) {
  CommandOutcome o;
  o.accepted = true;
  o.message = std::move(message);
  o.particles = particles;
  return o;
}

}  // namespace

SimulationLoop::SimulationLoop(std::unique_ptr<World> world, const LoopSettings& settings,
                               std::shared_ptr<CommandStats> stats, std::shared_ptr<LoopClock> clock)
    : world_(std::move(world)), settings_(settings), stats_(std::move(stats)),
      clock_(clock ? std::move(clock) : std::make_shared<SteadyLoopClock>()),
      realTimeFactor_(settings.realTimeFactor) {
  if (!world_ || world_->objectCount() == 0)
    throw std::invalid_argument("SimulationLoop: no object to simulate");
  if (!stats_) throw std::invalid_argument("SimulationLoop: no command statistics");
  if (!(settings_.realTimeFactor > 0.0) || settings_.maxCatchUpSteps < 1)
    throw std::invalid_argument("SimulationLoop: real-time factor must be > 0 and catch-up >= 1");
  if (!(settings_.restFraction >= 0.0))
    throw std::invalid_argument("SimulationLoop: rest fraction must be >= 0");
  names_ = world_->objectNames();
  for (const std::string& name : names_) {
    Solver* solver = world_->object(name);
    solvers_.push_back(solver);
    const Lattice& L = solver->lattice();  // immutable, owned through the solver
    lattices_.push_back(&L);
    Eigen::Vector3d com = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < L.size(); ++i) com += L.masses()[i] * L.restPositions()[i];
    restCenterOfMass_.push_back(com / L.totalMass());
    stillFrom_.push_back(solver->positions());
    versions_.emplace_back();
  }
  target_ = solvers_.front();
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

void SimulationLoop::setFrameSource(FrameSource source) { frameSource_ = std::move(source); }

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

Eigen::Vector3d SimulationLoop::centerOfMass(std::size_t object) const {
  std::lock_guard<std::mutex> lock(snapshotMutex_);
  return centerOfMass_.at(object);
}

void SimulationLoop::run() {
  Clock::time_point last = clock_->now();
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
    for (Command& c : batch) {
      ++appliedKinds_[c.body.index()];
      acted = apply(c) || acted;
    }
    batch.clear();

    const double rtf = realTimeFactor_.load();
    if (rtf != diag_.requestedRealTimeFactor) {
      // A new pace: measure it afresh rather than average it with the old one.
      diag_.requestedRealTimeFactor = rtf;
      restartWindow(clock_->now());
    }
    if (idle_) {
      if (!acted && !woken) continue;  // only rejected commands: rest on
      // Awake: the time spent resting is not owed.
      idle_ = false;
      restartStillness();
      last = clock_->now();
      owed = 0.0;
      restartWindow(last);
      diag_.idle = false;
      writeSnapshot();
    } else if (acted) {
      restartStillness();
    }

    const Clock::time_point now = clock_->now();
    owed += seconds(now - last) * rtf;
    last = now;
    const double dt = world_->timeStep();
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
      followColliders(dt);
      followFrames();
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
    clock_->waitUntil(lock, wakeUp_,
                      clock_->now() + std::chrono::duration_cast<LoopClock::Duration>(
                                          std::chrono::duration<double>(wait)),
                      [&] { return stopRequested_ || wakeRequested_ || !queue_.empty(); });
  }
}

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
                                       "move_collider", "remove_collider"};
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

void SimulationLoop::timedStep() {
  const Clock::time_point t0 = clock_->now();
  world_->step();
  const Clock::time_point t1 = clock_->now();
  ++diag_.steps;
  const double dt = world_->timeStep();
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
  if (settings_.idleHold > 0.0 && stillFor_ >= settings_.idleHold) {
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
  diag_.simTime = world_->time() - timeOrigin_;
  diag_.idle = idle_;
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

  std::lock_guard<std::mutex> lock(snapshotMutex_);
  for (std::size_t k = 0; k < s.objects.size(); ++k) centerOfMass_[k] = s.objects[k].objectFrame.translation();
  std::swap(back_, ready_);
  fresh_ = true;
  appliedKinds_.fill(0);
}

bool SimulationLoop::apply(Command& command) {
  CommandOutcome outcome;
  target_ = command.object.empty() ? solvers_.front() : world_->object(command.object);
  if (target_ == nullptr) {
    outcome = reject("unknown_object", "object '" + command.object +
                                           "' is not in the scene (removed): command refused");
  } else {
    outcome = applyBody(command);
  }
  if (outcome.accepted) stats_->accept();
  outcome.pinnedTotal = target_ != nullptr ? target_->pinnedCount() : 0;
  if (command.outcome) command.outcome->set_value(outcome);
  return outcome.accepted;
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
