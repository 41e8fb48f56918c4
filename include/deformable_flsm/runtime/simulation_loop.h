/// @file simulation_loop.h
/// The simulation thread: owns the World (one object, or the objects of ~objects), applies queued commands, steps at a fixed simulated
/// time step paced to its clock (LoopClock: the steady clock unless given another), goes idle when nothing moves, and hands out snapshots of
/// the state. No ROS: the node feeds it validated commands and reads its snapshots.
#pragma once

#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/world.h"
#include "deformable_flsm/runtime/commands.h"
#include "deformable_flsm/runtime/loop_clock.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

namespace deformable_flsm {

/// What the loop's simulated time follows.
enum class LoopTime {
  /// The loop's clock (the wall clock in the node) at the real-time factor; at rest the loop
  /// waits and its time stands still with the state (the node's ~clock wall).
  Paced,
  /// Paced as Paced, and the simulated time goes on at rest in whole steps at the pace, each one
  /// reported to the TickObserver, as every step is: the time of a simulator that serves /clock
  /// (~clock sim). A loop that cannot keep up runs slower than the pace; its time is always the
  /// time it stepped. A real-time factor of 0 steps as fast as the machine can and never rests.
  Served,
  /// The time handed to followTime() (another simulator's /clock, ~clock follow): the loop steps
  /// while a whole step fits before it, never ahead of it; behind by more than maxCatchUpSteps, it
  /// drops the steps beyond them (counted) and its time jumps to the followed one. The loop's time
  /// starts at the first followed time; a followed time that goes back resets the scene to rest
  /// and starts there (said through the Notice).
  Followed,
};

/// How the loop paces itself and when it rests.
struct LoopSettings {
  /// Simulated seconds per wall-clock second (Paced and Served; 0 only with LoopTime::Served).
  double realTimeFactor = 1.0;
  /// What the simulated time follows.
  LoopTime time = LoopTime::Paced;
  /// Starts paused (PauseCommand): nothing steps until unpaused or a StepCommand.
  bool startPaused = false;
  /// When the loop has fallen behind, it takes at most this many steps back to back and drops
  /// the rest of the simulated time it owes (reported as dropped steps), so that a machine that
  /// cannot keep up runs slower than real time instead of piling up a growing backlog.
  int maxCatchUpSteps = 4;
  /// Rest means equilibrium, not slowness: the loop stops stepping (until a command arrives) once
  /// no particle has moved farther than restFraction object sizes (Lattice::objectSize()) from
  /// where it was idleHold seconds of simulated time earlier, with no drag or force acting. A speed
  /// threshold is not enough: a slow swing turns at its ends with almost no speed for a second or
  /// more, far from where it settles (the soft cantilever of test_simulation_loop_pace's
  /// RestsOnlyAtEquilibrium, with a period of several seconds; figures in docs/design.md). Over a
  /// whole second, a swing of amplitude A moves a particle by ~A (slow swings) to 2A (fast ones),
  /// and a creep moves it by what the next second would add, so the object rests within
  /// ~restFraction sizes of its equilibrium: 2e-5 is 7 um for the 33 cm bunny, far below what can
  /// be seen, and the solver converges to its fixed point geometrically, so this costs seconds, not
  /// minutes.
  /// idleHold <= 0 never rests.
  double restFraction = 2e-5;
  double idleHold = 1.0;
  /// Window (s, wall clock) over which the achieved real-time factor and step cost are averaged.
  double statsWindow = 1.0;
};

/// Whether `settings` are consistent; "" when they are, else why not.
std::string checkLoopSettings(const LoopSettings& settings);

/// Figures of the loop and the solver, as reported on ~state: of one object
/// (ObjectSnapshot::diag), or of the whole scene (Snapshot::diag: energies, pins, drags, forces
/// and particles summed over the objects, displacement, speed and shape error the largest of
/// any object, saturated when any object is, alpha the first object's).
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
  /// paused (PauseCommand): nothing steps, the time stands still
  bool paused = false;
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
  /// what the drag exerted on the object over the step (Drag::force, Drag::torque: N, and N m
  /// about the drag frame's origin, a grab's target or an attached frame's origin; simulation
  /// frame), and how many particles it holds
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  std::size_t particles = 0;
};

/// One object's state after a step.
struct ObjectSnapshot {
  /// the object's name in the World
  std::string name;
  /// Snapshot::sequence of the last snapshot in which this object had moved (any particle
  /// farther than LoopSettings::restFraction object sizes from where it was at the version
  /// before) or its pins or drags changed: while it stays, the object looks the same, and
  /// its messages need not be rebuilt or re-sent although others move
  std::uint64_t version = 0;
  /// #P particle positions (m) and region rotations
  std::vector<Eigen::Vector3d> positions;
  std::vector<Eigen::Quaterniond> rotations;
  /// #P 1 for a pinned particle
  std::vector<char> pinned;
  std::vector<DragView> drags;
  /// the object's best-fit rigid frame, origin at its centre of mass: the identity maps the
  /// rest centre of mass to itself (Solver::rigidFrame() followed by a shift to the rest COM)
  Eigen::Isometry3d objectFrame = Eigen::Isometry3d::Identity();
  /// this object's figures (the loop's pace and counts are the scene's)
  LoopDiagnostics diag;
};

/// The state after a step, copied out of the simulation thread.
struct Snapshot {
  /// increases with every new state; equal sequence = identical content
  std::uint64_t sequence = 0;
  /// the loop's simulated time of this state (s; SimulationLoop::clockTime()): whole steps since
  /// the loop started (LoopTime::Followed: since the first followed time, which it starts at)
  double time = 0.0;
  /// false for a state of LoopTime::Followed written before the loop followed a first time: its
  /// time is not yet one of the followed clock's, and nothing may be stamped with it
  bool timeStarted = true;
  /// when this state was computed, on the loop clock's calendar (LoopClock::wallNow())
  std::chrono::system_clock::time_point wallTime;
  /// every object, in the World's order; objects[0] is the first (the single object)
  std::vector<ObjectSnapshot> objects;
  /// what each object exerted on each other it touched during the step (simulation frame)
  std::vector<ObjectPairWrench> objectWrenches;
  /// the colliders in the solver (poses at the end of the step) and what the object exerted on
  /// each during the step (simulation frame), all objects together
  std::map<std::string, Collider> colliders;
  std::map<std::string, ContactWrench> wrenches;
  /// per collider whose contacts the World records (World::recordContacts()), each particle's
  /// force on it over the step, every object's (simulation frame)
  std::map<std::string, std::vector<ParticleContact>> contacts;
  /// the whole scene's figures
  LoopDiagnostics diag;
};

/// Where a collider that follows a tf frame is (simulation frame), and how fast it moves.
struct ColliderMotion {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Vector3d linearVelocity = Eigen::Vector3d::Zero();   ///< m/s of the frame origin
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();  ///< rad/s
};

class SimulationLoop {
 public:
  /// Where a frame that drags follow is now: simFromFrame maps the frame into the simulation
  /// frame. Called by the simulation thread before every step, once per attached drag; it must
  /// not block (the node reads tf's latest transform). false = not known now: the drag holds
  /// its last pose.
  using FrameSource = std::function<bool(const std::string& frame, Eigen::Isometry3d& simFromFrame)>;
  /// Called on the simulation thread each time the loop's time moves on: `state` is the new
  /// state (already handed out by acquire()) after a step; nullptr when the time went on at rest
  /// (LoopTime::Served, Followed) and the state is the last one. The node serves /clock from it.
  /// It must not block, nor call acquire().
  using TickObserver = std::function<void(double time, const Snapshot* state)>;
  /// Something a user should hear about that is not a command's outcome (a followed clock that
  /// went back); called on the simulation thread.
  using Notice = std::function<void(const std::string& what)>;

  /// @param[in] world     the objects, ready (pins and colliders set), at least one; owned by
  ///                      the loop from now on
  /// @param[in] settings  pacing and idling
  /// @param[in] stats     where accepted and rejected commands are counted
  /// @param[in] clock     what the loop paces itself by; nullptr for the steady clock
  SimulationLoop(std::unique_ptr<World> world, const LoopSettings& settings,
                 std::shared_ptr<CommandStats> stats, std::shared_ptr<LoopClock> clock = nullptr);
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
  /// command is rejected ("queue_full"), its outcome delivered, and false returned. A command
  /// to an object the World no longer has is rejected when applied ("unknown_object").
  bool submit(Command command);
  /// Sets how attached drags (AttachCommand) find their frames; call before start(). Without a
  /// source, attached drags hold their pose.
  void setFrameSource(FrameSource source);
  /// Changes the pace (simulated seconds per wall second, > 0; 0 with LoopTime::Served) and
  /// wakes an idle loop.
  void setRealTimeFactor(double realTimeFactor);
  /// Sets what hears of each tick and what is said; call before start().
  void setTickObserver(TickObserver observer);
  void setNotice(Notice notice);
  /// LoopTime::Followed: the time to follow now (s, finite), from any thread.
  void followTime(double time);
  /// The loop's simulated time now (s), from any thread: the newest state's time, or later at
  /// rest (LoopTime::Served, Followed), where the state holds on.
  double clockTime() const { return clockTime_.load(); }

  /// Registers a collider that follows a tf frame; call before start() (colliders added at run
  /// time come as SetColliderCommand). It joins the solver at its first setColliderMotion().
  void addFollowedCollider(const std::string& id, const Collider& collider);
  /// The newest pose and velocity of followed collider `id`, from any thread (the node samples
  /// tf). Only the newest per collider is kept; before each step the loop moves the collider
  /// there, and between two samples along the sampled velocity for at most kMaxExtrapolation
  /// (then it holds still). Wakes a resting loop when the collider moves.
  void setColliderMotion(const std::string& id, const ColliderMotion& motion);
  /// Simulated seconds a followed collider keeps moving along its last sampled velocity.
  static constexpr double kMaxExtrapolation = 0.1;
  /// A stage of the loop longer than this (s of wall time) is said (watchStage()): the longest
  /// gap between states that the soak allows.
  static constexpr double kSlowStageSeconds = 1.0;

  /// The newest snapshot. Single reader: the reference stays valid and unchanged until the next
  /// call of acquire().
  const Snapshot& acquire();
  /// Copies the newest snapshot's small part (sequence, each object's name, version, drags,
  /// frame and figures, the colliders, the scene's figures; not the particles nor the wrenches)
  /// into `out`, from any thread beside the reader of acquire(): ~state goes out on a thread of
  /// its own, never held up by the meshes.
  void copySummary(Snapshot& out) const;
  /// Copies the newest snapshot whole (particles and rotations too, not the wrenches) into `out`,
  /// from any thread: the cameras render on a thread of their own. Nothing is copied when `out`
  /// already holds it (its sequence).
  void copyState(Snapshot& out) const;
  /// Why the last reset of a blown-up state happened (empty before the first), from any thread.
  std::string lastResetCause() const;
  /// Object `object`'s (index in objectNames()) current centre of mass (m), for range checks
  /// from any thread; its last one once it was removed.
  Eigen::Vector3d centerOfMass(std::size_t object = 0) const;
  /// Object `name`'s current centre of mass (m), from any thread; its last one once it was
  /// removed, the origin for a name the scene never had.
  Eigen::Vector3d centerOfMass(const std::string& name) const;

  /// the objects' names at start (World::objectNames()), their lattices (immutable; valid while
  /// the object is in the scene). Objects added and removed at run time (AddObjectCommand,
  /// RemoveObjectCommand) show in the snapshots (Snapshot::objects), not here.
  const std::vector<std::string>& objectNames() const { return startNames_; }
  const Lattice& lattice(std::size_t object = 0) const { return *startLattices_[object]; }

 private:
  /// The simulation thread: each turn collects what arrived, applies the commands, repaces,
  /// takes the steps due and sleeps until the next one.
  void run();
  /// What the loop found when it looked at its queue.
  struct Arrivals {
    bool stop = false;      ///< stop() was asked
    bool woken = false;     ///< a wake-up was asked (a new pace, a collider's motion)
    bool followed = false;  ///< LoopTime::Followed: a time has been followed
    double target = 0.0;    ///< the newest followed time
  };
  /// Waits while there is nothing to do (paused with no steps asked, or at rest), then takes the
  /// queued commands into `batch`.
  Arrivals collect(std::vector<Command>& batch);
  /// The clock's time since paceFrom_ owed at `pace`; paceFrom_ moves on to now, returned.
  std::chrono::steady_clock::time_point accrue(double pace);
  /// A new pace, an unpause or a wake from rest: the time before it is not owed at the new pace.
  void repace(double rtf, bool acted, bool woken);
  /// The whole steps due now.
  std::int64_t stepsDue(const Arrivals& arrived, double rtf, double dt);
  /// Takes the steps due (beyond maxCatchUpSteps dropped and counted; one early when a command
  /// acted between steps), or at rest moves the time on without stepping.
  void takeSteps(std::int64_t steps, bool acted, double dt);
  /// Sleeps until the next step is due or something arrives.
  void waitForNextStep(double rtf, double dt);
  /// A stage of the loop that held the simulation thread for more than kSlowStageSeconds of wall
  /// time (`since` its start) is said (Notice) with what it did: what holds the states up for
  /// seconds is then named in the node's log.
  void watchStage(std::chrono::steady_clock::time_point since, const char* what, long long count);
  /// the wall time collect() waited for the command queue's lock (not for work)
  std::chrono::steady_clock::duration queueLockWait_{};
  /// Applies one command to the object it addresses (target_); returns true when accepted.
  bool apply(Command& command);
  /// The command's body applied to target_.
  CommandOutcome applyBody(Command& command);
  CommandOutcome grab(const GrabCommand& c, const AttachCommand* attach = nullptr);
  CommandOutcome move(const MoveCommand& c);
  CommandOutcome release(const ReleaseCommand& c);
  CommandOutcome force(const ApplyForceCommand& c);
  CommandOutcome pinBox(const PinBoxCommand& c);
  CommandOutcome setParams(const ParamsCommand& c);
  CommandOutcome setCollider(const SetColliderCommand& c);
  CommandOutcome moveCollider(const MoveColliderCommand& c);
  CommandOutcome removeCollider(const RemoveColliderCommand& c);
  CommandOutcome addObject(const AddObjectCommand& c);
  CommandOutcome removeObject(const RemoveObjectCommand& c);
  CommandOutcome pause(const PauseCommand& c);
  CommandOutcome stepWhilePaused(const StepCommand& c);
  /// Object `k`'s entries in the per-object lists below, for a new object (at the end) or one
  /// that goes.
  void trackObject(const std::string& name);
  void untrackObject(std::size_t k);
  /// Before a step of dt: puts followed colliders at their newest sampled pose (or moves them on
  /// along the sampled velocity), adding those seen for the first time.
  void followColliders(double dt);
  /// Rejection: counted, and the outcome carries the detail.
  CommandOutcome reject(const std::string& reason, const std::string& detail);
  double massOf(const std::vector<std::uint32_t>& particles) const;
  /// Resets an object whose state is not finite to rest and counts it.
  void ensureFinite();
  /// Where object `k`'s state, which ensureFinite() is about to reset, went wrong, in words.
  std::string describeBlowUp(std::size_t k) const;
  /// Every object back to rest (pins kept, drags and forces released).
  void resetAll();
  /// Moves every attached drag to where its frame is now (see FrameSource).
  void followFrames();
  void timedStep();
  /// One step of the scene at the loop's time, counted on it.
  void stepScene(double dt);
  /// The loop's time moves on by `steps` steps without stepping the scene (at rest: the state
  /// holds); each tick is reported.
  void tickAtRest(std::int64_t steps, double dt);
  /// LoopTime::Followed: the whole steps from the loop's time to `target`, after starting the
  /// time at the first target or resetting the scene when the target went back.
  std::int64_t stepsToFollow(double target, double dt);
  /// While paused: up to maxCatchUpSteps of the steps StepCommands asked for; answers the
  /// command whose steps are done.
  void stepOnRequest(double dt);
  /// Sets the loop's time to `origin` + ticks_ steps of `dt`.
  void setClock(double dt);
  /// Starts a new averaging window for the step cost and the achieved real-time factor.
  void restartWindow(std::chrono::steady_clock::time_point now);
  void updateStillness(double simulated);
  /// Starts a new stillness window at the current positions.
  void restartStillness();
  void writeSnapshot();
  /// One object's part of the snapshot and figures.
  void writeObject(const Solver& solver, std::size_t k, ObjectSnapshot& o);

  std::unique_ptr<World> world_;
  /// the objects at start and their lattices, for objectNames() and lattice() (any thread)
  std::vector<std::string> startNames_;
  std::vector<const Lattice*> startLattices_;
  /// the objects now (the simulation thread's): names, solvers, lattices and rest centres of
  /// mass, in the World's order
  std::vector<std::string> names_;
  std::vector<Solver*> solvers_;
  std::vector<const Lattice*> lattices_;
  std::vector<Eigen::Vector3d> restCenterOfMass_;
  /// the object the command being applied addresses
  Solver* target_ = nullptr;
  LoopSettings settings_;
  std::shared_ptr<CommandStats> stats_;
  std::shared_ptr<LoopClock> clock_;

  // Command queue, shared with submitters.
  mutable std::mutex queueMutex_;
  std::condition_variable wakeUp_;
  std::vector<Command> queue_;
  bool stopRequested_ = false;
  bool wakeRequested_ = false;
  std::atomic<double> realTimeFactor_;
  /// LoopTime::Followed: the newest followed time, whether there was one, whether it moved since
  /// the loop last looked
  double followTarget_ = 0.0;
  bool followSet_ = false, followMoved_ = false;
  std::thread thread_;
  std::atomic<double> clockTime_{0.0};

  // Triple buffer: the thread fills back_, publishes it as ready_; the reader swaps ready_ into
  // front_. Only indices move under the lock.
  mutable std::mutex snapshotMutex_;
  std::array<Snapshot, 3> buffers_;
  int back_ = 0, ready_ = 1, front_ = 2;
  bool fresh_ = false;
  std::string lastReset_;  ///< lastResetCause(), under snapshotMutex_
  /// commands applied since the last snapshot, by CommandBody alternative (for describeBlowUp())
  std::array<std::uint32_t, std::variant_size_v<CommandBody>> appliedKinds_{};
  /// each object's centre of mass in the newest snapshot, by name (under snapshotMutex_)
  std::map<std::string, Eigen::Vector3d> centerOfMass_;

  // Followed colliders' motions, shared with setColliderMotion().
  std::mutex motionMutex_;
  std::map<std::string, ColliderMotion> motions_;        // not yet applied
  std::map<std::string, ColliderMotion> postedMotions_;  // the last posted, to decide on waking

  // Owned by the simulation thread.
  FrameSource frameSource_;
  TickObserver tickObserver_;
  Notice notice_;
  /// the loop's time: clockOrigin_ + ticks_ steps (s)
  double clockOrigin_ = 0.0;
  std::int64_t ticks_ = 0;
  bool clockStarted_ = false;  ///< LoopTime::Followed: a first time was followed
  bool running_ = false;  ///< run() has begun: snapshots from here on are ticks
  /// the newest time reported to the TickObserver: a state written again at one time (paused,
  /// a followed clock gone back and its reset) is no new tick
  double observed_ = -std::numeric_limits<double>::infinity();
  bool paused_ = false;
  bool resumed_ = false;  ///< unpaused since the loop last paced itself
  /// Paced and served times: the clock's time owed up to is paceFrom_, the simulated seconds
  /// due but not yet stepped owed_
  std::chrono::steady_clock::time_point paceFrom_;
  double owed_ = 0.0;
  /// steps StepCommands asked for and not yet taken, and the command to answer when they are
  std::int64_t stepsRequested_ = 0;
  OutcomePromise stepAnswer_;
  /// (object, drag id) -> the frame it follows
  std::map<std::pair<Solver*, std::string>, std::string> attachedFrames_;
  /// A collider that follows a tf frame: its shape, whether it is in the solver yet, the pose
  /// and velocity for the next step, and the simulated time since its last sample.
  struct Followed {
    Collider collider;
    bool inSolver = false;
    ColliderMotion motion;
    double sinceSample = 0.0;
  };
  std::map<std::string, Followed> followed_;
  std::map<std::string, ColliderMotion> incomingMotions_;
  bool collidersMoving_ = false;  // a followed collider moved in the last step
  LoopDiagnostics diag_;
  /// the World's time at the last reset of the whole scene: simulated time counts from there
  double timeOrigin_ = 0.0;
  std::uint64_t sequence_ = 0;
  bool idle_ = false;
  double stillFor_ = 0.0;  // simulated seconds of stillness
  /// per object, positions at the start of the stillness window
  std::vector<std::vector<Eigen::Vector3d>> stillFrom_;
  /// per object, the positions, pins and drags of its current version (ObjectSnapshot::version)
  struct Version {
    std::uint64_t sequence = 0;
    std::vector<Eigen::Vector3d> positions;
    std::size_t pinned = 0, drags = 0;
  };
  std::vector<Version> versions_;
  double windowSteps_ = 0.0, windowStepSeconds_ = 0.0, windowSimulated_ = 0.0;
  std::chrono::steady_clock::time_point windowStart_;
  bool windowComplete_ = false;  // a full window has passed since the last restart
};

}  // namespace deformable_flsm
