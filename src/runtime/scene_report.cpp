#include "deformable_flsm/runtime/scene_report.h"

#include "deformable_flsm/core/section.h"
#include "deformable_flsm/core/solver_params.h"
#include "deformable_flsm/runtime/format.h"

#include <cmath>
#include <sstream>

namespace deformable_flsm {

namespace {

std::string latticeLine(const SceneInfo& info, const NodeParams& params) {
  if (info.latticeFrom == "particle_budget") {
    return formatted("lattice: %zu particles (finest within ~particle_budget %d: resolution %d, "
                   "spacing %.4g m, %d voxelizations in %.0f ms)",
                   info.particles, params.particleBudget, info.resolution, info.spacing,
                   info.voxelizations, 1e3 * info.voxelizeSeconds);
  }
  return formatted("lattice: %zu particles from ~%s (spacing %.4g m, voxelized in %.0f ms); "
                 "~particle_budget not used",
                 info.particles, info.latticeFrom.c_str(), info.spacing, 1e3 * info.voxelizeSeconds);
}

std::string regionsLine(const SceneInfo& info, const NodeParams& params) {
  const char* from = params.regionRadius > 0.0
                         ? (info.regionAskedCells > 0 ? " from ~region_radius, clamped" : " from ~region_radius")
                         : params.regionHalfWidth > 0 ? " from ~region_half_width" : " (the default)";
  return formatted("regions: %zu (one per particle), half-width w = %d cells (%.4g m)%s; object "
                 "%.4g m across, %.4g kg",
                 info.particles, info.regionHalfWidth, info.regionHalfWidth * info.spacing, from,
                 info.objectSize, info.totalMass);
}

std::string sectionLine(const SceneInfo& info, const NodeParams& params) {
  if (info.sectionCells <= 0) {
    return "thinnest section: not measured (" + info.sectionNotMeasured + ")" +
           (params.regionFromSection ? "; ~region_from_section keeps the asked regions" : "");
  }
  const std::string narrowed =
      info.regionHalfWidth < info.regionHalfWidthAsked
          ? ", regions narrowed from w = " + std::to_string(info.regionHalfWidthAsked) +
                " to fit it (~region_from_section)"
          : "";
  return formatted("thinnest section: %d%s cells (%.4g m; %.0f %% of the particles lie in thinner "
                 "ones)%s",
                 info.sectionCells, info.sectionCells >= kMaxSectionThickness ? " or more" : "",
                 info.sectionCells * info.spacing, 100.0 * kThinSectionFraction, narrowed.c_str());
}

std::string materialLine(const SceneInfo& info, const NodeParams& params) {
  const SolverParams& s = params.solver;
  if (s.youngsModulus > 0.0) {
    return formatted("material: Young's modulus %.4g Pa, density %.4g kg/m^3 -> alpha %.3g per "
                   "sub-step (%s)",
                   s.youngsModulus, s.density, info.alpha,
                   info.substepsForModulus > 0 ? "saturated: softer than asked, see the warning"
                                               : "as asked");
  }
  return formatted("material: alpha = ~stiffness = %.3g per sub-step "
                 "(~material classic), density %.4g kg/m^3", s.stiffness, s.density);
}

std::string stepLine(const SceneInfo& info, const NodeParams& params) {
  const SolverParams& s = params.solver;
  return formatted("step: %.3g s in %d sub-steps (%s solver) measured at %.2f ms = %.0f ns per "
                 "particle-substep; at real-time factor %.3g the solver takes %.0f%% of a core",
                 s.timeStep, s.substeps, toString(s.kind), 1e3 * info.stepSeconds,
                 info.nsPerParticleSubstep, params.realTimeFactor, 100.0 * info.cpuFraction) +
         (info.simd.empty() ? "" : "; " + info.simd);
}

std::string renderLine(const SceneInfo& info, const NodeParams& params) {
  std::string line =
      formatted("render mesh: %zu triangles, %zu vertices", info.renderTriangles, info.renderVertices);
  if (info.renderTriangles != info.loadedTriangles) {
    line += formatted(" (simplified from %zu for ~render_triangle_budget %d, error %.2g%% of the "
                    "extent)",
                    info.loadedTriangles, params.renderTriangleBudget, 100.0 * info.simplifyError);
  }
  return line;
}

std::string collidersLine(const SceneInfo& info, const NodeParams& params) {
  return formatted("colliders: %zu (%s), particles collide as spheres of radius %.3g m",
                 params.colliders.size() + (params.ground ? 1 : 0),
                 params.ground ? "with the ground" : "no ground", info.contactRadius);
}

std::string pinnedLine(const SceneInfo& info) {
  std::ostringstream out;
  out << "pinned: " << info.pinned << " particles";
  for (std::size_t b = 0; b < info.pinnedPerBox.size(); ++b) {
    out << (b == 0 ? " (" : ", ") << "box " << b << ": " << info.pinnedPerBox[b];
    if (b + 1 == info.pinnedPerBox.size()) out << ")";
  }
  return out.str();
}

}  // namespace

std::vector<std::string> sceneSummaryLines(const SceneInfo& info, const NodeParams& params) {
  std::vector<std::string> lines = {latticeLine(info, params), regionsLine(info, params),
                                    sectionLine(info, params), materialLine(info, params)};
  if (!info.integratorChoice.empty()) lines.push_back("integrator: " + info.integratorChoice);
  if (info.stepMeasured) lines.push_back(stepLine(info, params));
  lines.push_back(renderLine(info, params));
  lines.push_back(collidersLine(info, params));
  lines.push_back(pinnedLine(info));
  return lines;
}

std::string describeScene(const SceneInfo& info, const NodeParams& params) {
  const std::vector<std::string> lines = sceneSummaryLines(info, params);
  std::string text;
  for (std::size_t k = 0; k < lines.size(); ++k) text += (k == 0 ? "" : "\n") + lines[k];
  return text;
}

std::string saturationWarning(const SceneInfo& info, const NodeParams& params) {
  if (info.substepsForModulus == 0) return "";
  const SolverParams& s = params.solver;
  return formatted("~youngs_modulus %.4g Pa asks for alpha %.3g per sub-step, more than the %.3g "
                   "the solver allows under ~stiffness %.3g: the material is %.3g times softer "
                   "than asked because the sub-step (%.3g s) is too long. ~substeps %d (instead of %d) "
                   "would fix it, or ~integrator implicit (the modulus as asked at any sub-step).",
                   s.youngsModulus, info.requestedAlpha, info.alpha, s.stiffness,
                   info.requestedAlpha / info.alpha, s.substepLength(), info.substepsForModulus,
                   s.substeps);
}

std::string stiffContactWarning(const SceneInfo& info, const NodeParams& params) {
  const SolverParams& s = params.solver;
  if (s.integrator != Integrator::Implicit || !(info.requestedAlpha > kStiffContactAlpha)) return "";
  const int substeps = static_cast<int>(std::ceil(s.substeps * std::sqrt(info.requestedAlpha / kStiffContactAlpha)));
  return formatted("~youngs_modulus %.4g Pa at a sub-step of %.3g s asks for alpha %.3g per sub-step, above the "
                   "%.0f up to which the implicit step's contacts settle reliably: an impact on a collider may "
                   "gain energy (a 10 MPa block at alpha 1.3e5 dropped 6 cm reached up to 2,800 times the energy "
                   "of its fall). ~substeps %d (instead of %d) keeps alpha below it.",
                   s.youngsModulus, s.substepLength(), info.requestedAlpha, kStiffContactAlpha, substeps,
                   s.substeps);
}

std::string regionClampWarning(const SceneInfo& info, const NodeParams& params) {
  if (info.regionAskedCells == 0) return "";
  return formatted("~region_radius %.4g m is %d cells on this lattice (spacing %.4g m), more than "
                   "the %d the solver allows: using %d cells (%.4g m), the largest that fits. Set "
                   "~region_radius to at most %.4g m, or use a coarser lattice (a larger ~spacing, a "
                   "smaller ~resolution or ~particle_budget), to silence this warning.",
                   params.regionRadius, info.regionAskedCells, info.spacing, kMaxRegionHalfWidth,
                   info.regionHalfWidth, info.regionHalfWidth * info.spacing,
                   kMaxRegionHalfWidth * info.spacing);
}

std::string sectionWarning(const SceneInfo& info, const NodeParams& params) {
  const int w = info.regionHalfWidth;
  if (params.solver.youngsModulus <= 0.0 || info.sectionCells <= 0 || 2 * w + 1 <= info.sectionCells) return "";
  const int fits = regionHalfWidthForSection(info.sectionCells, w);
  const std::string text = formatted("regions of half-width w = %d cells (%d cells wide) are wider than the object's "
                                     "thinnest section, %d cells (%.4g m; %.0f %% of the particles lie in thinner ones): "
                                     "bending there comes out about %.2g times as stiff as ~youngs_modulus says "
                                     "(cantilevers against linear FEM). ",
                                     w, 2 * w + 1, info.sectionCells, info.sectionCells * info.spacing,
                                     100.0 * kThinSectionFraction, bendingStiffeningEstimate(w, info.sectionCells));
  if (fits < w) {
    return text + formatted("~region_from_section true would use w = %d (regions within 10 %% of linear FEM "
                            "in bending; for the same modulus they may need more ~substeps), or use a finer "
                            "lattice.",
                            fits);
  }
  return text + "w = 1 is the narrowest region: only a finer lattice (more cells across the section) fixes it.";
}

}  // namespace deformable_flsm
