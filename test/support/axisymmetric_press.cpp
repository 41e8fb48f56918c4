#include "support/axisymmetric_press.h"

#include <Eigen/Sparse>
#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {

namespace {

/// Element growth away from the contact, and the coarsest element as a fraction of the thickness.
constexpr double kGrowth = 1.15;
constexpr double kCoarsestFraction = 0.25;
/// The fine zone: 1.5 contact radii out from the axis, one down from the top.
constexpr double kFineRadial = 1.5;
constexpr double kFineDepth = 1.0;
constexpr int kMaxPasses = 100;

/// Coordinates from 0 to `length`: steps of `fine` up to `fineUntil`, then growing by kGrowth up
/// to `coarse`.
std::vector<double> graded(double length, double fine, double fineUntil, double coarse) {
  std::vector<double> x{0.0};
  while (x.back() < std::min(fineUntil, length) - 1e-12 * length) x.push_back(std::min(x.back() + fine, fineUntil));
  double h = fine;
  while (x.back() < length - 1e-12 * length) {
    h = std::min(h * kGrowth, std::max(coarse, fine));
    x.push_back(std::min(x.back() + h, length));
  }
  return x;
}

void check(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument("axisymmetricPress: " + what);
}

}  // namespace

AxisymmetricPressResult axisymmetricPress(const AxisymmetricPress& p) {
  p.material.validate();
  const double R = p.indenterRadius, d = p.depth;
  check(std::isfinite(R) && R > 0.0, "indenterRadius must be > 0");
  check(std::isfinite(d) && d > 0.0 && d < R, "depth must be in (0, indenterRadius)");
  check(std::isfinite(p.thickness) && p.thickness > 0.0, "thickness must be > 0");
  const double a = std::sqrt(R * d);
  check(std::isfinite(p.outerRadius) && p.outerRadius > a, "outerRadius must exceed the contact radius sqrt(R d)");
  check(std::isfinite(p.finestFraction) && p.finestFraction > 0.0 && p.finestFraction <= 0.5,
        "finestFraction must be in (0, 0.5]");

  const double fine = p.finestFraction * a, coarse = kCoarsestFraction * p.thickness;
  const std::vector<double> rs = graded(p.outerRadius, fine, kFineRadial * a, coarse);
  std::vector<double> zs = graded(p.thickness, fine, kFineDepth * a, coarse);
  for (double& z : zs) z = p.thickness - z;
  std::reverse(zs.begin(), zs.end());  // zs[0] = 0 the base, zs.back() the top
  const int nr = static_cast<int>(rs.size()), nz = static_cast<int>(zs.size());
  const int nodes = nr * nz, dofs = 2 * nodes;
  const auto node = [nr](int i, int j) { return j * nr + i; };

  // D in the order (rr, zz, theta theta, rz), engineering shear
  const double lambda = p.material.lameLambda(), mu = p.material.shearModulus();
  Eigen::Matrix4d D = Eigen::Matrix4d::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) D(i, j) = lambda;
    D(i, i) = lambda + 2.0 * mu;
  }
  D(3, 3) = mu;

  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(64) * (nr - 1) * (nz - 1));
  const double g = 1.0 / std::sqrt(3.0), pi = 3.14159265358979323846;
  for (int j = 0; j + 1 < nz; ++j) {
    for (int i = 0; i + 1 < nr; ++i) {
      const int n[4] = {node(i, j), node(i + 1, j), node(i + 1, j + 1), node(i, j + 1)};
      const double hr = rs[i + 1] - rs[i], hz = zs[j + 1] - zs[j];
      Eigen::Matrix<double, 8, 8> K = Eigen::Matrix<double, 8, 8>::Zero();
      for (int gp = 0; gp < 4; ++gp) {
        const double xi = (gp & 1) ? g : -g, eta = (gp & 2) ? g : -g;
        const double N[4] = {0.25 * (1 - xi) * (1 - eta), 0.25 * (1 + xi) * (1 - eta), 0.25 * (1 + xi) * (1 + eta),
                             0.25 * (1 - xi) * (1 + eta)};
        const double dxi[4] = {-0.25 * (1 - eta), 0.25 * (1 - eta), 0.25 * (1 + eta), -0.25 * (1 + eta)};
        const double deta[4] = {-0.25 * (1 - xi), -0.25 * (1 + xi), 0.25 * (1 + xi), 0.25 * (1 - xi)};
        const double r = rs[i] + 0.5 * (1 + xi) * hr;  // a rectangle: the map is affine
        Eigen::Matrix<double, 4, 8> B = Eigen::Matrix<double, 4, 8>::Zero();
        for (int k = 0; k < 4; ++k) {
          const double dr = dxi[k] * 2.0 / hr, dz = deta[k] * 2.0 / hz;
          B(0, 2 * k) = dr;
          B(1, 2 * k + 1) = dz;
          B(2, 2 * k) = N[k] / r;
          B(3, 2 * k) = dz;
          B(3, 2 * k + 1) = dr;
        }
        const Eigen::Matrix<double, 4, 8> DB = D.lazyProduct(B);
        K += B.transpose().lazyProduct(DB) * (2.0 * pi * r * 0.25 * hr * hz);
      }
      for (int a1 = 0; a1 < 8; ++a1)
        for (int b1 = 0; b1 < 8; ++b1)
          triplets.emplace_back(2 * n[a1 / 2] + a1 % 2, 2 * n[b1 / 2] + b1 % 2, K(a1, b1));
    }
  }
  Eigen::SparseMatrix<double> K(dofs, dofs);
  K.setFromTriplets(triplets.begin(), triplets.end());

  // the indenter's surface below the top face at each top node's radius (m, > 0 where it presses)
  std::vector<double> reach(nr);
  for (int i = 0; i < nr; ++i) {
    const double r = rs[i];
    const double rise = p.paraboloid ? r * r / (2.0 * R) : (r < R ? R - std::sqrt(R * R - r * r) : R + r);
    reach[i] = d - rise;
  }
  std::vector<char> fixedDof(dofs, 0);
  for (int i = 0; i < nr; ++i) fixedDof[2 * node(i, 0)] = fixedDof[2 * node(i, 0) + 1] = 1;  // the base
  for (int j = 0; j < nz; ++j) fixedDof[2 * node(0, j)] = 1;                                 // u_r = 0 on the axis
  std::vector<char> held(nr, 0);
  for (int i = 0; i < nr; ++i) held[i] = reach[i] > 0.0;

  AxisymmetricPressResult result;
  result.nodes = static_cast<std::size_t>(nodes);
  Eigen::VectorXd u(dofs), reaction(dofs);
  for (int pass = 1;; ++pass) {
    if (pass > kMaxPasses) throw std::runtime_error("axisymmetricPress: the contact's active set did not settle");
    result.activeSetPasses = pass;
    std::vector<char> prescribed = fixedDof;
    Eigen::VectorXd value = Eigen::VectorXd::Zero(dofs);
    for (int i = 0; i < nr; ++i) {
      if (!held[i]) continue;
      const int dof = 2 * node(i, nz - 1) + 1;
      prescribed[dof] = 1;
      value[dof] = -reach[i];
    }
    // K with the prescribed rows and columns replaced by the identity; their values moved right
    const Eigen::VectorXd lifted = K * value;
    std::vector<Eigen::Triplet<double>> reduced;
    reduced.reserve(static_cast<std::size_t>(K.nonZeros()));
    for (int c = 0; c < K.outerSize(); ++c)
      for (Eigen::SparseMatrix<double>::InnerIterator it(K, c); it; ++it)
        if (!prescribed[it.row()] && !prescribed[it.col()]) reduced.emplace_back(it.row(), it.col(), it.value());
    Eigen::VectorXd rhs(dofs);
    for (int k = 0; k < dofs; ++k) {
      if (prescribed[k]) {
        reduced.emplace_back(k, k, 1.0);
        rhs[k] = value[k];
      } else {
        rhs[k] = -lifted[k];
      }
    }
    Eigen::SparseMatrix<double> A(dofs, dofs);
    A.setFromTriplets(reduced.begin(), reduced.end());
    Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt(A);
    if (ldlt.info() != Eigen::Success) throw std::runtime_error("axisymmetricPress: factorization failed");
    u = ldlt.solve(rhs);
    reaction = K * u;

    bool changed = false;
    for (int i = 0; i < nr; ++i) {
      const int dof = 2 * node(i, nz - 1) + 1;
      if (held[i] && reaction[dof] > 0.0) {  // the surface would pull the body up
        held[i] = 0;
        changed = true;
      } else if (!held[i] && u[dof] > -reach[i] + 1e-12 * d) {  // the body crosses the surface
        held[i] = 1;
        changed = true;
      }
    }
    if (!changed) break;
  }
  for (int i = 0; i < nr; ++i) {
    if (!held[i]) continue;
    result.force -= reaction[2 * node(i, nz - 1) + 1];
    result.contactRadius = std::max(result.contactRadius, rs[i]);
  }
  return result;
}

}  // namespace deformable_flsm
