/// @file scenarios.h
/// The objects and scenarios of the speed/accuracy study, run headless on any study Method:
/// a cantilever sagging under gravity, a drag of the bunny's ear, and three stress tests
/// (a drag far beyond the object, a collapse onto a plane, a scrambled start).
#pragma once

#include "deformable_flsm/core/embedding.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/section.h"
#include "deformable_flsm/core/voxelizer.h"
#include "study/method.h"
#include "study/metrics.h"
#include "study/setting.h"

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <limits>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

// --- objects ------------------------------------------------------------------------------

/// An object of the study: its closed render mesh and the points whose motion is measured.
struct StudyObject {
  std::string name;
  /// closed, outward-oriented render mesh (m)
  TriMesh mesh;
  /// diagonal of the render mesh's bounding box (m): the size errors are divided by, the same
  /// at every resolution
  double size = 0.0;
  /// mesh vertices whose trajectories are compared with the reference run (a subset, to keep
  /// the stored trajectories small)
  std::vector<std::uint32_t> sampleVertices;
  /// extra points embedded like the mesh vertices (the bar's centre line), in order
  std::vector<Eigen::Vector3d> probes;
  /// Young's modulus (Pa) and reach of a shape-matching region (m): the material, the same at
  /// every resolution and step (Setting)
  double youngsModulus = 0.0;
  double regionRadius = 0.0;
};

/// Bar of the cantilever: length L along x, square section a = L / 10 (10 x 1 x 1), lower corner
/// at the origin. Its render mesh is the box surface cut into squares of a / 4, and its probes
/// are kBarProbes points on the centre line from the clamp to the free end.
constexpr double kBarAspect = 10.0;
/// Coarsest resolution of the bar: 20 cells along L leaves 2 cells across the section, the
/// fewest that still bend (one cell of section has no lever arm inside a region) and let a
/// clamp hold a face rather than a line.
constexpr int kBarCoarsestResolution = 20;
/// The clamp holds the particles within L / 20 of the fixed end: one cell layer at the
/// coarsest resolution, the same length of bar at every resolution.
constexpr double kBarClampFraction = 1.0 / 20.0;
constexpr int kBarProbes = 20;
constexpr int kBarFacesPerSection = 4;
/// Bar material: E (Pa). The alpha this modulus asks for (Solver::alpha()) is below the
/// solver's cap (Solver::stiffnessSaturated()) for sub-steps of 1/480 s at 20 and 40 cells and
/// of 1/960 s at 80; at 60 cells 1/480 s is still capped. Capped sub-steps simulate a softer
/// bar, which the study measures (accuracy.csv: alpha, saturated).
constexpr double kBarYoungsModulus = 5e4;
/// Body load of the cantilever (m/s^2, along -z). Under 9.81 m/s^2 this bar would hang down
/// (Euler-Bernoulli's tip deflection 1.5 rho g L^4 / (E a^2) is about 24 L); a lighter load
/// keeps the sag near 5% of L, in the small-deflection regime where the Euler-Bernoulli profile
/// is the reference. The normalised profile does not depend on the load.
constexpr double kBarLoad = 0.02;

/// Appends to `mesh` a grid of n1 x n2 squares (two triangles each) spanning the rectangle
/// corner + [0, 1] e1 + [0, 1] e2, oriented so that e1 x e2 points outwards.
inline void appendGrid(TriMesh& mesh, const Eigen::Vector3d& corner, const Eigen::Vector3d& e1,
                       const Eigen::Vector3d& e2, int n1, int n2) {
  const auto base = static_cast<std::uint32_t>(mesh.vertices.size());
  for (int j = 0; j <= n2; ++j)
    for (int i = 0; i <= n1; ++i) mesh.vertices.push_back(corner + e1 * (double(i) / n1) + e2 * (double(j) / n2));
  auto id = [&](int i, int j) { return base + static_cast<std::uint32_t>(j * (n1 + 1) + i); };
  for (int j = 0; j < n2; ++j)
    for (int i = 0; i < n1; ++i) {
      mesh.triangles.push_back({id(i, j), id(i + 1, j), id(i + 1, j + 1)});
      mesh.triangles.push_back({id(i, j), id(i + 1, j + 1), id(i, j + 1)});
    }
}

/// The cantilever bar of length `length` (m).
inline StudyObject makeBar(double length) {
  StudyObject o;
  o.name = "bar";
  const double a = length / kBarAspect;
  const int nx = static_cast<int>(kBarAspect) * kBarFacesPerSection, ns = kBarFacesPerSection;
  const Eigen::Vector3d X(length, 0, 0), Y(0, a, 0), Z(0, 0, a), O = Eigen::Vector3d::Zero();
  appendGrid(o.mesh, O, Y, X, ns, nx);          // z = 0, normal -z
  appendGrid(o.mesh, O + Z, X, Y, nx, ns);      // z = a, normal +z
  appendGrid(o.mesh, O, X, Z, nx, ns);          // y = 0, normal -y
  appendGrid(o.mesh, O + Y, Z, X, ns, nx);      // y = a, normal +y
  appendGrid(o.mesh, O, Z, Y, ns, ns);          // x = 0, normal -x
  appendGrid(o.mesh, O + X, Y, Z, ns, ns);      // x = L, normal +x
  weldVertices(o.mesh);
  o.size = (o.mesh.boundsMax() - o.mesh.boundsMin()).norm();
  for (std::uint32_t v = 0; v < o.mesh.vertices.size(); ++v) o.sampleVertices.push_back(v);
  const double clamp = kBarClampFraction * length;
  for (int k = 1; k <= kBarProbes; ++k)
    o.probes.emplace_back(clamp + (length - clamp) * k / kBarProbes, 0.5 * a, 0.5 * a);
  o.youngsModulus = kBarYoungsModulus;
  o.regionRadius = length / kBarCoarsestResolution;
  return o;
}

/// Most mesh vertices compared along a trajectory.
constexpr std::size_t kMaxSampleVertices = 2000;
/// Coarsest resolution of the bunny; its region radius is one cell there.
constexpr int kBunnyCoarsestResolution = 12;
/// Bunny material: E (Pa), a soft jelly. With the solver's alpha cap every bunny setting of the
/// study (up to 16 sub-steps per 1/60 s frame) is capped: the bunny runs simulate a jelly softer
/// than this E, which accuracy.csv records (saturated).
constexpr double kBunnyYoungsModulus = 5e3;

/// The bunny (or any closed mesh) loaded with `scale`.
inline StudyObject makeBunny(const std::string& path, double scale) {
  StudyObject o;
  o.name = "bunny";
  o.mesh = loadMesh(path, scale);
  if (countBoundaryEdges(o.mesh) != 0)
    throw MeshError("mesh '" + path + "' is not closed: the study needs a closed mesh for its volume");
  o.size = (o.mesh.boundsMax() - o.mesh.boundsMin()).norm();
  const std::size_t stride = (o.mesh.vertices.size() + kMaxSampleVertices - 1) / kMaxSampleVertices;
  for (std::size_t v = 0; v < o.mesh.vertices.size(); v += stride) o.sampleVertices.push_back(static_cast<std::uint32_t>(v));
  o.youngsModulus = kBunnyYoungsModulus;
  o.regionRadius = (o.mesh.boundsMax() - o.mesh.boundsMin()).maxCoeff() / kBunnyCoarsestResolution;
  return o;
}

/// The lattice of `object` at `resolution`. Its regions are the object's region radius in cells,
/// narrowed to the widest that fit across the lattice's thinnest section, as the node does by
/// default (~region_from_section): regions wider than a section keep its curvature rigid.
/// @throws VoxelizationError, std::invalid_argument (region radius over 10 cells)
inline std::shared_ptr<const Lattice> buildLattice(const StudyObject& object, int resolution) {
  VoxelizeOptions options;
  options.resolution = resolution;
  const Voxelization voxels = voxelize(object.mesh, options);
  const int asked = regionHalfWidthForRadius(object.regionRadius, voxels.spacing);
  return std::make_shared<const Lattice>(voxels, kStudyDensity,
                                         regionHalfWidthForSection(measureSectionThickness(voxels).thinnest, asked));
}

// --- scenarios ----------------------------------------------------------------------------

enum class Scenario {
  /// the bar, clamped at x < L/20, sags under gravity (-z) to rest
  Cantilever,
  /// the same bar and clamp, loaded along its axis towards the clamp (a column standing on
  /// its clamped base): compression, to rest
  Column,
  /// the bunny's base is pinned, its ear dragged by 30% of the object size, held, released
  EarDrag,
  /// as EarDrag, but 5 object sizes far and fast
  DragFar,
  /// every particle collapsed onto the horizontal plane through the centroid, then released
  Plane,
  /// every particle placed at random in the rest bounding box, then released
  Scrambled,
};

inline const char* toString(Scenario s) {
  switch (s) {
    case Scenario::Cantilever: return "cantilever";
    case Scenario::Column: return "column";
    case Scenario::EarDrag: return "ear-drag";
    case Scenario::DragFar: return "drag-5x";
    case Scenario::Plane: return "plane";
    case Scenario::Scrambled: return "scrambled";
  }
  return "?";
}

/// Frame step of the accuracy scenarios (s).
constexpr double kAccuracyFrameStep = 1.0 / 60.0;
/// Frame step of the stress scenarios (s), always taken in one sub-step.
constexpr double kStressFrameStep = 1.0 / 30.0;
/// Cantilever: simulated time to rest (s), and the ambient damping rate (1/s) of every method.
/// The bar's first bending mode has omega_1 = 3.516 sqrt(E I / (rho A L^4)) ~ 0.8 rad/s; near
/// critical ambient damping (2 omega_1) settles it in ~10 s without changing the rest shape.
constexpr double kCantileverDuration = 12.0;
constexpr double kCantileverAmbientDamping = 1.5;
/// Ambient damping (1/s) of the other scenarios: the solver's default.
inline double defaultAmbientDamping() { return SolverParams().ambientDamping; }
/// Bunny scenarios: base = particles within this fraction of the height above the lowest rest
/// point (along +y, the bunny's up), ear = particles within this fraction of the size of the
/// highest rest particle (at least the nearest one).
constexpr double kBaseFraction = 0.1;
constexpr double kEarRadiusFraction = 0.08;
/// Ear drag: ramp (s), hold until (s), end (s); drag distance / object size (along +x).
constexpr double kEarDragRamp = 0.5, kEarDragHoldUntil = 1.5, kEarDragEnd = 3.5, kEarDragDistance = 0.3;
/// Drag far: 5 sizes in 0.2 s, held until 0.7 s, then 40 s to recover.
constexpr double kDragFarRamp = 0.2, kDragFarHoldUntil = 0.7, kDragFarEnd = 40.7, kDragFarDistance = 5.0;
/// Plane and scrambled starts: simulated time to recover (s); seed of the scramble. The soft
/// bunny (kBunnyYoungsModulus) at 1/30 s in one sub-step wobbles for seconds, the longer the
/// softer the cap on alpha makes it: RunRecord::recoveredAfter says when each run got there.
constexpr double kReleaseDuration = 40.0;
constexpr unsigned kScrambleSeed = 5;
/// A run has blown up when a coordinate is not finite or a particle is farther than this many
/// object sizes from the rest centroid (a drag far puts the ear 5 sizes away).
constexpr double kBlowUpSizes = 100.0;
/// A stress run has recovered when its rest-shape error is below this fraction of the size.
constexpr double kRecoveredTolerance = 0.01;

/// Body load of the column (m/s^2, along -x, towards the clamp): the top of a free column of
/// height H shortens by rho g H^2 / (2 E) (nu = 0), about 0.9% of L for this bar.
constexpr double kColumnLoad = 1.0;

/// Body load of a scenario: only the cantilever (kBarLoad, across the bar) and the column
/// (kColumnLoad, along it) have weight; the others are weightless so that the rest shape is
/// what they must return to.
inline Eigen::Vector3d scenarioGravity(Scenario s) {
  if (s == Scenario::Cantilever) return Eigen::Vector3d(0.0, 0.0, -kBarLoad);
  if (s == Scenario::Column) return Eigen::Vector3d(-kColumnLoad, 0.0, 0.0);
  return Eigen::Vector3d::Zero();
}

inline double scenarioDuration(Scenario s) {
  switch (s) {
    case Scenario::Cantilever:
    case Scenario::Column: return kCantileverDuration;
    case Scenario::EarDrag: return kEarDragEnd;
    case Scenario::DragFar: return kDragFarEnd;
    case Scenario::Plane:
    case Scenario::Scrambled: return kReleaseDuration;
  }
  return 0.0;
}

/// The setting of a scenario at a resolution and sub-step count: its frame step, the object's
/// material, the scenario's ambient damping and load.
inline Setting scenarioSetting(Scenario s, const StudyObject& object, int resolution, int substeps) {
  Setting st;
  st.resolution = resolution;
  st.substeps = substeps;
  st.frameStep = (s == Scenario::DragFar || s == Scenario::Plane || s == Scenario::Scrambled) ? kStressFrameStep
                                                                                              : kAccuracyFrameStep;
  st.youngsModulus = object.youngsModulus;
  st.regionRadius = object.regionRadius;
  st.ambientDamping =
      (s == Scenario::Cantilever || s == Scenario::Column) ? kCantileverAmbientDamping : defaultAmbientDamping();
  st.gravity = scenarioGravity(s);
  return st;
}

/// What a run measured.
struct RunRecord {
  /// frames simulated (fewer than planned when the run blew up)
  int frames = 0;
  bool blewUp = false;
  /// first frame after which the state was non-finite or beyond kBlowUpSizes; -1 if never
  int blowUpFrame = -1;
  /// largest kinetic energy seen after any frame, the last one of a blown-up run included
  /// (J; infinity once it is not finite)
  double peakKineticEnergy = 0.0;
  /// sample points (object.sampleVertices, then object.probes) every `sampleEvery` frames
  std::vector<std::vector<Eigen::Vector3d>> trajectory;
  /// sample points after the last frame
  std::vector<Eigen::Vector3d> finalPoints;
  /// (V - V0) / V0 of the embedded render mesh at the scenario's measuring instant (end of
  /// the hold for drags, the end otherwise); NaN if the run blew up first
  double volumeChange = std::numeric_limits<double>::quiet_NaN();
  /// (V - V0) / V0 after the last frame; NaN if the run blew up
  double finalVolumeChange = std::numeric_limits<double>::quiet_NaN();
  /// rigidFitError() / object size after the last frame (infinity after a blow-up)
  double shapeError = std::numeric_limits<double>::infinity();
  /// stress scenarios (drag far, plane, scrambled): simulated time from the release (the end of
  /// the hold, or the start) after which the shape error stayed below kRecoveredTolerance; NaN
  /// when it did not end below it
  double recoveredAfter = std::numeric_limits<double>::quiet_NaN();
  /// wall time (s) of each frame's step(), nothing else
  std::vector<double> frameSeconds;
  /// CPU time (s) the calling thread spent in each frame's step() (threadCpuSeconds()): the
  /// cost of a single-threaded method without the time its thread waited for a core while other
  /// jobs ran on the machine
  std::vector<double> frameCpuSeconds;
};

/// CPU time (s) consumed so far by the calling thread (POSIX CLOCK_THREAD_CPUTIME_ID). A method
/// that steps on this thread alone (the study's FastLSM runs with one thread; Bullet's task
/// scheduler is sequential unless an application installs another) costs this much per frame
/// whatever else the machine runs, up to the caches and memory bandwidth it shares.
inline double threadCpuSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

/// Particles of the bunny's base and ear (see kBaseFraction, kEarRadiusFraction).
inline std::vector<std::uint32_t> baseParticles(const Lattice& lattice, const StudyObject& object) {
  const double yCut = object.mesh.boundsMin().y() +
                      kBaseFraction * (object.mesh.boundsMax().y() - object.mesh.boundsMin().y());
  std::vector<std::uint32_t> out;
  for (std::size_t i = 0; i < lattice.size(); ++i)
    if (lattice.restPositions()[i].y() < yCut) out.push_back(static_cast<std::uint32_t>(i));
  return out;
}

inline std::vector<std::uint32_t> earParticles(const Lattice& lattice, const StudyObject& object) {
  const auto& x0 = lattice.restPositions();
  std::size_t top = 0;
  for (std::size_t i = 1; i < x0.size(); ++i)
    if (x0[i].y() > x0[top].y()) top = i;
  std::vector<std::uint32_t> out;
  const double r = kEarRadiusFraction * object.size;
  for (std::size_t i = 0; i < x0.size(); ++i)
    if ((x0[i] - x0[top]).norm() <= r) out.push_back(static_cast<std::uint32_t>(i));
  return out;
}

namespace detail {

/// The render mesh and probes of a run embedded in its lattice: deformed on demand with a
/// method's particles, then sampled (the sample points) or measured (the volume change).
class EmbeddedPoints {
 public:
  EmbeddedPoints(const StudyObject& object, const Lattice& lattice)
      : object_(object),
        embedding_(lattice, meshAndProbes(object)),
        v0_(closedMeshVolume(object.mesh.vertices, object.mesh.triangles)) {}

  /// Deforms the render mesh and probes with `method`'s particles and rotations.
  void embed(const Method& method) {
    method.rotations(rotations_);
    embedding_.deform(method.positions(), rotations_, deformed_);
  }

  /// Sample points of the last embed(): object.sampleVertices, then object.probes.
  std::vector<Eigen::Vector3d> samplePoints() const {
    std::vector<Eigen::Vector3d> s;
    s.reserve(object_.sampleVertices.size() + object_.probes.size());
    for (std::uint32_t v : object_.sampleVertices) s.push_back(deformed_[v]);
    s.insert(s.end(), deformed_.end() - static_cast<std::ptrdiff_t>(object_.probes.size()), deformed_.end());
    return s;
  }

  /// (V - V0) / V0 of the render mesh of the last embed().
  double volumeChange() const {
    const auto vertexCount = static_cast<std::ptrdiff_t>(object_.mesh.vertices.size());
    const std::vector<Eigen::Vector3d> verts(deformed_.begin(), deformed_.begin() + vertexCount);
    return closedMeshVolume(verts, object_.mesh.triangles) / v0_ - 1.0;
  }

 private:
  /// The points embedded: the render mesh's vertices, then the probes.
  static std::vector<Eigen::Vector3d> meshAndProbes(const StudyObject& object) {
    std::vector<Eigen::Vector3d> points = object.mesh.vertices;
    points.insert(points.end(), object.probes.begin(), object.probes.end());
    return points;
  }

  const StudyObject& object_;
  const Embedding embedding_;
  const double v0_;
  std::vector<Eigen::Vector3d> deformed_;
  std::vector<Eigen::Quaterniond> rotations_;
};

/// Centroid (unweighted mean) of the rest positions `x0`.
inline Eigen::Vector3d restCentroid(const std::vector<Eigen::Vector3d>& x0) {
  Eigen::Vector3d restCentroid = Eigen::Vector3d::Zero();
  for (const auto& p : x0) restCentroid += p;
  restCentroid /= static_cast<double>(x0.size());
  return restCentroid;
}

/// The drag of a scenario's ear: its particles (none: no drag), their rest centroid, how far
/// (m, along +x) and over what ramp (s) they are dragged, and until when they are held (s).
struct DragPlan {
  std::vector<std::uint32_t> ear;
  Eigen::Vector3d earStart = Eigen::Vector3d::Zero();
  double dragDistance = 0.0, ramp = 0.0, holdUntil = 0.0;
};

/// Cantilever and column: pins the particles within kBarClampFraction of the bar's fixed end.
inline void clampBar(const StudyObject& object, const Lattice& lattice, Method& method) {
  const auto& x0 = lattice.restPositions();
  std::vector<std::uint32_t> clamp;
  const double cut = object.mesh.boundsMin().x() + kBarClampFraction * (object.mesh.boundsMax().x() - object.mesh.boundsMin().x());
  for (std::size_t i = 0; i < x0.size(); ++i)
    if (x0[i].x() < cut) clamp.push_back(static_cast<std::uint32_t>(i));
  method.setPinned(clamp, true);
}

/// Ear drag and drag far: pins the bunny's base and grabs its ear where it rests; returns the drag.
inline DragPlan grabEar(Scenario scenario, const StudyObject& object, const Lattice& lattice, Method& method) {
  const auto& x0 = lattice.restPositions();
  DragPlan d;
  method.setPinned(baseParticles(lattice, object), true);
  d.ear = earParticles(lattice, object);
  for (std::uint32_t p : d.ear) d.earStart += x0[p];
  d.earStart /= static_cast<double>(d.ear.size());
  const bool far = scenario == Scenario::DragFar;
  d.dragDistance = (far ? kDragFarDistance : kEarDragDistance) * object.size;
  d.ramp = far ? kDragFarRamp : kEarDragRamp;
  d.holdUntil = far ? kDragFarHoldUntil : kEarDragHoldUntil;
  method.grab(d.ear, d.earStart);
  return d;
}

/// Plane: every particle collapsed onto the horizontal plane through the rest centroid.
inline void collapseOntoPlane(const Lattice& lattice, const Eigen::Vector3d& restCentroid, Method& method) {
  std::vector<Eigen::Vector3d> x = lattice.restPositions();
  for (auto& p : x) p.y() = restCentroid.y();
  method.setPositions(x);
}

/// Scrambled: every particle placed at random (seed kScrambleSeed) in the rest bounding box.
inline void scramble(const Lattice& lattice, Method& method) {
  std::mt19937 rng(kScrambleSeed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  const Eigen::Vector3d lo = lattice.restMin(), hi = lattice.restMax();
  std::vector<Eigen::Vector3d> x(lattice.restPositions().size());
  for (auto& p : x) {
    const double a = u(rng), b = u(rng), c = u(rng);
    p = lo + Eigen::Vector3d(a, b, c).cwiseProduct(hi - lo);
  }
  method.setPositions(x);
}

/// Sets `method` up for `scenario` (clamp, pins and grab, or start positions); returns the drag.
inline DragPlan setUpScenario(Scenario scenario, const StudyObject& object, const Lattice& lattice, Method& method,
                              const Eigen::Vector3d& restCentroid) {
  switch (scenario) {
    case Scenario::Cantilever:
    case Scenario::Column: clampBar(object, lattice, method); break;
    case Scenario::EarDrag:
    case Scenario::DragFar: return grabEar(scenario, object, lattice, method);
    case Scenario::Plane: collapseOntoPlane(lattice, restCentroid, method); break;
    case Scenario::Scrambled: scramble(lattice, method); break;
  }
  return DragPlan();
}

/// Before frame `f` of a drag: moves the grab to where the target is at the end of the frame
/// while held; at the end of the hold, records the volume change in `rec` and releases.
inline void driveDrag(const DragPlan& drag, int f, int holdEndFrame, double frameStep, Method& method,
                      EmbeddedPoints& points, RunRecord& rec) {
  const double t = (f + 1) * frameStep;  // where the target is at the end of this frame
  if (f < holdEndFrame) {
    method.moveGrab(drag.earStart + Eigen::Vector3d(drag.dragDistance * std::min(1.0, t / drag.ramp), 0.0, 0.0));
  } else if (f == holdEndFrame) {
    points.embed(method);
    rec.volumeChange = points.volumeChange();
    method.release();
  }
}

/// Steps `method` one frame and records the step's CPU and wall time in `rec`.
inline void timedStep(Method& method, RunRecord& rec) {
  const double cpu0 = threadCpuSeconds();
  const auto t0 = std::chrono::steady_clock::now();
  method.step();
  const auto t1 = std::chrono::steady_clock::now();
  rec.frameCpuSeconds.push_back(threadCpuSeconds() - cpu0);
  rec.frameSeconds.push_back(std::chrono::duration<double>(t1 - t0).count());
}

/// Has the state `x` blown up: a coordinate not finite, or a particle farther than kBlowUpSizes
/// object sizes (`size`) from the rest centroid?
inline bool blownUp(const std::vector<Eigen::Vector3d>& x, const Eigen::Vector3d& restCentroid, double size) {
  bool bad = !allFinite(x);
  if (!bad)
    for (const auto& p : x)
      if ((p - restCentroid).norm() > kBlowUpSizes * size) {
        bad = true;
        break;
      }
  return bad;
}

}  // namespace detail

/// Runs `scenario` on `method` (whose lattice is `lattice`, built for `object`), sampling the
/// embedded points every `sampleEvery` frames (0: only at the end).
/// @param[in]     scenario     what to do
/// @param[in]     object       the object (render mesh, probes, size)
/// @param[in]     lattice      the method's lattice
/// @param[in,out] method       a method at rest, built on `lattice`
/// @param[in]     frameStep    the method's frame step (s)
/// @param[in]     sampleEvery  frames between trajectory samples; 0 for none
inline RunRecord runScenario(Scenario scenario, const StudyObject& object, const Lattice& lattice, Method& method,
                             double frameStep, int sampleEvery) {
  RunRecord rec;
  const int frames = static_cast<int>(std::lround(scenarioDuration(scenario) / frameStep));
  const double size = object.size;
  const auto& x0 = lattice.restPositions();
  detail::EmbeddedPoints points(object, lattice);
  const Eigen::Vector3d restCentroid = detail::restCentroid(x0);
  const detail::DragPlan drag = detail::setUpScenario(scenario, object, lattice, method, restCentroid);

  const int holdEndFrame = static_cast<int>(std::lround(drag.holdUntil / frameStep));
  const bool stress = scenario == Scenario::DragFar || scenario == Scenario::Plane || scenario == Scenario::Scrambled;
  int lastDistortedFrame = -1;  // stress scenarios: the last frame that ended with the shape error at or above tolerance
  rec.frameSeconds.reserve(static_cast<std::size_t>(frames));
  rec.frameCpuSeconds.reserve(static_cast<std::size_t>(frames));
  for (int f = 0; f < frames; ++f) {
    if (!drag.ear.empty()) detail::driveDrag(drag, f, holdEndFrame, frameStep, method, points, rec);
    detail::timedStep(method, rec);
    rec.frames = f + 1;

    const double energy = method.kineticEnergy();
    rec.peakKineticEnergy = std::isfinite(energy) ? std::max(rec.peakKineticEnergy, energy)
                                                  : std::numeric_limits<double>::infinity();
    const auto& x = method.positions();
    if (detail::blownUp(x, restCentroid, size)) {
      rec.blewUp = true;
      rec.blowUpFrame = f;
      break;
    }
    if (stress && rigidFitError(lattice.masses(), x0, x) / size >= kRecoveredTolerance) lastDistortedFrame = f;
    if (sampleEvery > 0 && (f + 1) % sampleEvery == 0) {
      points.embed(method);
      rec.trajectory.push_back(points.samplePoints());
    }
  }
  if (rec.blewUp) return rec;
  points.embed(method);
  rec.finalPoints = points.samplePoints();
  rec.finalVolumeChange = points.volumeChange();
  if (drag.ear.empty()) rec.volumeChange = rec.finalVolumeChange;
  rec.shapeError = rigidFitError(lattice.masses(), x0, method.positions()) / size;
  if (stress && rec.shapeError < kRecoveredTolerance)
    rec.recoveredAfter =
        std::max(0.0, (lastDistortedFrame + 1) * frameStep - (drag.ear.empty() ? 0.0 : drag.holdUntil));
  return rec;
}

/// Cantilever measures from the final probe points (the centre line, clamp to free end):
/// tip deflection over length, and the RMS difference between the normalised deflection profile
/// y(x)/y(L) and Euler-Bernoulli's (eulerBernoulliProfile()).
struct CantileverProfile {
  double tipDeflection = 0.0;  // y(L) / L, y the downward (-z) displacement of the centre line
  double eulerBernoulliRms = 0.0;
};

inline CantileverProfile cantileverProfile(const StudyObject& bar, const std::vector<Eigen::Vector3d>& finalPoints) {
  CantileverProfile out;
  const std::size_t np = bar.probes.size();
  const std::size_t first = finalPoints.size() - np;
  const double length = bar.mesh.boundsMax().x() - bar.mesh.boundsMin().x();
  const double clamp = kBarClampFraction * length;
  const double tip = bar.probes.back().z() - finalPoints[first + np - 1].z();
  out.tipDeflection = tip / length;
  double e = 0.0;
  for (std::size_t k = 0; k < np; ++k) {
    const double s = (bar.probes[k].x() - clamp) / (length - clamp);
    const double y = (bar.probes[k].z() - finalPoints[first + k].z()) / tip;
    e += (y - eulerBernoulliProfile(s)) * (y - eulerBernoulliProfile(s));
  }
  out.eulerBernoulliRms = std::sqrt(e / static_cast<double>(np));
  return out;
}

}  // namespace study
}  // namespace deformable_flsm
