/// @file scene.h
/// Everything the node simulates and renders, built once at start-up from the parameters and
/// the loaded mesh: the lattice chosen from spacing, resolution or particle budget, the solver
/// with its pins, the render mesh (simplified on request) and its embedding, and the measured
/// cost of a step. Plain C++ (no master), so it is tested with gtest. What it chose is printed
/// by runtime/scene_report.h.
#pragma once

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/world.h"
#include "deformable_flsm/runtime/object_spec.h"
#include "deformable_flsm/runtime/node_params.h"
#include "deformable_flsm/runtime/scene_report.h"  // SceneInfo, and the report of it

#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {

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

/// The node's scene from its parameters: the object of ~mesh (buildScene(), worldOfOne()) or
/// those of ~objects (buildWorld()). With ~integrator auto (NodeParams::integratorAuto) it is built
/// with the explicit step; if that step would make any object softer than asked at ~substeps, the
/// scene is built again with the implicit step at one sub-step. `params` and
/// `objects` come back with the integrator and sub-steps chosen (what the simulation loop and
/// objects added later use), and each object's SceneInfo::integratorChoice says why.
/// @param[in] measureSteps  as for buildScene() (the object of ~mesh only)
/// @throws ParamError as buildScene() and buildWorld() do
WorldScene buildNodeScene(NodeParams& params, std::vector<ObjectSpec>& objects, const MeshLoader& loadMesh,
                          int measureSteps = 10);

/// The single object of a node without ~objects: a World of one object named
/// ~object_frame_id holding the built scene's solver at rest (lattice, parameters, pins,
/// colliders).
WorldScene worldOfOne(Scene scene, const NodeParams& params);

}  // namespace deformable_flsm
