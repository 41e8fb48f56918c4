/// @file simulation_loop.h
/// The simulation thread: owns the solver, applies queued commands, steps at a fixed simulated
/// time step paced to the wall clock, goes idle when nothing moves, and hands out snapshots of
/// the state. No ROS: the node feeds it validated commands and reads its snapshots.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/ros/commands.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace deformable_flsm {

/// How the loop paces itself and when it rests.
struct LoopSettings {
  /// Simulated seconds per wall-clock second.
  double realTimeFactor = 1.0;
  /// When the loop has fallen behind, it takes at most this many steps back to back and drops
  /// the rest of the simulated time it owes (reported as dropped steps), so that a machine that
  /// cannot keep up runs slower than real time instead of piling up a growing backlog.
  int maxCatchUpSteps = 4;
  /// The object is still when every particle is slower than idleSpeed (m/s) and the kinetic
  /// energy is below 1/2 M idleSpeed^2; after idleHold seconds of simulated stillness with no
  /// drag or force acting, the loop stops stepping until a command arrives. idleHold <= 0 never
  /// rests. The node sets idleSpeed relative to the object size (see SimulatorNode).
  double idleSpeed = 1e-4;
  double idleHold = 1.0;
  /// Window (s, wall clock) over which the achieved real-time factor and step cost are averaged.
  double statsWindow = 1.0;
};

/// Figures of the loop and the solver, as reported on ~state.
struct LoopDiagnostics {
  /// simulated time since start or reset (s)
  double simTime = 0.0;
  /// mean wall-clock time of one Solver::step() over the last window (s)
  double stepSeconds = 0.0;
  /// simulated seconds per wall second over the last window of stepping
  double achievedRealTimeFactor = 0.0;
  double requestedRealTimeFactor = 1.0;
  double kineticEnergy = 0.0;   ///< J
  double maxDisplacement = 0.0; ///< m, largest |x - x0|
  double maxSpeed = 0.0;        ///< m/s
  double shapeError = 0.0;      ///< m, RMS distance from the rest shape moved rigidly
  std::size_t pinned = 0;
  std::size_t drags = 0;
  std::size_t forces = 0;
  bool idle = false;
  bool stiffnessSaturated = false;
  double alpha = 0.0;
  std::uint64_t steps = 0;         ///< Solver::step() calls since start
  std::uint64_t droppedSteps = 0;  ///< steps owed but dropped because the machine was too slow
  std::uint64_t solverResets = 0;  ///< resets after a non-finite state (should stay 0)
};

/// A drag as shown on ~lattice: from the grabbed particles' centroid to the target.
struct DragView {
  std::string id;
  Eigen::Vector3d centroid = Eigen::Vector3d::Zero();
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
};

/// The state after a step, copied out of the simulation thread.
struct Snapshot {
  /// increases with every new state; equal sequence = identical content
  std::uint64_t sequence = 0;
  /// #P particle positions (m) and region rotations
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Quaterniond> rotations;
  /// #P 1 for a pinned particle
  std::vector<char> pinned;
  std::vector<DragView> drags;
  /// the object's best-fit rigid frame, origin at its centre of mass: the identity maps the
  /// rest centre of mass to itself (Solver::rigidFrame() followed by a shift to the rest COM)
  Eigen::Isometry3d objectFrame = Eigen::Isometry3d::Identity();
  LoopDiagnostics diag;
};

class SimulationLoop {
 public:
  /// @param[in] solver    the solver, ready (pins set); owned by the loop from now on
  /// @param[in] settings  pacing and idling
  /// @param[in] stats     where accepted and rejected commands are counted
  SimulationLoop(std::unique_ptr<Solver> solver, const LoopSettings& settings,
                 std::shared_ptr<CommandStats> stats);
  /// Stops and joins the thread.
  ~SimulationLoop();
  SimulationLoop(const SimulationLoop&) = delete;
  SimulationLoop& operator=(const SimulationLoop&) = delete;

  /// Starts the thread (publishes a first snapshot of the initial state before stepping).
  void start();
  /// Stops the thread; idempotent. Queued commands are dropped, waiting services get an answer.
  void stop();

  /// Queues a command and wakes the loop, which applies it and, if no step is due yet, steps at
  /// once (borrowing the next step's time; see run()). When the queue is full the
  /// command is rejected ("queue_full"), its outcome delivered, and false returned.
  bool submit(Command command);
  /// Changes the pace (simulated seconds per wall second, > 0) and wakes an idle loop.
  void setRealTimeFactor(double realTimeFactor);

  /// The newest snapshot. Single reader: the reference stays valid and unchanged until the next
  /// call of acquire().
  const Snapshot& acquire();
  /// The object's current centre of mass (m), for range checks from any thread.
  Eigen::Vector3d centerOfMass() const;

  const Lattice& lattice() const { return *lattice_; }

 private:
  void run();
  /// Applies one command; returns true when it was accepted.
  bool apply(Command& command);
  CommandOutcome grab(const GrabCommand& c);
  CommandOutcome move(const MoveCommand& c);
  CommandOutcome release(const ReleaseCommand& c);
  CommandOutcome force(const ApplyForceCommand& c);
  CommandOutcome pinBox(const PinBoxCommand& c);
  CommandOutcome setParams(const ParamsCommand& c);
  /// Rejection: counted, and the outcome carries the detail.
  CommandOutcome reject(const std::string& reason, const std::string& detail);
  double massOf(const std::vector<std::uint32_t>& particles) const;
  /// Resets a non-finite state to rest and counts it.
  void ensureFinite();
  void timedStep();
  /// Starts a new averaging window for the step cost and the achieved real-time factor.
  void restartWindow(std::chrono::steady_clock::time_point now);
  void updateStillness(double simulated);
  void writeSnapshot();

  std::unique_ptr<Solver> solver_;
  const Lattice* lattice_ = nullptr;  // the solver's; immutable, so any thread may read it
  LoopSettings settings_;
  std::shared_ptr<CommandStats> stats_;
  Eigen::Vector3d restCenterOfMass_ = Eigen::Vector3d::Zero();

  // Command queue, shared with submitters.
  mutable std::mutex queueMutex_;
  std::condition_variable wakeUp_;
  std::vector<Command> queue_;
  bool stopRequested_ = false;
  bool wakeRequested_ = false;
  std::atomic<double> realTimeFactor_;
  std::thread thread_;

  // Triple buffer: the thread fills back_, publishes it as ready_; the reader swaps ready_ into
  // front_. Only indices move under the lock.
  mutable std::mutex snapshotMutex_;
  std::array<Snapshot, 3> buffers_;
  int back_ = 0, ready_ = 1, front_ = 2;
  bool fresh_ = false;
  Eigen::Vector3d centerOfMass_ = Eigen::Vector3d::Zero();

  // Owned by the simulation thread.
  LoopDiagnostics diag_;
  std::uint64_t sequence_ = 0;
  bool idle_ = false;
  double stillFor_ = 0.0;  // simulated seconds of stillness
  double windowSteps_ = 0.0, windowStepSeconds_ = 0.0, windowSimulated_ = 0.0;
  std::chrono::steady_clock::time_point windowStart_;
  bool windowComplete_ = false;  // a full window has passed since the last restart
};

}  // namespace deformable_flsm
