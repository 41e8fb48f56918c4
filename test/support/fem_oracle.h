/// @file fem_oracle.h
/// A reference solution of linear elasticity on the solver's own voxels, and the analytic cases
/// it is checked against: the oracle that says whether the lattice material means what its
/// parameters say (tests, bench_material and the speed/accuracy study use it).
///
/// Usage (a cantilever clamped over its first quarter, sagging under gravity):
/// @code
///   FemOracle fem(voxels, FemMaterial{E, nu, rho}, 2);   // each cell split into 2^3 elements
///   fem.fixNodesInBox(lo, hi);  // the support Solver::pinBox(lo, hi) gives (hi at pinned centres)
///   const FemSolution u = fem.solveStatic(Eigen::Vector3d(0, 0, -9.81));
///   u.cellDisplacements[p];  // displacement at lattice particle p's rest position (m)
/// @endcode
///
/// Method: linear (small-strain) isotropic elasticity, trilinear hexahedra (8 nodes) integrated
/// with 2x2x2 Gauss points, one element per occupied cell, or s^3 per cell with subdivision s.
/// An element's stiffness and body force are scaled by its cell's fill fraction, as the
/// lattice's particle masses are. The sparse system K u = f over the free degrees of freedom is
/// solved by a sparse Cholesky (LDL^T) factorization. Fully integrated trilinear elements are
/// stiff in bending (parasitic shear): the error falls with the square of the element size
/// across a bent section, so compare coarse lattices with a subdivided oracle.
#pragma once

#include "deformable_flsm/core/voxelizer.h"

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <memory>
#include <vector>

namespace deformable_flsm {

/// An isotropic linear elastic material.
struct FemMaterial {
  /// Young's modulus E (Pa), > 0
  double youngsModulus = 1e5;
  /// Poisson's ratio nu, in [0, 0.5)
  double poissonsRatio = 0.0;
  /// Mass density rho (kg/m^3), > 0
  double density = 1000.0;

  /// @throws std::invalid_argument naming the field, its value and the valid range.
  void validate() const;
  /// Shear modulus mu = E / (2 (1 + nu)) (Pa)
  double shearModulus() const { return youngsModulus / (2.0 * (1.0 + poissonsRatio)); }
  /// First Lame parameter lambda = E nu / ((1 + nu)(1 - 2 nu)) (Pa)
  double lameLambda() const {
    return youngsModulus * poissonsRatio / ((1.0 + poissonsRatio) * (1.0 - 2.0 * poissonsRatio));
  }
};

/// What FemOracle::solveStatic() returns.
struct FemSolution {
  /// #N node displacements u (m), indexed like FemOracle::nodePositions()
  std::vector<Eigen::Vector3d> nodeDisplacements;
  /// #P displacement (m) at the centre of each occupied cell, in the order of the voxelization's
  /// cells, which is the order of the particles of a Lattice built from it: the trilinear
  /// interpolation of the element field there (for subdivision 1, the mean of the cell's 8
  /// corner displacements)
  std::vector<Eigen::Vector3d> cellDisplacements;
  /// #N force (N) the prescribed displacements and clamps exert on each node, K u - f, in the
  /// components they hold (zero in the free ones): their sum over a punch's nodes is the force
  /// the punch applies to the body (the body pushes the punch with its opposite)
  std::vector<Eigen::Vector3d> nodeReactions;
  /// Strain energy 1/2 u^T K u (J)
  double strainEnergy = 0.0;
};

/// Linear hexahedral finite elements on the occupied cells of a voxelization.
class FemOracle {
 public:
  /// @param[in] voxels       occupied cells and their fill fractions (the Voxelization a Lattice
  ///                         is built from); every fill fraction in (0, 1]
  /// @param[in] material     E, nu, rho
  /// @param[in] subdivision  s >= 1: each cell is split into s^3 elements
  /// @throws std::invalid_argument for an empty voxelization, an invalid material or s < 1.
  FemOracle(const Voxelization& voxels, const FemMaterial& material, int subdivision = 1);
  ~FemOracle();
  FemOracle(FemOracle&&) noexcept;
  FemOracle& operator=(FemOracle&&) noexcept;

  const FemMaterial& material() const { return material_; }
  int subdivision() const { return subdivision_; }
  /// #N rest positions of the element nodes (m)
  const std::vector<Eigen::Vector3d>& nodePositions() const { return nodes_; }
  std::size_t elementCount() const { return elementNodes_.size(); }

  /// Fixes every node of the cells whose centres lie in the box [lo, hi] (m): the same cells
  /// Solver::pinBox(lo, hi, true) pins, held in place as a whole. Returns how many cells.
  std::size_t clampCellsInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);
  /// Fixes (all three components of) every node whose rest position lies in [lo, hi] (m).
  /// Solver::pinBox holds particles, i.e. cell centres: to give the oracle the same support, fix
  /// the nodes up to the pinned cells' centres (an even subdivision puts a node at every centre);
  /// clampCellsInBox() instead moves the support out to the pinned cells' faces, half a cell
  /// further along the object. Returns how many nodes.
  std::size_t fixNodesInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi);
  /// Prescribes component `axis` (0, 1, 2) of the displacement of every node whose rest position
  /// lies in [lo, hi] (m) to `value` (m). Returns how many nodes.
  /// @throws std::invalid_argument for an axis outside 0..2 or a non-finite value.
  std::size_t prescribeInBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int axis, double value);
  /// Removes every clamp and prescribed displacement.
  void clearConstraints();

  /// Static equilibrium under a uniform body acceleration (m/s^2; gravity) and the prescribed
  /// displacements: K u = f with f the element body forces rho a V / 8 per node.
  /// @throws std::runtime_error when the constraints leave a rigid motion free (singular K).
  FemSolution solveStatic(const Eigen::Vector3d& bodyAcceleration) const;

  /// Sum of u.nodeReactions over the nodes whose rest positions lie in [lo, hi] (m): the force
  /// the prescribed displacements there exert on the body (N), e.g. a punch's.
  Eigen::Vector3d reactionInBox(const FemSolution& u, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) const;

  /// Lowest natural angular frequency omega_1 (rad/s) of K phi = omega^2 M phi with the lumped
  /// (row-sum) mass matrix, the constrained components held at zero (inverse iteration).
  /// @throws std::runtime_error when the constraints leave a rigid motion free.
  double lowestAngularFrequency() const;

 private:
  struct Factorization;
  /// Factorizes K over the free degrees of freedom (cached until the constraints change).
  const Factorization& factorization() const;

  FemMaterial material_;
  int subdivision_ = 1;
  double elementSize_ = 0.0;
  std::vector<Eigen::Vector3d> nodes_;
  /// per element, its 8 nodes, corner (a, b, c) in {0,1}^3 at index a + 2 b + 4 c
  std::vector<std::array<int, 8>> elementNodes_;
  std::vector<double> elementFill_;
  /// per cell, the nodes whose mean is the displacement at the cell centre (1 or 8)
  std::vector<std::vector<int>> cellCentreNodes_;
  /// per cell, its elements (s^3)
  std::vector<std::vector<int>> cellElements_;
  std::vector<Eigen::Vector3d> cellCentres_;
  /// per degree of freedom (3 node + axis): 1 when prescribed
  std::vector<char> prescribed_;
  std::vector<double> prescribedValue_;
  mutable std::unique_ptr<Factorization> factorization_;
};

/// Analytic solutions of linear elasticity the oracle and the lattice are checked against.
namespace analytic {

/// Deflection (m) at distance x from the clamp of a cantilever of free length L under its own
/// weight (uniform load q = rho g b t), Euler-Bernoulli plus Timoshenko's shear term
/// (Timoshenko & Gere): q x^2 (6 L^2 - 4 L x + x^2) / (24 E I) + q (L x - x^2 / 2) / (kappa G A),
/// I = b t^3 / 12, A = b t, G = E / (2 (1 + nu)), kappa = 10 (1 + nu) / (12 + 11 nu) (Cowper 1966,
/// rectangular section).
/// @param t  section height along the load (m); b the width across it (m); g the load (m/s^2)
double cantileverSelfWeightDeflection(double x, double length, double b, double t, double youngsModulus,
                                      double poissonsRatio, double density, double g);
/// Tip deflection (m): cantileverSelfWeightDeflection at x = L.
double cantileverSelfWeightTip(double length, double b, double t, double youngsModulus, double poissonsRatio,
                               double density, double g);
/// Top displacement (m) of a free-standing column of height H on a frictionless base under its
/// own weight, nu = 0 (uniaxial stress, exact): u_top = rho g H^2 / (2 E).
double columnSelfWeightTop(double height, double youngsModulus, double density, double g);
/// Lateral strain of a bar stretched by axial strain eps with free sides: -nu eps.
double uniaxialLateralStrain(double axialStrain, double poissonsRatio);
/// First bending angular frequency (rad/s) of a clamped-free Euler-Bernoulli beam of length L
/// and section height t along the vibration: omega_1 = (1.8751)^2 sqrt(E I / (rho A L^4)),
/// I / A = t^2 / 12.
double cantileverFirstBendingFrequency(double length, double t, double youngsModulus, double density);
/// Force (N) of a rigid frictionless sphere of radius R pressed to depth d into an elastic
/// half-space (Hertz): 4/3 E / (1 - nu^2) sqrt(R) d^1.5; contact radius sqrt(R d).
double hertzSphereForce(double radius, double depth, double youngsModulus, double poissonsRatio);
/// The same sphere pressed into a layer of thickness t bonded to a rigid base (laterally
/// unbounded): Hertz's force times the series of Dimitriadis et al. 2002 (Biophys. J. 82,
/// eq. 12) in chi = sqrt(R d) / t, 1 + c1 chi + c2 chi^2 + c3 chi^3 + c4 chi^4 with coefficients
/// from alpha0 = -(1.2876 - 1.4678 nu + 1.3442 nu^2) / (1 - nu) and
/// beta0 = (0.6387 - 1.0277 nu + 1.5164 nu^2) / (1 - nu) (at nu = 0.5: 1 + 1.133 chi +
/// 1.283 chi^2 + 0.769 chi^3 + 0.0975 chi^4, as published). At nu = 0 a layer 10 contact radii
/// thick carries 8.9 % more than the half-space.
double hertzSphereOnBondedLayerForce(double radius, double depth, double thickness, double youngsModulus,
                                     double poissonsRatio);

}  // namespace analytic

}  // namespace deformable_flsm
