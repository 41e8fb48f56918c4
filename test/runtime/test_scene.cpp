/// @file test_scene.cpp
/// Tests of runtime/scene.h and NodeParams: the lattice comes from exactly one of spacing,
/// resolution and particle budget; regions from radius or half-width; pins, simplified render
/// mesh and start-up measurement; every invalid parameter is refused with a message naming it.
#include "deformable_flsm/runtime/scene.h"

#include "../core/fixtures.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>

namespace deformable_flsm {
namespace {

const char* const kBunnyPath = deformable_flsm::kBunnyMeshPath;


NodeParams cubeParams() {
  NodeParams p;
  p.resolution = 10;  // 1000 particles on the unit cube
  p.solver.gravity.setZero();
  return p;
}

TEST(BuildScene, ResolutionGivesTheExactLattice) {
  const Scene s = buildScene(cubeParams(), test::boxMesh(Eigen::Vector3d::Ones()), 2);
  EXPECT_EQ(s.info.latticeFrom, "resolution");
  EXPECT_EQ(s.info.particles, 1000u);
  EXPECT_DOUBLE_EQ(s.info.spacing, 0.1);
  // neither radius nor half-width: the narrowest regions, right under a finger
  EXPECT_EQ(s.info.regionHalfWidth, 1);
  EXPECT_NE(describeScene(s.info, cubeParams()).find("w = 1 cells (0.1 m) (the default)"), std::string::npos)
      << describeScene(s.info, cubeParams());
  NodeParams classic = cubeParams();
  classic.material = NodeParams::Material::Classic;
  EXPECT_EQ(classic.resolveRegionHalfWidth(0.1), 2);  // alpha per sub-step: FastLSM's own default
  EXPECT_EQ(s.solver->lattice().size(), 1000u);
  EXPECT_GT(s.info.stepSeconds, 0.0);
  EXPECT_GT(s.info.nsPerParticleSubstep, 0.0);
  EXPECT_GT(s.info.cpuFraction, 0.0);
  // The measurement ran the solver, then put it back to rest.
  EXPECT_EQ(s.solver->time(), 0.0);
  EXPECT_EQ(s.solver->maxDisplacement(), 0.0);
}

TEST(BuildScene, SpacingAndBudget) {
  NodeParams p = cubeParams();
  p.resolution = 0;
  p.spacing = 0.25;
  Scene s = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
  EXPECT_EQ(s.info.latticeFrom, "spacing");
  EXPECT_EQ(s.info.particles, 64u);

  p.spacing = 0.0;
  p.particleBudget = 500;  // 7^3 = 343 fits, 8^3 = 512 does not
  s = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
  EXPECT_EQ(s.info.latticeFrom, "particle_budget");
  EXPECT_EQ(s.info.resolution, 7);
  EXPECT_EQ(s.info.particles, 343u);
}

TEST(BuildScene, RegionRadiusInMetresBecomesWholeCells) {
  NodeParams p = cubeParams();
  p.regionRadius = 0.31;  // 3.1 cells of 0.1 m
  EXPECT_EQ(buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0).info.regionHalfWidth, 3);
  p.regionRadius = 0.0;
  p.regionHalfWidth = 1;
  EXPECT_EQ(buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0).info.regionHalfWidth, 1);
  EXPECT_EQ(regionClampWarning(buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0).info, p),
            "");
}

TEST(BuildScene, RegionRadiusBeyondTheLimitIsClampedWithAWarning) {
  // A radius that suits one mesh is too many cells on a smaller one (the same particle budget
  // makes a finer lattice): the scene starts with the largest regions the solver allows.
  NodeParams p = cubeParams();
  p.regionRadius = 5.0;  // 50 cells of 0.1 m
  p.regionFromSection = false;  // the clamp, not the section (10 cells: w = 4), is tested here
  const Scene s = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
  EXPECT_EQ(s.info.regionHalfWidth, kMaxRegionHalfWidth);
  EXPECT_EQ(s.info.regionAskedCells, 50);
  EXPECT_EQ(s.solver->params().regionHalfWidth, kMaxRegionHalfWidth);
  const std::string w = regionClampWarning(s.info, p);
  EXPECT_NE(w.find("50 cells"), std::string::npos) << w;
  EXPECT_NE(w.find("at most 1 m"), std::string::npos) << w;  // 10 cells of 0.1 m
  EXPECT_NE(describeScene(s.info, p).find("clamped"), std::string::npos);
  // 10.4 cells rounds to 10: no clamp.
  p.regionRadius = 1.04;
  EXPECT_EQ(buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0).info.regionAskedCells, 0);
}

// A bar 4 cells across with regions 7 cells wide: bending would be ~1.4x too stiff. Without
// ~region_from_section the scene keeps the regions and warns with the figures; with it the
// regions are narrowed to w = 1 (3 cells wide, within 10 % of FEM in test_solver_material).
TEST(BuildScene, RegionsWiderThanTheThinnestSectionWarnOrAreNarrowed) {
  NodeParams p;
  p.resolution = 40;  // 1 m long, 0.1 m = 4 cells across
  p.regionHalfWidth = 3;
  p.regionFromSection = false;
  p.solver.youngsModulus = 14000.0;
  p.solver.gravity.setZero();
  const TriMesh bar = test::boxMesh(Eigen::Vector3d(1.0, 0.1, 0.1));
  const Scene asked = buildScene(p, bar, 0);
  EXPECT_EQ(asked.info.sectionCells, 4);
  EXPECT_EQ(asked.info.regionHalfWidth, 3);
  const std::string w = sectionWarning(asked.info, p);
  EXPECT_NE(w.find("w = 3 cells (7 cells wide)"), std::string::npos) << w;
  EXPECT_NE(w.find("thinnest section, 4 cells"), std::string::npos) << w;
  EXPECT_NE(w.find("1.4 times"), std::string::npos) << w;
  EXPECT_NE(w.find("~region_from_section true would use w = 1"), std::string::npos) << w;
  EXPECT_NE(describeScene(asked.info, p).find("thinnest section: 4 cells"), std::string::npos);

  p.regionFromSection = true;
  const Scene narrowed = buildScene(p, bar, 0);
  EXPECT_EQ(narrowed.info.regionHalfWidth, 1);
  EXPECT_EQ(narrowed.info.regionHalfWidthAsked, 3);
  EXPECT_EQ(narrowed.solver->lattice().regionHalfWidth(), 1);
  EXPECT_EQ(sectionWarning(narrowed.info, p), "");
  EXPECT_NE(describeScene(narrowed.info, p).find("narrowed from w = 3"), std::string::npos)
      << describeScene(narrowed.info, p);

  // classic mode has no modulus to be stiffer than: no warning
  p.regionFromSection = false;
  p.solver.youngsModulus = 0.0;
  EXPECT_EQ(sectionWarning(buildScene(p, bar, 0).info, p), "");
}

TEST(BuildScene, RegionsThatFitTheSectionDoNotWarn) {
  NodeParams p = cubeParams();  // 10 cells across
  p.regionHalfWidth = 2;
  p.solver.youngsModulus = 14000.0;
  p.regionFromSection = true;
  const Scene s = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
  EXPECT_EQ(s.info.sectionCells, 10);
  EXPECT_EQ(s.info.regionHalfWidth, 2);
  EXPECT_EQ(sectionWarning(s.info, p), "");
}

// Two small cubes 1 m apart on 4 mm cells: a bounding box too large to measure the section on
// (core/section.h kMaxSectionGridCells). The scene still starts, says so, and keeps the regions.
TEST(BuildScene, ASectionTooSparseToMeasureKeepsTheAskedRegions) {
  TriMesh mesh = test::boxMesh(Eigen::Vector3d::Zero(), Eigen::Vector3d::Constant(0.02));
  const TriMesh far = test::boxMesh(Eigen::Vector3d::Constant(0.98), Eigen::Vector3d::Ones());
  const auto offset = static_cast<std::uint32_t>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), far.vertices.begin(), far.vertices.end());
  for (auto t : far.triangles) {
    for (auto& v : t) v += offset;
    mesh.triangles.push_back(t);
  }
  NodeParams p;
  p.spacing = 0.004;
  p.regionHalfWidth = 3;
  p.regionFromSection = true;
  p.solver.youngsModulus = 14000.0;
  p.solver.gravity.setZero();
  const Scene s = buildScene(p, mesh, 0);
  EXPECT_EQ(s.info.particles, 250u);
  EXPECT_EQ(s.info.sectionCells, 0);
  EXPECT_EQ(s.info.regionHalfWidth, 3);
  const std::string d = describeScene(s.info, p);
  EXPECT_NE(d.find("thinnest section: not measured"), std::string::npos) << d;
  EXPECT_NE(d.find("keeps the asked regions"), std::string::npos) << d;
  EXPECT_EQ(sectionWarning(s.info, p), "");
}

TEST(BuildScene, PinnedBoxesAreCountedPerBox) {
  NodeParams p = cubeParams();
  p.pinned.push_back(Box{Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(2, 2, 0.1)});  // z = 0.05
  p.pinned.push_back(Box{Eigen::Vector3d(5, 5, 5), Eigen::Vector3d(6, 6, 6)});       // nothing
  const Scene s = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
  ASSERT_EQ(s.info.pinnedPerBox.size(), 2u);
  EXPECT_EQ(s.info.pinnedPerBox[0], 100u);
  EXPECT_EQ(s.info.pinnedPerBox[1], 0u);
  EXPECT_EQ(s.solver->pinnedCount(), 100u);
}

TEST(BuildScene, TooFineForMaxParticlesNamesTheParameters) {
  NodeParams p = cubeParams();
  p.resolution = 50;  // 125000 particles
  p.maxParticles = 10000;
  try {
    buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
    FAIL() << "no error";
  } catch (const ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("~max_particles"), std::string::npos) << e.what();
  }
}

TEST(BuildScene, SaturatedModulusSaysWhichSubstepsFixIt) {
  NodeParams p = cubeParams();
  p.solver.youngsModulus = 1e9;  // far stiffer than 4 sub-steps of 1/60 s allow
  const Scene s = buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0);
  EXPECT_TRUE(s.solver->stiffnessSaturated());
  EXPECT_GT(s.info.substepsForModulus, p.solver.substeps);
  // At that many sub-steps the solver is no longer saturated.
  SolverParams fixed = s.solver->params();
  fixed.substeps = s.info.substepsForModulus;
  s.solver->setParams(fixed);
  EXPECT_FALSE(s.solver->stiffnessSaturated());
  const std::string w = saturationWarning(s.info, p);
  EXPECT_NE(w.find("~substeps " + std::to_string(s.info.substepsForModulus)), std::string::npos) << w;
  p.solver.youngsModulus = 0.0;
  EXPECT_EQ(saturationWarning(buildScene(p, test::boxMesh(Eigen::Vector3d::Ones()), 0).info, p), "");
}

TEST(BuildScene, RenderBudgetSimplifiesOnlyTheRenderMesh) {
  ASSERT_TRUE(std::filesystem::exists(kBunnyPath)) << kBunnyPath << " missing: install glmark2-data (a test dependency)";
  const TriMesh bunny = loadMesh(kBunnyPath, 0.1);
  NodeParams p;
  p.resolution = 12;
  p.renderTriangleBudget = 3000;
  const Scene simple = buildScene(p, bunny, 0);
  EXPECT_LE(simple.info.renderTriangles, 3000u);
  EXPECT_EQ(simple.info.loadedTriangles, bunny.triangles.size());
  EXPECT_EQ(simple.embedding->vertexCount(), simple.renderMesh.vertices.size());
  p.renderTriangleBudget = 0;
  const Scene full = buildScene(p, bunny, 0);
  EXPECT_EQ(full.info.renderTriangles, bunny.triangles.size());
  // The lattice does not depend on the render budget.
  EXPECT_EQ(simple.info.particles, full.info.particles);
  const std::string text = describeScene(simple.info, p);
  EXPECT_NE(text.find("particles"), std::string::npos);
  EXPECT_NE(text.find("ns per particle-substep"), std::string::npos);
}

TEST(PrepareObject, BuildsTheObjectAtItsPoseWithoutAWorld) {
  // the unit cube at resolution 10 (1000 particles), placed 2 m along x and turned about z
  ObjectSpec spec;
  spec.name = "crate";
  spec.params = cubeParams();
  spec.params.objectFrameId = spec.name;
  spec.pose.translation() = Eigen::Vector3d(2.0, 0.0, 0.0);
  spec.pose.linear() = Eigen::AngleAxisd(0.5 * M_PI, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  const PreparedObject prepared =
      prepareObject(spec, [](const NodeParams&) { return test::boxMesh(Eigen::Vector3d::Ones()); });
  const SceneObject& o = prepared.object;
  EXPECT_EQ(o.name, "crate");
  ASSERT_TRUE(o.lattice);
  EXPECT_EQ(o.lattice->size(), 1000u);
  // the cube [0, 1]^3 turned a quarter about z spans x in [-1, 0], then moved 2 m: [1, 2]
  Eigen::Vector3d lo = o.lattice->restPositions()[0], hi = lo;
  for (const Eigen::Vector3d& x : o.lattice->restPositions()) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  EXPECT_GT(lo.x(), 1.0 - 1e-9);
  EXPECT_LT(hi.x(), 2.0 + 1e-9);
  EXPECT_GT(o.info.contactRadius, 0.0);
  ASSERT_TRUE(o.embedding);
  EXPECT_EQ(o.embedding->vertexCount(), o.renderMesh.vertices.size());
  EXPECT_EQ(prepared.solverParams.timeStep, spec.params.solver.timeStep);
  EXPECT_EQ(prepared.solverParams.substeps, spec.params.solver.substeps);
}

TEST(PrepareObject, AMeshThatCannotBeLoadedNamesTheObject) {
  ObjectSpec spec;
  spec.name = "ghost";
  spec.params = cubeParams();
  try {
    prepareObject(spec, [](const NodeParams&) -> TriMesh { throw ParamError("~mesh 'x.obj' cannot be read"); });
    FAIL() << "no error";
  } catch (const ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("object 'ghost'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("x.obj"), std::string::npos) << e.what();
  }
}

/// Objects "a" and "b" with these parameters, 3 m apart along x.
std::vector<ObjectSpec> twoCubesApart(const NodeParams& params) {
  std::vector<ObjectSpec> objects(2);
  for (int k = 0; k < 2; ++k) {
    objects[k].name = k == 0 ? "a" : "b";
    objects[k].params = params;
    objects[k].pose.translation() = Eigen::Vector3d(3.0 * k, 0.0, 0.0);
  }
  return objects;
}

// Several objects with the implicit step are built into one World, each with the implicit
// integrator, and step (their contact is inside one solve: test_world).
TEST(BuildScene, SeveralObjectsWithTheImplicitStepAreBuilt) {
  NodeParams params = cubeParams();
  params.solver.integrator = Integrator::Implicit;
  params.solver.substeps = 1;
  const std::vector<ObjectSpec> objects = twoCubesApart(params);
  const auto cube = [](const NodeParams&) { return test::boxMesh(Eigen::Vector3d::Ones()); };
  const WorldScene scene = buildWorld(params, objects, cube);
  ASSERT_EQ(scene.world->objectCount(), 2u);
  for (const std::string& name : scene.world->objectNames())
    EXPECT_EQ(scene.world->object(name)->params().integrator, Integrator::Implicit) << name;
  for (int i = 0; i < 10; ++i) scene.world->step();
  for (const std::string& name : scene.world->objectNames())
    for (const auto& x : scene.world->object(name)->positions()) ASSERT_TRUE(x.allFinite()) << name;
}

// ~integrator auto keeps the explicit step where ~substeps give the modulus, and otherwise builds
// the whole scene with the implicit step at one sub-step (the modulus as asked), saying why; the
// parameters come back with the choice, for the loop and for objects added later.
TEST(BuildNodeScene, AutoTakesTheImplicitStepWhereTheExplicitOneWouldSoften) {
  const auto cube = [](const NodeParams&) { return test::boxMesh(Eigen::Vector3d::Ones()); };
  NodeParams soft = cubeParams();
  soft.integratorAuto = true;
  soft.solver.youngsModulus = 1e3;
  std::vector<ObjectSpec> none;
  WorldScene scene = buildNodeScene(soft, none, cube, 0);
  const Solver& explicitOne = *scene.world->object(scene.world->objectNames().front());
  EXPECT_EQ(explicitOne.params().integrator, Integrator::Explicit);
  EXPECT_EQ(explicitOne.params().substeps, 4);
  EXPECT_FALSE(explicitOne.stiffnessSaturated());
  EXPECT_EQ(soft.solver.integrator, Integrator::Explicit);
  EXPECT_NE(scene.objects.front().info.integratorChoice.find("explicit"), std::string::npos);

  NodeParams stiff = soft;
  stiff.solver.youngsModulus = 1e9;  // far stiffer than 4 sub-steps of 1/60 s allow
  scene = buildNodeScene(stiff, none, cube, 0);
  const Solver& implicitOne = *scene.world->object(scene.world->objectNames().front());
  EXPECT_EQ(implicitOne.params().integrator, Integrator::Implicit);
  EXPECT_EQ(implicitOne.params().substeps, 1);
  EXPECT_FALSE(implicitOne.stiffnessSaturated());
  EXPECT_DOUBLE_EQ(implicitOne.alpha(), implicitOne.params().requestedAlpha(implicitOne.lattice().spacing()));
  EXPECT_EQ(stiff.solver.integrator, Integrator::Implicit);
  EXPECT_EQ(stiff.solver.substeps, 1);
  EXPECT_EQ(scene.world->substeps(), 1);
  const std::string why = scene.objects.front().info.integratorChoice;
  EXPECT_NE(why.find("implicit at 1 sub-step"), std::string::npos) << why;
  EXPECT_NE(why.find("~substeps 4"), std::string::npos) << why;
  bool reported = false;
  for (const std::string& line : sceneSummaryLines(scene.objects.front().info, stiff))
    reported = reported || line.rfind("integrator: implicit", 0) == 0;
  EXPECT_TRUE(reported);

  // Asked for by name, the explicit step stays, softened (and warned about), as before.
  NodeParams named = stiff;
  named.integratorAuto = false;
  named.solver.integrator = Integrator::Explicit;
  named.solver.substeps = 4;
  scene = buildNodeScene(named, none, cube, 0);
  EXPECT_TRUE(scene.world->object(scene.world->objectNames().front())->stiffnessSaturated());
  EXPECT_EQ(scene.objects.front().info.integratorChoice, "");
}

// With several objects, one object the explicit step would soften takes the whole scene to the
// implicit step (one World, one sub-step count), and the reason names it.
TEST(BuildNodeScene, AutoWithSeveralObjectsFollowsTheStiffestNeed) {
  const auto cube = [](const NodeParams&) { return test::boxMesh(Eigen::Vector3d::Ones()); };
  NodeParams params = cubeParams();
  params.integratorAuto = true;
  params.solver.youngsModulus = 1e3;
  std::vector<ObjectSpec> objects = twoCubesApart(params);
  WorldScene scene = buildNodeScene(params, objects, cube, 0);
  for (const std::string& name : scene.world->objectNames())
    EXPECT_EQ(scene.world->object(name)->params().integrator, Integrator::Explicit) << name;
  objects[1].params.solver.youngsModulus = 1e9;
  scene = buildNodeScene(params, objects, cube, 0);
  for (const std::string& name : scene.world->objectNames())
    EXPECT_EQ(scene.world->object(name)->params().integrator, Integrator::Implicit) << name;
  EXPECT_EQ(objects[0].params.solver.integrator, Integrator::Implicit);
  EXPECT_EQ(objects[1].params.solver.substeps, 1);
  EXPECT_NE(scene.objects.front().info.integratorChoice.find("object 'b'"), std::string::npos)
      << scene.objects.front().info.integratorChoice;
  for (int i = 0; i < 5; ++i) scene.world->step();
  for (const std::string& name : scene.world->objectNames())
    for (const auto& x : scene.world->object(name)->positions()) ASSERT_TRUE(x.allFinite()) << name;
}

// The implicit scheme bdf2 steps one object alone: objects that touch each other are refused at
// start-up with what to change; with object contact off they are built.
TEST(BuildScene, Bdf2ObjectsThatTouchAreRefusedWithWhatToChange) {
  NodeParams params = cubeParams();
  params.solver.integrator = Integrator::Implicit;
  params.solver.implicitScheme = ImplicitScheme::Bdf2;
  params.solver.substeps = 1;
  const std::vector<ObjectSpec> objects = twoCubesApart(params);
  const auto cube = [](const NodeParams&) { return test::boxMesh(Eigen::Vector3d::Ones()); };
  try {
    buildWorld(params, objects, cube);
    FAIL() << "no error";
  } catch (const ParamError& e) {
    EXPECT_NE(std::string(e.what()).find("~implicit_scheme"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("backward_euler"), std::string::npos) << e.what();
  }
  params.objectContact.enabled = false;
  const WorldScene scene = buildWorld(params, objects, cube);
  EXPECT_EQ(scene.world->objectCount(), 2u);
}

/// The message of the ParamError that validate() throws, or "" when it passes.
std::string problem(const NodeParams& p) {
  try {
    p.validate();
  } catch (const ParamError& e) {
    return e.what();
  }
  return "";
}

TEST(NodeParams, DefaultsAreValid) { EXPECT_EQ(problem(NodeParams()), ""); }

TEST(NodeParams, EveryInvalidValueIsNamed) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  struct Case {
    std::function<void(NodeParams&)> change;
    const char* named;
  };
  const std::vector<Case> cases = {
      {[](NodeParams& p) { p.mesh = ""; }, "~mesh"},
      {[](NodeParams& p) { p.meshScale = 0.0; }, "~mesh_scale"},
      {[&](NodeParams& p) { p.meshRpy.x() = nan; }, "~mesh_rpy"},
      {[](NodeParams& p) { p.frameId = ""; }, "~frame_id"},
      {[](NodeParams& p) { p.objectFrameId = p.frameId; }, "~object_frame_id"},
      {[](NodeParams& p) { p.spacing = -0.1; }, "~spacing"},
      {[](NodeParams& p) { p.resolution = -3; }, "~resolution"},
      {[](NodeParams& p) { p.spacing = 0.01; p.resolution = 10; }, "both set"},
      {[](NodeParams& p) { p.particleBudget = 0; }, "~particle_budget"},
      {[](NodeParams& p) { p.particleBudget = 300000; }, "~particle_budget"},
      {[](NodeParams& p) { p.maxParticles = 0; }, "~max_particles"},
      {[](NodeParams& p) { p.regionRadius = -1.0; }, "~region_radius"},
      {[](NodeParams& p) { p.regionHalfWidth = -1; }, "~region_half_width"},
      {[](NodeParams& p) { p.regionRadius = 0.02; p.regionHalfWidth = 2; }, "both set"},
      {[](NodeParams& p) { p.regionHalfWidth = 11; }, "region_half_width"},
      {[](NodeParams& p) { p.publishRate = 0.0; }, "~publish_rate"},
      {[&](NodeParams& p) { p.publishRate = nan; }, "~publish_rate"},
      {[](NodeParams& p) { p.realTimeFactor = -1.0; }, "~real_time_factor"},
      {[](NodeParams& p) { p.realTimeFactor = 1e6; }, "~real_time_factor"},
      {[](NodeParams& p) { p.renderTriangleBudget = -5; }, "~render_triangle_budget"},
      {[](NodeParams& p) { p.pinned.push_back(Box{Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 1)}); }, "~pinned"},
      {[&](NodeParams& p) { p.pinned.push_back(Box{Eigen::Vector3d(nan, 0, 0), Eigen::Vector3d(1, 1, 1)}); }, "~pinned"},
      {[](NodeParams& p) { p.solver.stiffness = 2.0; }, "stiffness"},
      {[](NodeParams& p) { p.youngsModulus = -1.0; }, "~youngs_modulus is -1"},
      {[](NodeParams& p) { p.youngsModulus = 0.0; }, "~material"},  // no longer "classic"
      {[&](NodeParams& p) { p.youngsModulus = nan; }, "~youngs_modulus"},
      {[](NodeParams& p) { p.solver.damping = -1.0; }, "damping"},
      {[](NodeParams& p) { p.solver.timeStep = 0.0; }, "time_step"},
      {[](NodeParams& p) { p.solver.substeps = 0; }, "substeps"},
      {[](NodeParams& p) { p.solver.density = 0.0; }, "density"},
      {[&](NodeParams& p) { p.solver.gravity.z() = nan; }, "gravity"},
      {[](NodeParams& p) { p.solver.threads = -1; }, "threads"},
  };
  for (const Case& c : cases) {
    NodeParams p;
    c.change(p);
    const std::string why = problem(p);
    EXPECT_NE(why.find(c.named), std::string::npos) << "expected '" << c.named << "' in: " << why;
  }
}

TEST(NodeParams, TheMaterialIsItsOwnSwitch) {
  NodeParams p;
  p.youngsModulus = 2e4;
  p.solver.stiffness = 0.5;
  p.applyMaterial();
  EXPECT_EQ(p.solver.youngsModulus, 2e4);
  p.material = NodeParams::Material::Classic;
  p.youngsModulus = 0.0;  // not used by the classic model, so not checked
  EXPECT_EQ(problem(p), "");
  p.applyMaterial();
  EXPECT_EQ(p.solver.youngsModulus, 0.0);  // the solver's alpha = stiffness
  NodeParams::Material m = NodeParams::Material::Youngs;
  EXPECT_TRUE(parseMaterial("classic", m));
  EXPECT_EQ(m, NodeParams::Material::Classic);
  EXPECT_FALSE(parseMaterial("", m));
  EXPECT_STREQ(toString(NodeParams::Material::Youngs), "youngs");
}

}  // namespace
}  // namespace deformable_flsm
