/// @file node_params.h
/// Everything the node is configured with, as plain values: the object (mesh, lattice, regions,
/// material), running and publishing, pins, colliders, the robot and the objects' contact; and
/// their validation, with messages that name the parameter to fix. Reading them from the
/// parameter server is ros/param_loader.h.
#pragma once

#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/solver_params.h"
#include "deformable_flsm/core/world.h"
#include "deformable_flsm/runtime/camera_spec.h"
#include "deformable_flsm/runtime/collider_spec.h"
#include "deformable_flsm/runtime/robot_spec.h"
#include "deformable_flsm/runtime/tactile.h"

#include <Eigen/Core>

#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {

/// Thrown for a parameter that has the wrong type or is out of range; the message names the
/// parameter, the value found and what would be accepted.
class ParamError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An axis-aligned box [lo, hi] (m, simulation frame, compared with rest positions).
struct Box {
  Eigen::Vector3d lo = Eigen::Vector3d::Zero();
  Eigen::Vector3d hi = Eigen::Vector3d::Zero();
};

/// Everything the node reads from `~` parameters. Plain values; SolverParams is filled here and
/// completed (region half-width from the radius) once the lattice spacing is known.
///
/// "Unset" for spacing, resolution, region_radius and region_half_width is 0: the lattice comes
/// from ~spacing or ~resolution when one is set (both is an error), else from
/// ~particle_budget; regions from ~region_radius or ~region_half_width (both is an error),
/// else w = 2.
struct NodeParams {
  /// Default render mesh: the Stanford bunny shipped by Debian's glmark2-data.
  static constexpr const char* kDefaultMesh = kBunnyMeshPath;

  // --- the object -------------------------------------------------------------------------
  /// ~mesh: a file path or a package://<pkg>/<path> or file:// URL
  std::string mesh = kDefaultMesh;
  /// ~mesh_scale: uniform scale from file units to metres (> 0)
  double meshScale = 0.1;
  /// ~mesh_rpy: roll, pitch, yaw (rad) applied to the mesh at load, after the scale
  Eigen::Vector3d meshRpy = Eigen::Vector3d::Zero();
  /// ~frame_id: the simulation frame; every published message and ~pinned are in it
  std::string frameId = "world";
  /// ~object_frame_id: tf child frame of the object's best-fit rigid motion
  std::string objectFrameId = "flsm_object";

  // --- the lattice ------------------------------------------------------------------------
  /// ~spacing: lattice cell edge (m); 0 = unset
  double spacing = 0.0;
  /// ~resolution: cells along the mesh's longest axis; 0 = unset
  int resolution = 0;
  /// ~particle_budget: when neither spacing nor resolution is set, the finest lattice with at
  /// most this many particles
  int particleBudget = 4000;
  /// ~max_particles: hard limit on the particle count of any lattice (>= 1)
  int maxParticles = 200000;

  // --- regions and material ---------------------------------------------------------------
  /// ~region_radius: region half-width in metres (preferred; rounded to whole cells, at most
  /// kMaxRegionHalfWidth cells: clamped with a warning); 0 = unset
  double regionRadius = 0.0;
  /// ~region_half_width: region half-width in cells (classic); 0 = unset
  int regionHalfWidth = 0;
  /// ~region_from_section: narrow the regions (from ~region_radius or ~region_half_width) to the
  /// widest that are no wider than the object's thinnest section (core/section.h), so that
  /// bending keeps the asked modulus (within 10 % of linear FEM on cantilevers; regions wider
  /// than the section bend too stiffly, core/section.h). Narrower regions need more sub-steps for
  /// the same modulus near the cap (the node warns when they do). false: the regions as asked,
  /// with a warning when they are wider than the thinnest section.
  bool regionFromSection = true;
  /// ~material: how the stiffness is given. Youngs: by ~youngs_modulus (> 0), alpha follows
  /// from it (the cap being ~stiffness); Classic: alpha = ~stiffness per sub-step, as in the
  /// original FastLSM (youngs_modulus is not used). No value of youngs_modulus switches
  /// between the two: a typo such as -5 is refused, not taken as "classic".
  enum class Material { Youngs, Classic };
  Material material = Material::Youngs;
  /// ~youngs_modulus (Pa): the material with Material::Youngs; a firm jelly by default. The
  /// solver receives it in solver.youngsModulus (0 there under Material::Classic).
  double youngsModulus = 14000.0;
  /// ~poissons_ratio: Poisson's ratio with Material::Youngs, [0, 0.45]; solver.poissonsRatio
  /// (0 there under Material::Classic, which has no Poisson effect).
  double poissonsRatio = 0.0;
  /// ~stiffness, ~damping, ~ambient_damping, ~gravity, ~time_step, ~substeps, ~density,
  /// ~solver, ~threads, ~contact_radius; youngsModulus and poissonsRatio from ~material,
  /// ~youngs_modulus and ~poissons_ratio (see applyMaterial()); regionHalfWidth is set by
  /// resolveRegionHalfWidth()
  SolverParams solver;
  /// ~integrator auto: buildNodeScene() chooses solver.integrator for the whole scene at start-up,
  /// the explicit step where it gives every object its modulus at solver.substeps, else the
  /// implicit step at one sub-step (solver.integrator and solver.substeps then hold the choice)
  bool integratorAuto = false;

  // --- running and publishing -------------------------------------------------------------
  /// ~publish_rate: rate of every published topic and of tf (Hz, (0, kMaxPublishRate])
  double publishRate = 30.0;
  /// ~republish_at_rest: at rest, keep sending the markers ~mesh and ~lattice at ~publish_rate
  /// (copies of the last state) instead of once; for consumers that expect a steady stream
  /// (rate monitors, bag recording); it costs the mesh's serialisation at every tick
  /// (docs/design.md). The clouds ~surface, ~particles, ~state and tf keep the rate at rest in
  /// any case.
  bool republishAtRest = false;
  /// ~real_time_factor: simulated seconds per wall-clock second ((0, kMaxRealTimeFactor]; 0, as
  /// fast as the machine can, with ~clock sim only; not used with ~clock follow)
  double realTimeFactor = 1.0;
  /// ~clock: what the node's time is and what its messages are stamped with.
  ///   Wall:   paced by the wall clock (a node beside a real robot); every message carries the
  ///           wall time at which its state was computed (at rest or paused: the time it is sent,
  ///           the state holding on).
  ///   Sim:    the node serves /clock with its simulated time, once per step after that step's
  ///           tf (/use_sim_time must be true: flsm.launch sim_time:=true), paced by the wall
  ///           clock at ~real_time_factor; every message carries the simulated time of its state.
  ///   Follow: another simulator serves /clock (Gazebo, rosbag play --clock); the node steps so
  ///           that its time follows it, never ahead, and stamps as Sim does.
  enum class Clock { Wall, Sim, Follow };
  Clock clock = Clock::Wall;
  /// ~start_paused: nothing steps until ~unpause or ~step
  bool startPaused = false;
  /// ~pinned: boxes whose particles (by rest position) are pinned at start-up
  std::vector<Box> pinned;
  /// ~ground: a plane collider "ground" below the object, normal against gravity
  bool ground = true;
  /// ~ground_clearance: gap (m, >= 0) between the object's lowest rest point and the ground
  double groundClearance = 0.1;
  /// ~colliders: more colliders (parsed and validated, meshes loaded)
  std::vector<ColliderSpec> colliders;
  /// ~cameras: simulated depth cameras (parsed and validated)
  std::vector<CameraSpec> cameras;
  /// ~tactile: tactile sensors on box colliders' faces (parsed and checked against the colliders)
  std::vector<TactileSpec> tactile;
  /// ~robot_description and ~robot_*: the robot's collision model (no colliders when
  /// robot.options.descriptionParam is empty)
  RobotColliders robot;
  /// ~render_triangle_budget: simplify the render mesh to at most this many triangles at
  /// load (0 = render the mesh as loaded); the lattice is chosen from the full mesh
  int renderTriangleBudget = 0;
  /// ~object_contact, ~self_contact, ~object_static_friction, ~object_kinetic_friction: how the
  /// objects of ~objects touch each other and themselves
  ObjectContactParams objectContact;
  /// ~object_sleep: an object of ~objects at rest (LoopSettings' rest: restFraction of its size
  /// over idleHold) is not stepped until something moves near it (SleepParams)
  bool objectSleep = true;

  static constexpr double kMaxPublishRate = 1000.0;
  static constexpr double kMaxRealTimeFactor = 100.0;

  /// @throws ParamError naming the first field that is out of range.
  void validate() const;
  /// solver.youngsModulus from material and youngsModulus: the modulus, or 0 (alpha =
  /// stiffness) under Material::Classic.
  void applyMaterial() {
    solver.youngsModulus = material == Material::Youngs ? youngsModulus : 0.0;
    solver.poissonsRatio = material == Material::Youngs ? poissonsRatio : 0.0;
  }

  /// Region half-width w for a lattice of the given spacing: from regionRadius (rounded to
  /// whole cells), from regionHalfWidth, or else 1 with Material::Youngs (the narrowest
  /// regions: a contact a few cells wide meets the asked modulus) and 2 with Material::Classic.
  /// A radius of more cells than the solver accepts (kMaxRegionHalfWidth) on this lattice is
  /// clamped to the largest that fits, and
  /// `askedCells`, when given, receives the cells asked for (else 0), so that the caller can
  /// warn: a radius that suits one mesh must not stop another from starting.
  int resolveRegionHalfWidth(double latticeSpacing, int* askedCells = nullptr) const;

 private:
  /// validate()'s parts: the first scalar out of range in words ("" when none is), the pinned
  /// boxes, the colliders' ids and count, the friction pairs (each throws ParamError)
  std::string scalarProblem() const;
  void checkPinned() const;
  void checkColliders() const;
  void checkFrictions() const;
};

/// "youngs" or "classic".
const char* toString(NodeParams::Material material);
/// Parses "youngs" / "classic"; false for anything else.
bool parseMaterial(const std::string& name, NodeParams::Material& material);
/// A name that can stand as one level of a topic's name (a camera's, a tactile pad's): not
/// empty, no '/', '~' or space.
bool isTopicLevel(const std::string& name);

/// "wall", "sim" or "follow".
const char* toString(NodeParams::Clock clock);
/// Parses "wall" / "sim" / "follow"; false for anything else.
bool parseClock(const std::string& name, NodeParams::Clock& clock);

}  // namespace deformable_flsm
