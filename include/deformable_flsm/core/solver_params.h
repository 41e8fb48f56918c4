/// @file solver_params.h
/// Plain parameters of the FastLSM solver, filled by the caller (the ROS layer reads them).
#pragma once

#include <Eigen/Core>

#include <stdexcept>
#include <string>

namespace deformable_flsm {

/// Which way region sums are computed. Both give the same results (to round-off).
enum class SolverKind {
  /// FastLSM separable summation: cost per particle independent of the region half-width w
  Fast,
  /// Direct summation over each region's members, O(w^3) per particle (the seed's "SLSM");
  /// kept as the oracle the fast solver is tested against
  Naive,
};

/// Parses "fast" / "naive". @throws std::invalid_argument otherwise.
SolverKind parseSolverKind(const std::string& name);
/// "fast" or "naive".
const char* toString(SolverKind kind);

/// How a sub-step advances the state.
enum class Integrator {
  /// Symplectic Euler (Rivers & James 2007, eq. 7): cheap per sub-step, stable only while
  /// (omega h)^2 stays under its bound, so a stiff material is capped (Solver::alpha())
  Explicit,
  /// Linearly implicit backward Euler with the co-rotated region stiffness (one Newton step per
  /// sub-step, solved by conjugate gradients): no bound on the modulus from the sub-step, at the
  /// price of numerical damping of the stiff modes (docs/method.md)
  Implicit,
};

/// Parses "explicit" / "implicit". @throws std::invalid_argument otherwise.
Integrator parseIntegrator(const std::string& name);
/// "explicit" or "implicit".
const char* toString(Integrator integrator);

/// The implicit step's time discretisation (Integrator::Implicit only).
enum class ImplicitScheme {
  /// Backward Euler: first order; damps a mode of angular frequency omega by
  /// (1 + (omega h)^2)^(-pi / (omega h)) a period (docs/method.md)
  BackwardEuler,
  /// BDF2, the second-order backward differentiation formula: x+ = (4 x_n - x_{n-1}) / 3 +
  /// (2h / 3) v+, v+ likewise; still L-stable, and a mode keeps 0.96 of its amplitude a period at
  /// omega h = 0.32 where backward Euler keeps 0.38. Solved as a backward Euler step of 2h/3 from
  /// the extrapolated state; the first sub-step, and a particle that a contact, a pin or a hard
  /// drag moved in the last one, start again from their present velocity. After a sub-step in
  /// which some particle's goal - x changed by more than a tenth of a cell (a crushed, scrambled
  /// or violently dragged object, a landing) a sub-step is backward Euler's, which recovers from
  /// any start (docs/method.md). One object, or objects that do not touch (World refuses it
  /// otherwise).
  Bdf2,
};

/// Parses "backward_euler" / "bdf2". @throws std::invalid_argument otherwise.
ImplicitScheme parseImplicitScheme(const std::string& name);
/// "backward_euler" or "bdf2".
const char* toString(ImplicitScheme scheme);

/// Largest region half-width w (cells) the solver accepts: (2w+1)^3 = 9261 cells per region at
/// w = 10, beyond any useful stiffness.
constexpr int kMaxRegionHalfWidth = 10;

/// Region half-width w (cells) for a region radius in metres: the nearest whole number of cells,
/// at least 1, so that regions keep their physical size whatever the lattice spacing.
/// @throws std::invalid_argument for a non-positive or non-finite radius or spacing, or a
///         radius of more than kMaxRegionHalfWidth cells
int regionHalfWidthForRadius(double radius, double spacing);

struct SolverParams {
  /// Region half-width w in lattice cells: a region spans up to (2w+1)^3 cells. Larger is stiffer.
  int regionHalfWidth = 2;
  /// Fraction alpha in (0, 1] of the way to the goal positions taken per sub-step:
  /// v += alpha (g - x) / h (Rivers & James 2007, eq. 7). Used as is when youngsModulus is 0
  /// (classic mode). In physical mode (youngsModulus > 0) it scales the cap on alpha, which
  /// follows the stability of the sub-step (Solver::alpha()): 1 allows the full documented margin.
  /// alpha alone changes meaning with the time step and the lattice: prefer youngsModulus.
  double stiffness = 1.0;
  /// Young's modulus E (Pa) of the material; 0 to use `stiffness` as alpha directly.
  ///
  /// Shape matching's impulses are the gradient of E_sm = k/2 sum_r beta_r sum_{i in r} m~_i
  /// |T_r x0_i - x_i|^2 with k = alpha / h^2 (h the sub-step). For a small uniform strain eps, an
  /// interior region of (2w+1)^3 cells of spacing dx holds k/2 m dx^2 sigma^2 tr(eps^2),
  /// sigma^2 = w(w+1)/3, one region per cell: the energy density of linear elasticity with shear
  /// modulus mu = k rho dx^2 sigma^2 / 2 and lambda = 0. So alpha = 6 mu h^2 / (rho dx^2 w(w+1))
  /// with mu = E / (2 (1 + nu)), and poissonsRatio adds lambda: the same E and nu give the same
  /// material at every time step and lattice spacing, as long as alpha stays under its cap
  /// (Solver::stiffnessSaturated() tells when the step is too long for E).
  ///
  /// Accuracy against linear elasticity (FEM on the same voxels, bench_material): within 10 % for
  /// bending, compression and stretching when the regions (2w + 1 cells) are no wider than the
  /// thinnest section; wider regions make bending stiffer (section.h says why; the figures are in
  /// docs/method.md). Choose w from the thinnest feature of the object: section.h measures it and
  /// regionHalfWidthForSection() gives the widest regions that fit.
  double youngsModulus = 0.0;
  /// Poisson's ratio nu of the material, in [0, 0.45] (physical mode only: with youngsModulus 0
  /// it must stay 0). Shape matching penalises every non-rigid deformation alike, the energy of
  /// a material with Lame parameters (mu, lambda = 0), i.e. nu = 0; nu > 0 takes
  /// mu = E / (2 (1 + nu)) for shape matching and adds lambda / 2 (tr eps)^2 per cell,
  /// lambda = E nu / ((1 + nu)(1 - 2 nu)), with tr eps the trace of the Green strain on the
  /// lattice stencil of each particle (see Solver). Lateral strain in uniaxial stress is -nu eps
  /// within 0.04; the volumetric stiffness needs shorter sub-steps as nu grows (lambda = 9 mu at
  /// 0.45), see Solver::alpha(). 0 by default: classic shape matching's material.
  double poissonsRatio = 0.0;
  /// Rate (1/s) at which each region's deviation from rigid motion is damped; 0 for none.
  /// Momentum-conserving: linear and angular momentum of every region are kept. Bending modes
  /// longer than a region look nearly rigid inside each region and are damped far more slowly
  /// than this rate, hence a default well above the wobble one wants to see.
  double damping = 10.0;
  /// Ambient damping c (1/s): mass-proportional Rayleigh damping, C = c M, of the motion relative
  /// to the object's own rigid motion (its best rigid fit keeping linear and angular momentum).
  /// Every vibration mode of angular frequency omega gets the damping ratio zeta = c / (2 omega):
  /// for a damping ratio zeta of the first mode, c = 2 zeta omega_1. It settles the long, slow
  /// modes (a cantilever's first bending mode looks rigid inside every region, so region damping
  /// hardly reaches it); a falling, thrown or spinning object keeps its momentum. An object the
  /// world can hold (pinned, dragged or attached, or with colliders in the scene) is damped
  /// relative to rest instead, so that it settles on its supports. 0 for none.
  double ambientDamping = 0.5;
  /// Gravitational acceleration (m/s^2).
  Eigen::Vector3d gravity = Eigen::Vector3d(0.0, 0.0, -9.81);
  /// Simulated time advanced by one call of Solver::step() (s).
  double timeStep = 1.0 / 60.0;
  /// Sub-steps per call of Solver::step(); each advances timeStep / substeps.
  int substeps = 4;
  /// Mass density of the object (kg/m^3); particle mass = density * filled cell volume.
  double density = 1000.0;
  SolverKind kind = SolverKind::Fast;
  /// Explicit (symplectic Euler, alpha capped by stability) or implicit (backward Euler, alpha as
  /// requested whatever the sub-step).
  Integrator integrator = Integrator::Explicit;
  /// The implicit step's discretisation (ignored by the explicit step).
  ImplicitScheme implicitScheme = ImplicitScheme::BackwardEuler;
  /// Threads a step uses (OpenMP); 0 for every hardware thread. Results do not depend on it:
  /// threads take whole blocks of z-slices, at whose starts every sliding window restarts, so
  /// each sum is the same sequence of additions (see SliceStreamSummer). Threads pay only on idle
  /// cores (with another job on a core, threads that wait for each other cost several times one
  /// thread: docs/performance.md), so with more than one the solver times its steps and runs each
  /// on the threads or on one thread, whichever has been faster lately (ThreadGovernor,
  /// Solver::threadGovernor()).
  int threads = 1;

  /// Radius (m) of the sphere each particle is for contact with colliders; 0 means half the
  /// lattice spacing (the particles' cells then tile the object's volume).
  double contactRadius = 0.0;

  /// @throws std::invalid_argument with a message naming the field, its value and the valid range.
  void validate() const;

  /// Sub-step length h = timeStep / substeps (s).
  double substepLength() const { return timeStep / substeps; }
  /// The alpha that youngsModulus asks for on a lattice of the given spacing (m), before the cap;
  /// `stiffness` when youngsModulus is 0.
  double requestedAlpha(double spacing) const;
  /// Shear modulus mu = E / (2 (1 + nu)) (Pa); 0 in classic mode.
  double shearModulus() const { return youngsModulus / (2.0 * (1.0 + poissonsRatio)); }
  /// Lame's first parameter lambda = E nu / ((1 + nu)(1 - 2 nu)) (Pa); 0 in classic mode.
  double lameLambda() const {
    return youngsModulus * poissonsRatio / ((1.0 + poissonsRatio) * (1.0 - 2.0 * poissonsRatio));
  }
};

}  // namespace deformable_flsm
