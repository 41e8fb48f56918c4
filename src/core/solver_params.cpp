#include "deformable_flsm/core/solver_params.h"

#include "number_text.h"

#include <algorithm>
#include <cmath>

namespace deformable_flsm {

namespace {

/// Largest time step accepted (s); beyond it even a stiff lattice is a slideshow.
constexpr double kMaxTimeStep = 0.1;
constexpr int kMaxSubsteps = 1000;
/// Largest Poisson's ratio accepted: lambda / mu = 2 nu / (1 - 2 nu) grows without bound towards
/// 0.5, and with it the volumetric stiffness the sub-step must resolve (9 mu at 0.45).
constexpr double kMaxPoissonsRatio = 0.45;
/// More threads than any machine this runs on has cores; beyond it is a typo.
constexpr int kMaxThreads = 256;

[[noreturn]] void fail(const std::string& field, const std::string& value,
                       const std::string& expected) {
  throw std::invalid_argument("invalid solver parameter '" + field + "' = " + value + ": " +
                              expected);
}

}  // namespace

SolverKind parseSolverKind(const std::string& name) {
  if (name == "fast") return SolverKind::Fast;
  if (name == "naive") return SolverKind::Naive;
  throw std::invalid_argument("invalid solver '" + name + "': expected 'fast' or 'naive'");
}

const char* toString(SolverKind kind) { return kind == SolverKind::Fast ? "fast" : "naive"; }

Integrator parseIntegrator(const std::string& name) {
  if (name == "explicit") return Integrator::Explicit;
  if (name == "implicit") return Integrator::Implicit;
  throw std::invalid_argument("invalid integrator '" + name + "': expected 'explicit' or 'implicit'");
}

const char* toString(Integrator integrator) {
  return integrator == Integrator::Implicit ? "implicit" : "explicit";
}

ImplicitScheme parseImplicitScheme(const std::string& name) {
  if (name == "backward_euler") return ImplicitScheme::BackwardEuler;
  if (name == "bdf2") return ImplicitScheme::Bdf2;
  throw std::invalid_argument("invalid implicit scheme '" + name + "': expected 'backward_euler' or 'bdf2'");
}

const char* toString(ImplicitScheme scheme) { return scheme == ImplicitScheme::Bdf2 ? "bdf2" : "backward_euler"; }

int regionHalfWidthForRadius(double radius, double spacing) {
  if (!std::isfinite(radius) || radius <= 0.0)
    fail("region_radius", numberText(radius), "expected a finite radius > 0 (m)");
  if (!std::isfinite(spacing) || spacing <= 0.0)
    fail("spacing", numberText(spacing), "expected a finite lattice spacing > 0 (m)");
  const double w = std::round(radius / spacing);
  if (w > kMaxRegionHalfWidth)
    fail("region_radius", numberText(radius),
         "is " + numberText(w) + " cells at spacing " + numberText(spacing) + " m; at most " +
             std::to_string(kMaxRegionHalfWidth) + " cells: use a radius of at most " +
             numberText(kMaxRegionHalfWidth * spacing) + " m on this lattice, or a coarser lattice (a larger "
             "spacing, a smaller resolution or particle_budget)");
  return std::max(1, static_cast<int>(w));
}

double SolverParams::requestedAlpha(double spacing) const {
  if (youngsModulus <= 0.0) return stiffness;
  const double h = substepLength();
  const double w = regionHalfWidth;
  // shape matching carries the shear modulus: 2 mu = k rho dx^2 w (w + 1) / 3, k = alpha / h^2
  return 3.0 * 2.0 * shearModulus() * h * h / (density * spacing * spacing * w * (w + 1.0));
}

void SolverParams::validate() const {
  if (regionHalfWidth < 1 || regionHalfWidth > kMaxRegionHalfWidth)
    fail("region_half_width", std::to_string(regionHalfWidth),
         "expected an integer from 1 to " + std::to_string(kMaxRegionHalfWidth));
  if (!std::isfinite(stiffness) || stiffness <= 0.0 || stiffness > 1.0)
    fail("stiffness", numberText(stiffness), "expected a fraction in (0, 1]");
  if (!std::isfinite(youngsModulus) || youngsModulus < 0.0)
    fail("youngs_modulus", numberText(youngsModulus), "expected a finite modulus >= 0 (Pa; 0 uses stiffness)");
  if (!std::isfinite(poissonsRatio) || poissonsRatio < 0.0 || poissonsRatio > kMaxPoissonsRatio)
    fail("poissons_ratio", numberText(poissonsRatio), "expected a ratio from 0 to " + numberText(kMaxPoissonsRatio));
  if (youngsModulus <= 0.0 && poissonsRatio != 0.0)
    fail("poissons_ratio", numberText(poissonsRatio),
         "needs youngs_modulus > 0 (with youngs_modulus 0, alpha = stiffness is a bare shape-matching "
         "fraction with no Poisson effect): set youngs_modulus or poissons_ratio 0");
  if (!std::isfinite(damping) || damping < 0.0)
    fail("damping", numberText(damping), "expected a finite rate >= 0 (1/s)");
  if (!std::isfinite(ambientDamping) || ambientDamping < 0.0)
    fail("ambient_damping", numberText(ambientDamping), "expected a finite rate >= 0 (1/s)");
  if (!gravity.allFinite())
    fail("gravity", "[" + numberText(gravity.x()) + ", " + numberText(gravity.y()) + ", " + numberText(gravity.z()) + "]",
         "expected three finite numbers (m/s^2)");
  if (!std::isfinite(timeStep) || timeStep <= 0.0 || timeStep > kMaxTimeStep)
    fail("time_step", numberText(timeStep), "expected a step in (0, " + numberText(kMaxTimeStep) + "] seconds");
  if (substeps < 1 || substeps > kMaxSubsteps)
    fail("substeps", std::to_string(substeps),
         "expected an integer from 1 to " + std::to_string(kMaxSubsteps));
  if (threads < 0 || threads > kMaxThreads)
    fail("threads", std::to_string(threads),
         "expected 0 (all hardware threads) or a count from 1 to " + std::to_string(kMaxThreads));
  if (!std::isfinite(density) || density <= 0.0)
    fail("density", numberText(density), "expected a finite density > 0 (kg/m^3)");
  if (integrator != Integrator::Explicit && integrator != Integrator::Implicit)
    fail("integrator", std::to_string(static_cast<int>(integrator)), "expected 'explicit' or 'implicit'");
  if (implicitScheme != ImplicitScheme::BackwardEuler && implicitScheme != ImplicitScheme::Bdf2)
    fail("implicit_scheme", std::to_string(static_cast<int>(implicitScheme)), "expected 'backward_euler' or 'bdf2'");
  if (!std::isfinite(contactRadius) || contactRadius < 0.0)
    fail("contact_radius", numberText(contactRadius),
         "expected a finite radius >= 0 (m; 0 uses half the lattice spacing)");
}

}  // namespace deformable_flsm
