/// @file commands.h
/// The commands the simulation thread accepts, as plain validated values (no ROS types), the
/// limits they are checked against, and the thread-safe tally of accepted and rejected ones.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/solver_params.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <functional>
#include <future>
#include <map>
#include <memory>
#include <mutex>
#include <string>
#include <variant>

namespace deformable_flsm {

/// Limits on commands, relative to the object so that they mean the same for a 2 cm part and a
/// 2 m one. L is Lattice::objectSize() (the diagonal of the rest bounding box, m).
struct CommandLimits {
  /// Points and targets farther than kMaxReach L from the object's centre of mass are refused.
  static constexpr double kMaxReach = 2.0;
  /// A force radius above kMaxRadius L (more than the whole object) is refused.
  static constexpr double kMaxRadius = 1.0;
  /// A force may accelerate the particles it acts on by at most kMaxAcceleration L per s^2
  /// (|F| / M_selected); ~300 m/s^2 for the 30 cm bunny diagonal.
  static constexpr double kMaxAcceleration = 1000.0;
  /// An impulse may change the velocity of the particles it acts on by at most
  /// kMaxSpeedChange L per s (|J| / M_selected); ~3 m/s for the bunny.
  static constexpr double kMaxSpeedChange = 10.0;
  /// Longest force (s of simulated time).
  static constexpr double kMaxForceDuration = 60.0;
  /// Particles one grab may take (nearest to a point).
  static constexpr std::uint32_t kMaxGrabCount = 512;
  /// Concurrent drags and timed forces.
  static constexpr std::size_t kMaxDrags = 32;
  static constexpr std::size_t kMaxForces = 256;
  /// Drag ids: 1 to kMaxIdLength printable characters.
  static constexpr std::size_t kMaxIdLength = 64;
  /// Commands waiting for the simulation thread; more are refused ("queue_full"). The thread
  /// drains the queue before every step, so this allows 256 commands per step (15k/s at 60 Hz).
  static constexpr std::size_t kQueueCapacity = 256;
  /// Steps one StepCommand may ask for (an hour of simulated time at 30 steps a second).
  static constexpr std::uint32_t kMaxSteps = 108000;
};

/// How a command ended, for services that wait for it.
struct CommandOutcome {
  bool accepted = false;
  /// accepted: what was done; rejected: why (a sentence a user can act on)
  std::string message;
  /// particles affected (pin box: particles in the box)
  std::size_t particles = 0;
  /// pinned particles after the command
  std::size_t pinnedTotal = 0;
};

/// Shared by a command and whoever waits for its outcome (a service call).
using OutcomePromise = std::shared_ptr<std::promise<CommandOutcome>>;

/// Grab `particle`, or the `count` particles nearest `point`, and pull their centroid to
/// `target` (simulation frame, m). stiffness 0 = hard, > 0 = spring (N/m). Replaces a drag with
/// the same id.
struct GrabCommand {
  std::string id;
  /// particle index, or -1 to pick by `point`
  std::int64_t particle = -1;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  std::uint32_t count = 1;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
  double stiffness = 0.0;
};

/// Grab like `grab` and attach the particles to the moving frame `frame`: each keeps its present
/// position in that frame. `pose` is the frame now (simulation frame <- frame); the simulation
/// loop follows the frame before every step through its FrameSource. An empty `frame` holds the
/// particles where they are (nothing to follow).
struct AttachCommand {
  GrabCommand grab;
  std::string frame;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

/// Move the target of drag `id` (simulation frame, m).
struct MoveCommand {
  std::string id;
  Eigen::Vector3d target = Eigen::Vector3d::Zero();
};

/// Let drag `id` go.
struct ReleaseCommand {
  std::string id;
};

/// A force (N) for `duration` s of simulated time, or an impulse (N s), on `particle` or on the
/// particles within `radius` of `point` (radius 0: the nearest particle), spread by mass: a
/// validated ForceCommand message.
struct ApplyForceCommand {
  std::int64_t particle = -1;
  Eigen::Vector3d point = Eigen::Vector3d::Zero();
  double radius = 0.0;
  /// force (N), or impulse (N s) when `impulse`
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  double duration = 0.0;
  bool impulse = false;
};

/// Back to rest (pins kept), drags and forces released.
struct ResetCommand {};
/// Release every drag.
struct ReleaseAllCommand {};
/// Pin (or free) the particles whose rest positions lie in [lo, hi] (m).
struct PinBoxCommand {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero();
  Eigen::Vector3d hi = Eigen::Vector3d::Zero();
  bool pin = true;
};
/// New solver parameters (validated; regionHalfWidth and density as at start-up).
struct ParamsCommand {
  SolverParams params;
};

/// Add collider `id`, or replace the collider of that id. With an empty followFrame the
/// collider stays at collider.pose (simulation frame); otherwise it follows that tf frame and
/// joins the solver at the first pose the node hands over (SimulationLoop::setColliderMotion).
struct SetColliderCommand {
  std::string id;
  Collider collider;
  std::string followFrame;
};
/// Move collider `id` to `pose` (simulation frame) with the given velocity over the next step
/// (m/s, rad/s, simulation frame); refused for a collider that follows a tf frame.
struct MoveColliderCommand {
  std::string id;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Vector3d linearVelocity = Eigen::Vector3d::Zero();
  Eigen::Vector3d angularVelocity = Eigen::Vector3d::Zero();
};
/// Remove collider `id`.
struct RemoveColliderCommand {
  std::string id;
};

/// Add deformable object `name` to the running scene. Its lattice (already placed where the
/// object starts) and parameters are built off the simulation thread (prepareObject() in
/// scene.h), so that loading and voxelizing a mesh never holds up a step; the loop only makes
/// its solver. Refused when the name is taken or the object starts inside another.
struct AddObjectCommand {
  std::string name;
  std::shared_ptr<const Lattice> lattice;
  /// the world's time step and sub-steps, the object's material and regions
  SolverParams params;
};
/// Remove object `name` with its drags, forces and pins; refused for an unknown name and for
/// the last object (a scene has at least one).
struct RemoveObjectCommand {
  std::string name;
};

/// Pause the simulation (no step, and its time stands still, until unpaused) or go on. Commands
/// are still applied while paused; they take effect at the next step.
struct PauseCommand {
  bool pause = true;
};
/// While paused: take `steps` steps (1 to CommandLimits::kMaxSteps) as fast as the machine can,
/// then answer; refused when not paused ("not_paused"). Lockstep with a controller or a learning
/// loop.
struct StepCommand {
  std::uint32_t steps = 1;
};

using CommandBody = std::variant<GrabCommand, AttachCommand, MoveCommand, ReleaseCommand,
                                 ApplyForceCommand, ResetCommand, ReleaseAllCommand, PinBoxCommand,
                                 ParamsCommand, SetColliderCommand, MoveColliderCommand,
                                 RemoveColliderCommand, AddObjectCommand, RemoveObjectCommand,
                                 PauseCommand, StepCommand>;

/// A command and, optionally, the promise its outcome is delivered to.
struct Command {
  CommandBody body;
  OutcomePromise outcome;
  /// the object it addresses (World's name); "" = the first object. Colliders, reset,
  /// release-all and adding or removing an object concern the scene (their body names the
  /// object).
  std::string object;
};

/// Thread-safe tally of commands: accepted, and rejected by reason. Reasons are short keys
/// ("non_finite", "unknown_frame", ...) reported in ~state; details go to the log hook.
class CommandStats {
 public:
  struct Counts {
    std::uint64_t accepted = 0;
    std::uint64_t rejected = 0;
    std::map<std::string, std::uint64_t> rejectedByReason;
    /// detail of the last rejection ("" before the first)
    std::string lastRejection;
  };
  /// Called on every rejection with (reason, detail), from whichever thread rejected.
  using RejectHook = std::function<void(const std::string&, const std::string&)>;

  void setRejectHook(RejectHook hook);
  void accept();
  void reject(const std::string& reason, const std::string& detail);
  /// `count` rejections for one reason at once (messages lost before they could be looked at).
  void reject(const std::string& reason, const std::string& detail, std::uint64_t count);
  Counts counts() const;

 private:
  mutable std::mutex mutex_;
  Counts counts_;
  RejectHook hook_;
};

}  // namespace deformable_flsm
