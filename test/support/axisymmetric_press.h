/// @file axisymmetric_press.h
/// The oracle for a sphere pressed into a block: linear elasticity of a cylinder bonded to a
/// rigid base, axisymmetric, on a mesh graded down to a small fraction of the contact radius,
/// with frictionless unilateral contact (the active set of surface nodes the indenter holds).
/// Unlike Hertz's formulas it takes the sphere as a sphere (not a paraboloid) and the block's
/// finite width (a free side); unlike the 3-D FemOracle it resolves the contact.
///
/// Usage (the lattice block of test_local_stiffness, 5.25 cm square, as a cylinder of its area):
/// @code
///   AxisymmetricPress p;
///   p.indenterRadius = 0.02; p.depth = 0.002; p.thickness = 0.02875;
///   p.outerRadius = 0.0525 / std::sqrt(M_PI);
///   p.material = FemMaterial{2e4, 0.0, 1000.0};
///   const AxisymmetricPressResult r = axisymmetricPress(p);   // r.force (N)
/// @endcode
///
/// Method: bilinear quadrilaterals in (r, z) with 2 x 2 Gauss points, strains (rr, zz, theta
/// theta = u_r / r, rz), each weighted by 2 pi r; u_r = 0 on the axis, the base fixed. The top
/// nodes the indenter's surface reaches are held to it in z (free in r: frictionless); a held
/// node the surface would have to pull is released, a free one that crosses the surface is
/// held, until the set stands (each pass a sparse LDL^T solve). Checked against Hertz on a thick
/// layer and Dimitriadis et al.'s bonded layer (test_fem_oracle).
#pragma once

#include "support/fem_oracle.h"

#include <cstddef>

namespace deformable_flsm {

/// A rigid frictionless sphere pressed into the centre of a bonded elastic cylinder.
struct AxisymmetricPress {
  /// R (m), > 0
  double indenterRadius = 0.02;
  /// how far the sphere's lowest point goes below the undeformed top face (m), in (0, R)
  double depth = 0.001;
  /// from the rigid base to the top face (m), > 0
  double thickness = 0.03;
  /// the cylinder's radius (m), its side free, > sqrt(R depth)
  double outerRadius = 0.3;
  FemMaterial material;
  /// true: the paraboloid z = r^2 / (2 R) of Hertz's theory instead of the sphere
  bool paraboloid = false;
  /// element size near the contact, as a fraction of the contact radius sqrt(R depth)
  double finestFraction = 0.04;
};

struct AxisymmetricPressResult {
  /// the indenter's force on the body (N, pressing)
  double force = 0.0;
  /// the outermost held node's radius (m)
  double contactRadius = 0.0;
  std::size_t nodes = 0;
  int activeSetPasses = 0;
};

/// @throws std::invalid_argument for a field outside its range, std::runtime_error when the
///         active set does not settle.
AxisymmetricPressResult axisymmetricPress(const AxisymmetricPress& press);

}  // namespace deformable_flsm
