#include "deformable_flsm/runtime/scene.h"

#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/section.h"
#include "deformable_flsm/core/simd.h"
#include "deformable_flsm/core/voxelizer.h"
#include "deformable_flsm/runtime/format.h"
#include "deformable_flsm/runtime/render_mesh.h"
#include "deformable_flsm/runtime/simulation_loop.h"

#include <chrono>
#include <limits>
#include <map>
#include <tuple>
#include <cmath>

namespace deformable_flsm {

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point t0) {
  return std::chrono::duration<double>(Clock::now() - t0).count();
}

Voxelization chooseLattice(const NodeParams& params, const TriMesh& mesh, SceneInfo& info) {
  const Clock::time_point t0 = Clock::now();
  Voxelization voxels;
  try {
    if (params.spacing > 0.0 || params.resolution > 0) {
      VoxelizeOptions o;
      o.spacing = params.spacing;
      o.resolution = params.resolution;
      o.maxParticles = static_cast<std::size_t>(params.maxParticles);
      voxels = voxelize(mesh, o);
      info.latticeFrom = params.spacing > 0.0 ? "spacing" : "resolution";
      info.resolution = params.resolution;
      info.voxelizations = 1;
    } else {
      ResolutionChoice c =
          finestResolutionWithin(mesh, static_cast<std::size_t>(params.particleBudget));
      voxels = std::move(c.voxels);
      info.latticeFrom = "particle_budget";
      info.resolution = c.resolution;
      info.voxelizations = c.voxelizations;
    }
  } catch (const VoxelizationError& e) {
    throw ParamError(std::string("the lattice cannot be built: ") + e.what() +
                     ". Change ~spacing, ~resolution, ~particle_budget or ~max_particles.");
  }
  info.voxelizeSeconds = secondsSince(t0);
  info.spacing = voxels.spacing;
  info.particles = voxels.cells.size();
  return voxels;
}

/// Sub-steps at which the solver would give the asked alpha: the asked alpha grows like h^2,
/// i.e. like 1 / substeps^2, and the solver caps it at alpha(); 0 when not saturated. With strong
/// damping the cap also rises with the sub-steps (the damping keeps more of the velocity in a
/// shorter one), so this is an upper bound there: enough, perhaps more than needed.
int substepsForModulus(const Solver& solver) {
  if (!solver.stiffnessSaturated()) return 0;
  const SolverParams& p = solver.params();
  const double asked = p.requestedAlpha(solver.lattice().spacing());
  return static_cast<int>(std::ceil(p.substeps * std::sqrt(asked / solver.alpha())));
}

}  // namespace

namespace {

/// The lattice of one object and its solver parameters (regions resolved), with what was
/// chosen in `info`.
std::shared_ptr<const Lattice> buildLattice(const NodeParams& params, const TriMesh& mesh,
                                            SceneInfo& info, SolverParams& solverParams) {
  const Voxelization voxels = chooseLattice(params, mesh, info);
  solverParams = params.solver;
  info.regionHalfWidthAsked = params.resolveRegionHalfWidth(voxels.spacing, &info.regionAskedCells);
  try {
    info.sectionCells = measureSectionThickness(voxels).thinnest;
  } catch (const std::invalid_argument& e) {
    info.sectionCells = 0;  // not measured: the regions stay as asked
    info.sectionNotMeasured = e.what();
  }
  solverParams.regionHalfWidth = params.regionFromSection && info.sectionCells > 0
                                     ? regionHalfWidthForSection(info.sectionCells, info.regionHalfWidthAsked)
                                     : info.regionHalfWidthAsked;
  info.regionHalfWidth = solverParams.regionHalfWidth;
  try {
    return std::make_shared<const Lattice>(voxels, solverParams.density, solverParams.regionHalfWidth);
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string("the solver cannot be built: ") + e.what());
  }
}

/// What the solver chose from the parameters on this lattice.
void describeSolver(const Solver& solver, SceneInfo& info) {
  const Lattice& L = solver.lattice();
  info.objectSize = L.objectSize();
  info.totalMass = L.totalMass();
  info.requestedAlpha = solver.params().requestedAlpha(L.spacing());
  info.alpha = solver.alpha();
  info.substepsForModulus = substepsForModulus(solver);
  info.contactRadius = solver.contactRadius();
}

/// The render mesh (simplified when ~render_triangle_budget asks) and its embedding.
void buildRender(const NodeParams& params, const TriMesh& mesh, const Lattice& lattice,
                 SceneInfo& info, TriMesh& renderMesh, std::unique_ptr<Embedding>& embedding) {
  info.loadedTriangles = mesh.triangles.size();
  if (params.renderTriangleBudget > 0) {
    SimplifyResult simple =
        simplifyMesh(mesh, static_cast<std::size_t>(params.renderTriangleBudget));
    renderMesh = std::move(simple.mesh);
    info.simplifyError = simple.relativeError;
  } else {
    renderMesh = mesh;
  }
  info.renderTriangles = renderMesh.triangles.size();
  info.renderVertices = renderMesh.vertices.size();
  embedding = std::make_unique<Embedding>(lattice, renderMesh.vertices);
}

double heightAlong(const Collider& ground) {
  return ground.pose.translation().dot(ground.pose.linear().col(2));
}

/// Object `spec` (its mesh at its pose) added to `world`, pinned by the node's ~pinned boxes.
SceneObject addWorldObject(World& world, const ObjectSpec& spec, const NodeParams& params,
                           const TriMesh& mesh) {
  const NodeParams& p = spec.params;
  SceneObject object;
  object.name = spec.name;
  object.params = p;
  object.info.stepMeasured = false;
  SolverParams solverParams;
  try {
    object.lattice = buildLattice(p, mesh, object.info, solverParams);
    Solver& solver = world.addObject(spec.name, object.lattice, solverParams);
    describeSolver(solver, object.info);
    for (const Box& box : params.pinned) {
      object.info.pinnedPerBox.push_back(solver.pinBox(box.lo, box.hi, true));
    }
    object.info.pinned = solver.pinnedCount();
  } catch (const ParamError& e) {
    throw ParamError("object '" + spec.name + "': " + e.what());
  } catch (const std::invalid_argument& e) {  // World: objects inside each other
    throw ParamError("object '" + spec.name + "' cannot be added: " + e.what() +
                     ". Move the objects apart with their pose.");
  }
  buildRender(p, mesh, *object.lattice, object.info, object.renderMesh, object.embedding);
  return object;
}

/// The ground below the lowest object and the colliders fixed in the simulation frame, shared by
/// every object of the world.
void setWorldColliders(const NodeParams& params, const std::vector<TriMesh>& meshes,
                       WorldScene& scene) {
  World& world = *scene.world;
  try {
    if (params.ground) {
      // Below the lowest object: the ground of each object alone, the lowest of them.
      Collider ground;
      double lowest = std::numeric_limits<double>::infinity();
      for (std::size_t k = 0; k < scene.objects.size(); ++k) {
        const SceneObject& o = scene.objects[k];
        const Collider g = groundCollider(*o.lattice, meshes[k], params.solver.gravity,
                                          o.info.contactRadius, params.groundClearance);
        if (heightAlong(g) < lowest) {
          lowest = heightAlong(g);
          ground = g;
        }
      }
      world.setCollider(ColliderLimits::kGroundId, ground);
      for (SceneObject& o : scene.objects) o.info.groundHeight = lowest;
    }
    for (const ColliderSpec& spec : params.colliders) {
      if (spec.followFrame.empty()) world.setCollider(spec.id, spec.collider);
    }
  } catch (const std::exception& e) {  // invalid_argument, MeshError
    throw ParamError(std::string("a collider cannot be used: ") + e.what());
  }
  const std::size_t colliders = world.object(world.objectNames().front())->colliders().size();
  for (SceneObject& o : scene.objects) o.info.colliders = colliders;
}

}  // namespace

Scene buildScene(const NodeParams& params, const TriMesh& mesh, int measureSteps) {
  Scene scene;
  SceneInfo& info = scene.info;
  SolverParams solverParams;
  scene.lattice = buildLattice(params, mesh, info, solverParams);
  try {
    scene.solver = std::make_unique<Solver>(scene.lattice, solverParams);
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string("the solver cannot be built: ") + e.what());
  }
  const Lattice& L = *scene.lattice;
  Solver& solver = *scene.solver;
  describeSolver(solver, info);

  // Colliders before the measurement, so that it includes their cost (reset() keeps them).
  try {
    if (params.ground) {
      const Collider ground = groundCollider(L, mesh, solverParams.gravity, info.contactRadius,
                                             params.groundClearance);
      info.groundHeight = heightAlong(ground);
      solver.setCollider(ColliderLimits::kGroundId, ground);
    }
    for (const ColliderSpec& spec : params.colliders) {
      if (spec.followFrame.empty()) solver.setCollider(spec.id, spec.collider);
    }
  } catch (const std::exception& e) {  // invalid_argument, MeshError
    throw ParamError(std::string("a collider cannot be used: ") + e.what());
  }
  info.colliders = solver.colliders().size();

  // The cost of a step, measured on this machine with this lattice, then back to rest.
  if (measureSteps > 0) {
    solver.step();  // warm-up: first touches of the scratch arrays
    const Clock::time_point t0 = Clock::now();
    for (int s = 0; s < measureSteps; ++s) solver.step();
    info.stepSeconds = secondsSince(t0) / measureSteps;
    info.nsPerParticleSubstep =
        1e9 * info.stepSeconds / (static_cast<double>(L.size()) * solverParams.substeps);
    info.cpuFraction = info.stepSeconds * params.realTimeFactor / solverParams.timeStep;
    info.simd = simdLevelNote();
    solver.reset();
  }

  for (const Box& box : params.pinned) {
    info.pinnedPerBox.push_back(solver.pinBox(box.lo, box.hi, true));
  }
  info.pinned = solver.pinnedCount();
  buildRender(params, mesh, L, info, scene.renderMesh, scene.embedding);
  return scene;
}

WorldScene buildWorld(const NodeParams& params, const std::vector<ObjectSpec>& objects,
                      const MeshLoader& loadMesh) {
  WorldScene scene;
  try {
    scene.world = std::make_unique<World>(params.solver.timeStep, params.solver.substeps,
                                          params.objectContact);
  } catch (const std::invalid_argument& e) {
    throw ParamError(std::string("the scene cannot be built: ") + e.what());
  }
  World& world = *scene.world;
  if (params.objectSleep) {
    // at rest as the loop means it: its rest, per object
    const LoopSettings rest;
    SleepParams sleep;
    sleep.fraction = rest.restFraction;
    sleep.hold = rest.idleHold;
    world.setSleepParams(sleep);
  }
  // World::bdf2Refusal()'s rule, refused before any lattice is built, in the parameters' names
  for (const ObjectSpec& spec : objects)
    if (World::bdf2Refusal(spec.params.solver, objects.size(), params.objectContact) != nullptr)
      throw ParamError("object '" + spec.name + "': ~implicit_scheme bdf2 steps one object alone, and these objects "
                       "touch each other (~object_contact) or themselves (~self_contact): set ~implicit_scheme to "
                       "backward_euler, or turn object contact off");
  // Objects of the same mesh file, scale and orientation share one load.
  std::map<std::tuple<std::string, double, double, double, double>, TriMesh> loaded;
  std::vector<TriMesh> meshes;  // each object's mesh at its pose, for the ground
  for (const ObjectSpec& spec : objects) {
    const NodeParams& p = spec.params;
    const auto key = std::make_tuple(p.mesh, p.meshScale, p.meshRpy.x(), p.meshRpy.y(), p.meshRpy.z());
    auto it = loaded.find(key);
    if (it == loaded.end()) {
      try {
        it = loaded.emplace(key, loadMesh(p)).first;
      } catch (const ParamError& e) {
        throw ParamError("object '" + spec.name + "': " + e.what());
      }
    }
    TriMesh mesh = it->second;
    for (Eigen::Vector3d& v : mesh.vertices) v = spec.pose * v;

    SceneObject object = addWorldObject(world, spec, params, mesh);
    meshes.push_back(std::move(mesh));
    scene.objects.push_back(std::move(object));
  }
  setWorldColliders(params, meshes, scene);
  return scene;
}

PreparedObject prepareObject(const ObjectSpec& spec, const MeshLoader& loadMesh) {
  PreparedObject prepared;
  SceneObject& object = prepared.object;
  object.name = spec.name;
  object.params = spec.params;
  object.info.stepMeasured = false;
  try {
    TriMesh mesh = loadMesh(spec.params);
    for (Eigen::Vector3d& v : mesh.vertices) v = spec.pose * v;
    object.lattice = buildLattice(spec.params, mesh, object.info, prepared.solverParams);
    // A solver of its own, off the simulation thread, for what it chooses (the contact radius,
    // alpha); the loop makes the one it steps.
    try {
      describeSolver(Solver(object.lattice, prepared.solverParams), object.info);
    } catch (const std::invalid_argument& e) {
      throw ParamError(std::string("the solver cannot be built: ") + e.what());
    }
    buildRender(spec.params, mesh, *object.lattice, object.info, object.renderMesh, object.embedding);
  } catch (const ParamError& e) {
    throw ParamError("object '" + spec.name + "': " + e.what());
  }
  return prepared;
}

namespace {

std::unique_ptr<World> worldHolding(const Solver& solver, std::shared_ptr<const Lattice> lattice,
                                    const std::string& name, const ObjectContactParams& contact) {
  const SolverParams& p = solver.params();
  auto world = std::make_unique<World>(p.timeStep, p.substeps, contact);
  Solver& object = world->addObject(name, std::move(lattice), p);
  for (std::uint32_t i = 0; i < solver.lattice().size(); ++i)
    if (solver.isPinned(i)) object.setPinned(i, true);
  for (const auto& entry : solver.colliders()) world->setCollider(entry.first, entry.second);
  return world;
}

}  // namespace

WorldScene worldOfOne(Scene scene, const NodeParams& params) {
  WorldScene world;
  world.world = worldHolding(*scene.solver, scene.lattice, params.objectFrameId, params.objectContact);
  SceneObject object;
  object.name = params.objectFrameId;
  object.params = params;
  object.lattice = scene.lattice;
  object.renderMesh = std::move(scene.renderMesh);
  object.embedding = std::move(scene.embedding);
  object.info = scene.info;
  world.objects.push_back(std::move(object));
  return world;
}

namespace {

void setIntegrator(NodeParams& params, std::vector<ObjectSpec>& objects, Integrator integrator, int substeps) {
  params.solver.integrator = integrator;
  params.solver.substeps = substeps;
  for (ObjectSpec& spec : objects) {
    spec.params.solver.integrator = integrator;
    spec.params.solver.substeps = substeps;
  }
}

}  // namespace

WorldScene buildNodeScene(NodeParams& params, std::vector<ObjectSpec>& objects, const MeshLoader& loadMesh,
                          int measureSteps) {
  auto build = [&](int measure) {
    return objects.empty() ? worldOfOne(buildScene(params, loadMesh(params), measure), params)
                           : buildWorld(params, objects, loadMesh);
  };
  if (!params.integratorAuto) return build(measureSteps);
  const int substeps = params.solver.substeps;
  setIntegrator(params, objects, Integrator::Explicit, substeps);
  WorldScene scene = build(measureSteps);
  // the object the explicit step would soften most
  const SceneObject* softest = nullptr;
  for (const SceneObject& o : scene.objects)
    if (o.info.substepsForModulus > 0 &&
        (softest == nullptr || o.info.requestedAlpha / o.info.alpha > softest->info.requestedAlpha / softest->info.alpha))
      softest = &o;
  std::string choice;
  if (softest == nullptr) {
    choice = formatted("explicit (~integrator auto): it gives the modulus as asked at ~substeps %d", substeps);
  } else {
    const std::string who = objects.empty() ? "the object" : "object '" + softest->name + "'";
    choice = formatted("implicit at 1 sub-step (~integrator auto): the explicit step at ~substeps %d would make %s "
                       "%.3g times softer than asked (it needs %d)",
                       substeps, who.c_str(), softest->info.requestedAlpha / softest->info.alpha,
                       softest->info.substepsForModulus);
    setIntegrator(params, objects, Integrator::Implicit, 1);
    scene = build(measureSteps);
  }
  for (SceneObject& o : scene.objects) o.info.integratorChoice = choice;
  return scene;
}

}  // namespace deformable_flsm
