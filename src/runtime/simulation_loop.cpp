/// @file simulation_loop.cpp
/// SimulationLoop: the simulation thread, its command queue and its pacing to the wall clock.
/// The commands' rules, the snapshots and idling, the followed colliders and the blown-up-state
/// guard are in simulation_loop_{commands,snapshots,colliders,guard}.cpp.
#include "deformable_flsm/runtime/simulation_loop.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <utility>

namespace deformable_flsm {

namespace {

using Clock = std::chrono::steady_clock;

double seconds(Clock::duration d) { return std::chrono::duration<double>(d).count(); }

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
  startNames_ = world_->objectNames();
  for (const std::string& name : startNames_) trackObject(name);
  startLattices_ = lattices_;
  target_ = solvers_.front();
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

void SimulationLoop::run() {
  Clock::time_point last = clock_->now();
  restartWindow(last);
  double owed = 0.0;  // simulated seconds due but not yet stepped
  // the clock's time since `last` owed at `pace`; `last` moves on to now, which it returns
  const auto accrue = [&](double pace) {
    const Clock::time_point t = clock_->now();
    owed += seconds(t - last) * pace;
    last = t;
    return t;
  };
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
      // A new pace: the clock's time until now is owed at the old one (a wait cut short by the
      // change is not a backlog at the new pace); measure it afresh rather than average it with
      // the old one.
      const Clock::time_point changed = accrue(diag_.requestedRealTimeFactor);
      diag_.requestedRealTimeFactor = rtf;
      restartWindow(changed);
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

    accrue(rtf);
    const double dt = world_->timeStep();
    // whole steps owed (a sum of clock intervals a hair short of k steps is k steps)
    auto steps = static_cast<std::int64_t>(std::floor(owed / dt + 1e-9));
    if (steps > settings_.maxCatchUpSteps) {
      // drop the whole steps beyond the batch, each counted; the fraction of a step stays owed
      const std::int64_t dropped = steps - settings_.maxCatchUpSteps;
      diag_.droppedSteps += static_cast<std::uint64_t>(dropped);
      owed -= static_cast<double>(dropped) * dt;
      steps = settings_.maxCatchUpSteps;
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

    // Sleep until the next step is due, or until a command arrives. The time the steps took is
    // owed too: a step slower than its share of the clock leaves the next one due at once, and
    // the loop steps on without sleeping (a sleep of a step after every batch of 4 would run a
    // step of 1.5 shares at 4/7 of the pace, not 2/3).
    accrue(rtf);
    const double wait = std::max(0.0, (dt - owed) / rtf);
    std::unique_lock<std::mutex> lock(queueMutex_);
    clock_->waitUntil(lock, wakeUp_,
                      clock_->now() + std::chrono::duration_cast<LoopClock::Duration>(
                                          std::chrono::duration<double>(wait)),
                      [&] { return stopRequested_ || wakeRequested_ || !queue_.empty(); });
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
