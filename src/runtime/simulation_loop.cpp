/// @file simulation_loop.cpp
/// SimulationLoop: the simulation thread, its command queue and its pacing to the wall clock.
/// The commands' rules, the snapshots and idling, the followed colliders and the blown-up-state
/// guard are in simulation_loop_{commands,snapshots,colliders,guard}.cpp.
#include "deformable_flsm/runtime/simulation_loop.h"

#include <pthread.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <utility>

namespace deformable_flsm {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

/// A followed time that is behind the loop's by more than this many steps went back (a time
/// a hair behind, by rounding, did not).
constexpr double kFollowSlack = 1e-6;

}  // namespace

std::string checkLoopSettings(const LoopSettings& settings) {
  const double rtf = settings.realTimeFactor;
  if (!std::isfinite(rtf) || rtf < 0.0 || (rtf == 0.0 && settings.time != LoopTime::Served))
    return "real-time factor must be finite and > 0 (0, as fast as the machine can, only for a "
           "loop whose time is served)";
  if (settings.maxCatchUpSteps < 1) return "catch-up must be >= 1 step";
  if (!(settings.restFraction >= 0.0)) return "rest fraction must be >= 0";
  return "";
}

SimulationLoop::SimulationLoop(std::unique_ptr<World> world, const LoopSettings& settings,
                               std::shared_ptr<CommandStats> stats, std::shared_ptr<LoopClock> clock)
    : world_(std::move(world)), settings_(settings), stats_(std::move(stats)),
      clock_(clock ? std::move(clock) : std::make_shared<SteadyLoopClock>()),
      realTimeFactor_(settings.realTimeFactor) {
  if (!world_ || world_->objectCount() == 0)
    throw std::invalid_argument("SimulationLoop: no object to simulate");
  if (!stats_) throw std::invalid_argument("SimulationLoop: no command statistics");
  const std::string bad = checkLoopSettings(settings_);
  if (!bad.empty()) throw std::invalid_argument("SimulationLoop: " + bad);
  startNames_ = world_->objectNames();
  for (const std::string& name : startNames_) trackObject(name);
  startLattices_ = lattices_;
  target_ = solvers_.front();
  diag_.requestedRealTimeFactor = settings_.realTimeFactor;
  paused_ = settings_.startPaused;
  diag_.paused = paused_;
  queue_.reserve(CommandLimits::kQueueCapacity);
}

SimulationLoop::~SimulationLoop() { stop(); }

void SimulationLoop::start() {
  if (thread_.joinable()) return;
  ensureFinite();
  writeSnapshot();  // the rest state, so that readers have something before the first step
  thread_ = std::thread(&SimulationLoop::run, this);
  // named, so that a thread listing (top -H, /proc/<pid>/task/*/comm, gdb) tells the simulation apart
  pthread_setname_np(thread_.native_handle(), "flsm_simulation");
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
  CommandOutcome o;
  o.message = "the simulation is shutting down";
  for (Command& c : left)
    if (c.outcome) c.outcome->set_value(o);
  if (stepAnswer_) {
    stepAnswer_->set_value(o);
    stepAnswer_.reset();
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

void SimulationLoop::setTickObserver(TickObserver observer) { tickObserver_ = std::move(observer); }

void SimulationLoop::setNotice(Notice notice) { notice_ = std::move(notice); }

void SimulationLoop::setRealTimeFactor(double realTimeFactor) {
  LoopSettings changed = settings_;
  changed.realTimeFactor = realTimeFactor;
  const std::string bad = checkLoopSettings(changed);
  if (!bad.empty()) throw std::invalid_argument(bad);
  realTimeFactor_.store(realTimeFactor);
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    wakeRequested_ = true;
  }
  wakeUp_.notify_one();
}

void SimulationLoop::followTime(double time) {
  if (!std::isfinite(time)) return;
  {
    std::lock_guard<std::mutex> lock(queueMutex_);
    followTarget_ = time;
    followSet_ = followMoved_ = true;
  }
  wakeUp_.notify_one();
}

void SimulationLoop::run() {
  running_ = true;
  paceFrom_ = clock_->now();
  restartWindow(paceFrom_);
  owed_ = 0.0;
  std::vector<Command> batch;
  batch.reserve(CommandLimits::kQueueCapacity);
  using Wall = std::chrono::steady_clock;
  for (;;) {
    const Arrivals arrived = collect(batch);
    if (arrived.stop) break;
    watchStage(Wall::now() - queueLockWait_, "waiting for the command queue's lock", -1);
    const Wall::time_point applying = Wall::now();
    bool acted = false;
    for (Command& c : batch) {
      ++appliedKinds_[c.body.index()];
      acted = apply(c) || acted;
    }
    watchStage(applying, "applying commands:", static_cast<long long>(batch.size()));
    batch.clear();
    const double dt = world_->timeStep();
    if (paused_) {
      stepOnRequest(dt);
      continue;
    }
    const double rtf = realTimeFactor_.load();
    repace(rtf, acted, arrived.woken);
    const Wall::time_point stepping = Wall::now();
    const std::int64_t due = stepsDue(arrived, rtf, dt);
    takeSteps(due, acted, dt);
    watchStage(stepping, "stepping the scene and handing out its state, steps due:", static_cast<long long>(due));
    waitForNextStep(rtf, dt);
  }
}

SimulationLoop::Arrivals SimulationLoop::collect(std::vector<Command>& batch) {
  const auto asked = std::chrono::steady_clock::now();
  std::unique_lock<std::mutex> lock(queueMutex_);
  queueLockWait_ = std::chrono::steady_clock::now() - asked;
  // Nothing to do until something happens: paused (no steps asked), or at rest where the time
  // stands still with the state. At rest a served time goes on (takeSteps()), and a followed one
  // moves on with the time it follows.
  const bool waitForWork = paused_ ? stepsRequested_ == 0 : idle_ && settings_.time != LoopTime::Served;
  if (waitForWork) {
    wakeUp_.wait(lock, [&] {
      return stopRequested_ || wakeRequested_ || !queue_.empty() || (followMoved_ && !paused_);
    });
  }
  Arrivals a;
  if (stopRequested_) {
    a.stop = true;
    return a;
  }
  batch.swap(queue_);
  a.woken = wakeRequested_;
  wakeRequested_ = false;
  a.followed = followSet_;
  a.target = followTarget_;
  followMoved_ = false;
  return a;
}

std::chrono::steady_clock::time_point SimulationLoop::accrue(double pace) {
  const Clock::time_point t = clock_->now();
  owed_ += seconds(t - paceFrom_) * pace;
  paceFrom_ = t;
  return t;
}

void SimulationLoop::repace(double rtf, bool acted, bool woken) {
  if (rtf != diag_.requestedRealTimeFactor) {
    // A new pace: the clock's time until now is owed at the old one (a wait cut short by the
    // change is not a backlog at the new pace); measure it afresh rather than average it with
    // the old one.
    const Clock::time_point changed = accrue(diag_.requestedRealTimeFactor);
    diag_.requestedRealTimeFactor = rtf;
    restartWindow(changed);
  }
  if (resumed_) {
    // Unpaused: the time spent paused is not owed.
    resumed_ = false;
    paceFrom_ = clock_->now();
    owed_ = 0.0;
    restartWindow(paceFrom_);
  }
  if (idle_ && (acted || woken)) {
    // Awake: the time spent resting is not owed.
    idle_ = false;
    restartStillness();
    paceFrom_ = clock_->now();
    owed_ = 0.0;
    restartWindow(paceFrom_);
    diag_.idle = false;
    writeSnapshot();
  } else if (acted) {
    restartStillness();
  }
}

std::int64_t SimulationLoop::stepsDue(const Arrivals& arrived, double rtf, double dt) {
  if (settings_.time == LoopTime::Followed) return arrived.followed ? stepsToFollow(arrived.target, dt) : 0;
  if (rtf == 0.0) return 1;  // as fast as the machine can
  accrue(rtf);
  // whole steps owed (a sum of clock intervals a hair short of k steps is k steps)
  return static_cast<std::int64_t>(std::floor(owed_ / dt + 1e-9));
}

void SimulationLoop::takeSteps(std::int64_t steps, bool acted, double dt) {
  const LoopTime mode = settings_.time;
  if (idle_) {
    // At rest the state holds: the time moves on (Served, Followed) without stepping.
    tickAtRest(steps, dt);
    owed_ -= static_cast<double>(steps) * dt;
    return;
  }
  if (steps > settings_.maxCatchUpSteps) {
    // drop the whole steps beyond the batch, each counted; the fraction of a step stays owed
    const std::int64_t dropped = steps - settings_.maxCatchUpSteps;
    diag_.droppedSteps += static_cast<std::uint64_t>(dropped);
    owed_ -= static_cast<double>(dropped) * dt;
    // A followed time is kept up with by a jump; a paced one runs slower instead.
    if (mode == LoopTime::Followed) ticks_ += dropped;
    steps = settings_.maxCatchUpSteps;
  }
  if (steps == 0 && acted && mode != LoopTime::Followed) {
    // A command took effect between steps (0 <= owed < dt): step now rather than at the next
    // step's time, up to a whole step later, borrowing that step. The next one then comes a
    // step later than it would have: simulated time leads the clock by at most one step (until
    // it is paid back, owed < 0 and steps < 0: no second early step), and the pace is kept.
    // A followed time is never led.
    steps = 1;
  }
  for (std::int64_t s = 0; s < steps; ++s) {
    stepScene(dt);
    owed_ -= dt;
    // A served time goes out with every step, each state with it.
    if (mode == LoopTime::Served) {
      updateStillness(dt);
      writeSnapshot();
    }
  }
  if (steps > 0 && mode != LoopTime::Served) {
    updateStillness(static_cast<double>(steps) * dt);
    writeSnapshot();
  }
}

void SimulationLoop::waitForNextStep(double rtf, double dt) {
  // Sleep until the next step is due, or until a command arrives. The time the steps took is
  // owed too: a step slower than its share of the clock leaves the next one due at once, and
  // the loop steps on without sleeping (a sleep of a step after every batch of 4 would run a
  // step of 1.5 shares at 4/7 of the pace, not 2/3). A followed time wakes the loop when it
  // moves; as fast as the machine can is no wait at all.
  const LoopTime mode = settings_.time;
  if (mode != LoopTime::Followed && rtf == 0.0) {
    owed_ = 0.0;  // as fast as it can owes nothing: a pace set later starts from now
    paceFrom_ = clock_->now();
    return;
  }
  std::unique_lock<std::mutex> lock(queueMutex_);
  const auto woke = [&] { return stopRequested_ || wakeRequested_ || !queue_.empty() || followMoved_; };
  if (mode == LoopTime::Followed) {
    wakeUp_.wait(lock, woke);
    return;
  }
  accrue(rtf);
  const double wait = std::max(0.0, (dt - owed_) / rtf);
  clock_->waitUntil(lock, wakeUp_,
                    clock_->now() + std::chrono::duration_cast<LoopClock::Duration>(
                                        std::chrono::duration<double>(wait)),
                    woke);
}

void SimulationLoop::watchStage(std::chrono::steady_clock::time_point since, const char* what, long long count) {
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count();
  if (!(seconds > kSlowStageSeconds) || !notice_) return;
  std::ostringstream os;
  os.precision(3);
  os << "the simulation thread spent " << seconds << " s " << what;
  if (count >= 0) os << " " << count;
  os << " (no state goes out meanwhile; a machine without a free core, or a stalled disk, can do this)";
  notice_(os.str());
}

void SimulationLoop::stepScene(double dt) {
  followColliders(dt);
  followFrames();
  timedStep();
  ++ticks_;
  setClock(dt);
}

void SimulationLoop::setClock(double dt) {
  clockTime_.store(clockOrigin_ + static_cast<double>(ticks_) * dt);
}

void SimulationLoop::tickAtRest(std::int64_t steps, double dt) {
  if (steps <= 0) return;
  if (settings_.time == LoopTime::Followed) {
    ticks_ += steps;  // one tick for the lot: the followed time went on by them at once
    setClock(dt);
    observed_ = clockTime();
    if (tickObserver_) tickObserver_(observed_, nullptr);
    return;
  }
  if (settings_.time != LoopTime::Served) return;
  for (std::int64_t s = 0; s < steps; ++s) {
    ++ticks_;
    setClock(dt);
    observed_ = clockTime();
    if (tickObserver_) tickObserver_(observed_, nullptr);
  }
}

std::int64_t SimulationLoop::stepsToFollow(double target, double dt) {
  if (!clockStarted_) {
    // The loop's time starts at the first time it follows: the state at start is the state then.
    clockStarted_ = true;
    clockOrigin_ = target;
    ticks_ = 0;
    setClock(dt);
    writeSnapshot();
    return 0;
  }
  const double now = clockTime();
  // (a bag's times are ~1.7e9 s, where a double's rounding is ~2e-7 s)
  const double slack = kFollowSlack * dt + 8.0 * std::numeric_limits<double>::epsilon() * std::abs(now);
  if (target < now - slack) {
    // The followed time went back (a bag played again, a simulator reset): the scene starts
    // again from rest at the new time, so that no state is stamped before the one before it.
    if (notice_) {
      std::ostringstream os;
      os << "the followed clock went back from " << now << " s to " << target
         << " s: the scene is reset to rest and goes on from there";
      notice_(os.str());
    }
    resetAll();
    clockOrigin_ = target;
    ticks_ = 0;
    setClock(dt);
    idle_ = false;
    diag_.idle = false;
    observed_ = -std::numeric_limits<double>::infinity();  // the time starts again
    writeSnapshot();
    return 0;
  }
  return static_cast<std::int64_t>(std::floor((target - now) / dt + 1e-9));
}

void SimulationLoop::stepOnRequest(double dt) {
  const std::int64_t steps = std::min<std::int64_t>(stepsRequested_, settings_.maxCatchUpSteps);
  // The pace of steps on request is the machine's: the time paused before them is no part of it.
  if (steps > 0) restartWindow(clock_->now());
  for (std::int64_t s = 0; s < steps; ++s) {
    stepScene(dt);
    --stepsRequested_;
    updateStillness(dt);
    // Stepping on request never rests: every step asked for is taken.
    idle_ = false;
    diag_.idle = false;
    writeSnapshot();
  }
  if (stepsRequested_ == 0 && stepAnswer_) {
    CommandOutcome o;
    o.accepted = true;
    std::ostringstream os;
    os << "stepped to " << clockTime() << " s";
    o.message = os.str();
    o.pinnedTotal = solvers_.front()->pinnedCount();
    stepAnswer_->set_value(o);
    stepAnswer_.reset();
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

}  // namespace deformable_flsm
