/// @file scene_report.h
/// The text the node prints about a built scene at start-up: a summary (the lattice, the regions,
/// the material, the cost, the render mesh, the colliders, the pins) and the warnings about
/// choices the solver had to make (regions clamped or wider than the object, stiffness capped).
/// It reads only what building chose and measured (SceneInfo) and the parameters, so it is tested
/// without a solver. Building the scene is runtime/scene.h.
#pragma once

#include "deformable_flsm/runtime/node_params.h"

#include <cstddef>
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
  /// what ~integrator auto chose and why (empty when the integrator was asked for by name)
  std::string integratorChoice;
  /// false for an object of ~objects: the objects step together (~state's step_time)
  bool stepMeasured = true;
  /// measured: wall time of one step (s) and ns per particle per sub-step
  double stepSeconds = 0.0, nsPerParticleSubstep = 0.0;
  /// fraction of one core the solver needs at the configured real-time factor
  double cpuFraction = 0.0;
  /// the instruction set the step was measured at (simdLevelNote(): chosen at run time)
  std::string simd;
};

/// The start-up summary, one entry per line (no newlines inside): lattice, regions, thinnest
/// section, material, the integrator ~integrator auto chose, step cost (when measured), render mesh,
/// colliders, pins.
std::vector<std::string> sceneSummaryLines(const SceneInfo& info, const NodeParams& params);

/// A few lines for the start-up log: sceneSummaryLines() joined by newlines (none at the end).
std::string describeScene(const SceneInfo& info, const NodeParams& params);

/// Warning text when the time step is too long for the asked Young's modulus, else "".
std::string saturationWarning(const SceneInfo& info, const NodeParams& params);

/// The implicit step's collider contacts settle reliably up to this alpha per sub-step: above it
/// an impact can gain energy (docs/method.md, the implicit step's limits; `bench_drop`).
constexpr double kStiffContactAlpha = 1e4;

/// Warning text when the implicit integrator's alpha per sub-step is above kStiffContactAlpha
/// (the ~substeps that bring it below), else "".
std::string stiffContactWarning(const SceneInfo& info, const NodeParams& params);

/// Warning text when ~region_radius was more cells than the solver allows on this lattice and
/// the regions were clamped to the largest that fit, else "".
std::string regionClampWarning(const SceneInfo& info, const NodeParams& params);

/// Warning text when the regions are wider than the object's thinnest section in physical mode
/// (bending there comes out stiffer than the asked modulus: by how much, and what fixes it),
/// else "".
std::string sectionWarning(const SceneInfo& info, const NodeParams& params);

}  // namespace deformable_flsm
