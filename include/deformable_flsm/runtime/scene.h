/// @file scene.h
/// Everything the node simulates and renders, built once at start-up from the parameters and
/// the loaded mesh: the lattice chosen from spacing, resolution or particle budget, the solver
/// with its pins, the render mesh (simplified on request) and its embedding, and the measured
/// cost of a step. Plain C++ (no master), so it is tested with gtest.
#pragma once

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/world.h"
#include "deformable_flsm/runtime/object_spec.h"
#include "deformable_flsm/runtime/node_params.h"

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {

/// What was chosen and measured, for the start-up report.
struct SceneInfo {
  /// "spacing", "resolution" or "particle_budget": which parameter set the lattice
  std::string latticeFrom;
  int resolution = 0;  ///< cells along the longest axis (0 when set by spacing)
  double spacing = 0.0;
  std::size_t particles = 0;
  int voxelizations = 0;
  double voxelizeSeconds = 0.0;
  int regionHalfWidth = 0;
  /// cells ~region_radius asked for when that was more than the solver allows and
  /// regionHalfWidth was clamped to kMaxRegionHalfWidth; 0 when not clamped
  int regionAskedCells = 0;
  /// the object's thinnest section (cells; measureSectionThickness() in core/section.h); 0 when
  /// it was not measured (sectionNotMeasured says why)
  int sectionCells = 0;
  std::string sectionNotMeasured;
  /// the half-width ~region_radius or ~region_half_width asked for, before
  /// ~region_from_section narrowed it to regionHalfWidth
  int regionHalfWidthAsked = 0;
  double objectSize = 0.0;  ///< m, diagonal of the rest bounding box of the lattice
  double totalMass = 0.0;   ///< kg
  std::size_t loadedTriangles = 0, renderTriangles = 0, renderVertices = 0;
  double simplifyError = 0.0;  ///< relative to the mesh extent
  std::vector<std::size_t> pinnedPerBox;
  std::size_t pinned = 0;
  /// colliders in the solver at start-up (the ground and those fixed in the simulation frame;
  /// colliders that follow a tf frame join when their frame is first known)
  std::size_t colliders = 0;
  /// radius of the particles' contact spheres (m)
  double contactRadius = 0.0;
  /// height of the ground's surface along its normal (m), when there is a ground
  double groundHeight = 0.0;
  /// alpha asked for by youngs_modulus (before the cap), alpha used, and the sub-steps that
  /// would bring the asked alpha under the cap when it is saturated (0 otherwise)
  double requestedAlpha = 0.0, alpha = 0.0;
  int substepsForModulus = 0;
  /// false for an object of ~objects: the objects step together (~state's step_time)
  bool stepMeasured = true;
  /// measured: wall time of one step (s) and ns per particle per sub-step
  double stepSeconds = 0.0, nsPerParticleSubstep = 0.0;
  /// fraction of one core the solver needs at the configured real-time factor
  double cpuFraction = 0.0;
};

struct Scene {
  std::shared_ptr<const Lattice> lattice;
  std::unique_ptr<Solver> solver;
  /// the mesh that ~mesh and ~surface show (simplified when render_triangle_budget asks)
  TriMesh renderMesh;
  std::unique_ptr<Embedding> embedding;
  SceneInfo info;
};

/// Builds the scene.
/// @param[in] params  validated node parameters
/// @param[in] mesh    the loaded mesh (m, oriented), already validated
/// @param[in] measureSteps  solver steps timed at start-up (0 skips the measurement)
/// @throws ParamError with a message naming the parameter to change (lattice too fine for
///         ~max_particles, ...). A region radius beyond the solver's limit is clamped, not
///         refused (SceneInfo::regionAskedCells, regionClampWarning()).
Scene buildScene(const NodeParams& params, const TriMesh& mesh, int measureSteps = 10);

/// One object of a scene of several (~objects), as the node renders it. Its lattice is the
/// one its Solver in the World holds (placed at the object's pose in ~frame_id).
struct SceneObject {
  std::string name;
  /// the object's parameters (the node's with the entry's keys applied)
  NodeParams params;
  std::shared_ptr<const Lattice> lattice;
  TriMesh renderMesh;
  std::unique_ptr<Embedding> embedding;
  SceneInfo info;
};

/// Every object the node simulates, in a World, with what renders each.
struct WorldScene {
  std::unique_ptr<World> world;
  /// in the world's order (World::objectNames())
  std::vector<SceneObject> objects;
};


/// Builds the objects of ~objects into one World sharing the colliders (~colliders, and the
/// ground below the lowest object) and the pins (~pinned boxes pin whatever object's rest
/// particles lie in them). Each object's step cost is not measured (SceneInfo::stepSeconds 0).
/// @param[in] params   validated node parameters (time step, sub-steps, colliders, contact)
/// @param[in] objects  parsed ~objects (parseObjectList())
/// @param[in] loadMesh  loads an object's mesh from its parameters (mesh, mesh_scale, mesh_rpy),
///                      throwing ParamError saying why it cannot; called once per distinct mesh
/// @throws ParamError naming the object and what to change (a lattice that cannot be built,
///         objects that start inside each other)
using MeshLoader = std::function<TriMesh(const NodeParams&)>;
WorldScene buildWorld(const NodeParams& params, const std::vector<ObjectSpec>& objects,
                      const MeshLoader& loadMesh);

/// An object built for a scene that is already running, off the simulation thread: what renders
/// it (SceneObject) and the solver parameters the simulation loop adds it with
/// (AddObjectCommand{object.name, object.lattice, solverParams}).
struct PreparedObject {
  SceneObject object;
  SolverParams solverParams;
};

/// Builds object `spec` for a running scene: loads its mesh (scaled, turned by mesh_rpy), places
/// it at its pose, chooses its lattice, regions and render mesh as buildWorld() does. ~pinned
/// boxes pin at start-up only: the object comes free (its pin_box service pins it). Whether it
/// starts inside another object is the World's to say when it is added.
/// @param[in] spec      the object (parseObjectEntry() in ros/object_params.h), validated
/// @param[in] loadMesh  as for buildWorld()
/// @throws ParamError naming the object and what to change (a mesh that cannot be loaded, a
///         lattice or solver that cannot be built)
PreparedObject prepareObject(const ObjectSpec& spec, const MeshLoader& loadMesh);

/// The single object of a node without ~objects: a World of one object named
/// ~object_frame_id holding the built scene's solver at rest (lattice, parameters, pins,
/// colliders).
WorldScene worldOfOne(Scene scene, const NodeParams& params);

/// A few lines for the start-up log: the lattice, the regions, the material, the cost.
std::string describeScene(const SceneInfo& info, const NodeParams& params);

/// Warning text when the time step is too long for the asked Young's modulus, else "".
std::string saturationWarning(const SceneInfo& info, const NodeParams& params);

/// Warning text when ~region_radius was more cells than the solver allows on this lattice and
/// the regions were clamped to the largest that fit, else "".
std::string regionClampWarning(const SceneInfo& info, const NodeParams& params);

/// Warning text when the regions are wider than the object's thinnest section in physical mode
/// (bending there comes out stiffer than the asked modulus: by how much, and what fixes it),
/// else "".
std::string sectionWarning(const SceneInfo& info, const NodeParams& params);

}  // namespace deformable_flsm
