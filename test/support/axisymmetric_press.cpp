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
constexpr double kPi = 3.14159265358979323846;

using SparseMatrix = Eigen::SparseMatrix<double>;

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

void validate(const AxisymmetricPress& p) {
  p.material.validate();
  const double R = p.indenterRadius, d = p.depth;
  check(std::isfinite(R) && R > 0.0, "indenterRadius must be > 0");
  check(std::isfinite(d) && d > 0.0 && d < R, "depth must be in (0, indenterRadius)");
  check(std::isfinite(p.thickness) && p.thickness > 0.0, "thickness must be > 0");
  check(std::isfinite(p.outerRadius) && p.outerRadius > std::sqrt(R * d),
        "outerRadius must exceed the contact radius sqrt(R d)");
  check(std::isfinite(p.finestFraction) && p.finestFraction > 0.0 && p.finestFraction <= 0.5,
        "finestFraction must be in (0, 0.5]");
}

/// The (r, z) grid: node (i, j) at (rs[i], zs[j]), zs[0] = 0 the base, zs.back() the top.
struct Mesh {
  std::vector<double> rs, zs;
  int nr() const { return static_cast<int>(rs.size()); }
  int nz() const { return static_cast<int>(zs.size()); }
  int node(int i, int j) const { return j * nr() + i; }
  /// degree of freedom of node (i, j)'s axis 0 (r) or 1 (z)
  int dof(int i, int j, int axis) const { return 2 * node(i, j) + axis; }
  int dofs() const { return 2 * nr() * nz(); }
};

Mesh gradedMesh(const AxisymmetricPress& p) {
  const double a = std::sqrt(p.indenterRadius * p.depth);
  const double fine = p.finestFraction * a, coarse = kCoarsestFraction * p.thickness;
  Mesh m;
  m.rs = graded(p.outerRadius, fine, kFineRadial * a, coarse);
  m.zs = graded(p.thickness, fine, kFineDepth * a, coarse);
  for (double& z : m.zs) z = p.thickness - z;
  std::reverse(m.zs.begin(), m.zs.end());
  return m;
}

/// Stiffness of the rectangle [r0, r0 + hr] x [z0, z0 + hz] (nodes counter-clockwise from
/// (r0, z0), dofs (r, z) per node): sum over 2 x 2 Gauss points of B^T D B 2 pi r |J|, the
/// strains (rr, zz, theta theta = u_r / r, rz) with engineering shear.
Eigen::Matrix<double, 8, 8> ringStiffness(double r0, double hr, double hz, const Eigen::Matrix4d& D) {
  const double g = 1.0 / std::sqrt(3.0);
  Eigen::Matrix<double, 8, 8> K = Eigen::Matrix<double, 8, 8>::Zero();
  for (int gp = 0; gp < 4; ++gp) {
    const double xi = (gp & 1) ? g : -g, eta = (gp & 2) ? g : -g;
    const double N[4] = {0.25 * (1 - xi) * (1 - eta), 0.25 * (1 + xi) * (1 - eta), 0.25 * (1 + xi) * (1 + eta),
                         0.25 * (1 - xi) * (1 + eta)};
    const double dxi[4] = {-0.25 * (1 - eta), 0.25 * (1 - eta), 0.25 * (1 + eta), -0.25 * (1 + eta)};
    const double deta[4] = {-0.25 * (1 - xi), -0.25 * (1 + xi), 0.25 * (1 + xi), 0.25 * (1 - xi)};
    const double r = r0 + 0.5 * (1 + xi) * hr;  // a rectangle: the map is affine
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
    K += B.transpose().lazyProduct(DB) * (2.0 * kPi * r * 0.25 * hr * hz);
  }
  return K;
}

SparseMatrix stiffness(const Mesh& m, const FemMaterial& material) {
  const double lambda = material.lameLambda(), mu = material.shearModulus();
  Eigen::Matrix4d D = Eigen::Matrix4d::Zero();
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) D(i, j) = lambda;
    D(i, i) = lambda + 2.0 * mu;
  }
  D(3, 3) = mu;
  std::vector<Eigen::Triplet<double>> triplets;
  triplets.reserve(static_cast<std::size_t>(64) * (m.nr() - 1) * (m.nz() - 1));
  for (int j = 0; j + 1 < m.nz(); ++j) {
    for (int i = 0; i + 1 < m.nr(); ++i) {
      const int n[4] = {m.node(i, j), m.node(i + 1, j), m.node(i + 1, j + 1), m.node(i, j + 1)};
      const Eigen::Matrix<double, 8, 8> K = ringStiffness(m.rs[i], m.rs[i + 1] - m.rs[i], m.zs[j + 1] - m.zs[j], D);
      for (int a = 0; a < 8; ++a)
        for (int b = 0; b < 8; ++b) triplets.emplace_back(2 * n[a / 2] + a % 2, 2 * n[b / 2] + b % 2, K(a, b));
    }
  }
  SparseMatrix K(m.dofs(), m.dofs());
  K.setFromTriplets(triplets.begin(), triplets.end());
  return K;
}

/// K u = 0 on the free degrees of freedom with u = value on the prescribed ones: K with the
/// prescribed rows and columns replaced by the identity, their values moved to the right.
Eigen::VectorXd solvePrescribed(const SparseMatrix& K, const std::vector<char>& prescribed,
                                const Eigen::VectorXd& value) {
  const Eigen::Index n = K.rows();
  const Eigen::VectorXd lifted = K * value;
  std::vector<Eigen::Triplet<double>> reduced;
  reduced.reserve(static_cast<std::size_t>(K.nonZeros()));
  for (int c = 0; c < K.outerSize(); ++c)
    for (SparseMatrix::InnerIterator it(K, c); it; ++it)
      if (!prescribed[it.row()] && !prescribed[it.col()]) reduced.emplace_back(it.row(), it.col(), it.value());
  Eigen::VectorXd rhs(n);
  for (Eigen::Index k = 0; k < n; ++k) {
    if (prescribed[k]) reduced.emplace_back(k, k, 1.0);
    rhs[k] = prescribed[k] ? value[k] : -lifted[k];
  }
  SparseMatrix A(n, n);
  A.setFromTriplets(reduced.begin(), reduced.end());
  Eigen::SimplicialLDLT<SparseMatrix> ldlt(A);
  if (ldlt.info() != Eigen::Success) throw std::runtime_error("axisymmetricPress: factorization failed");
  return ldlt.solve(rhs);
}

}  // namespace

AxisymmetricPressResult axisymmetricPress(const AxisymmetricPress& p) {
  validate(p);
  const double R = p.indenterRadius, d = p.depth;
  const Mesh m = gradedMesh(p);
  const SparseMatrix K = stiffness(m, p.material);
  const int top = m.nz() - 1;

  // how far the indenter's surface reaches below the top face at each top node (m; > 0 presses)
  std::vector<double> reach(m.nr());
  for (int i = 0; i < m.nr(); ++i) {
    const double r = m.rs[i];
    const double rise = p.paraboloid ? r * r / (2.0 * R) : (r < R ? R - std::sqrt(R * R - r * r) : R + r);
    reach[i] = d - rise;
  }
  std::vector<char> supported(m.dofs(), 0);
  for (int i = 0; i < m.nr(); ++i) supported[m.dof(i, 0, 0)] = supported[m.dof(i, 0, 1)] = 1;  // the base
  for (int j = 0; j < m.nz(); ++j) supported[m.dof(0, j, 0)] = 1;  // u_r = 0 on the axis
  std::vector<char> held(m.nr(), 0);
  for (int i = 0; i < m.nr(); ++i) held[i] = reach[i] > 0.0;

  AxisymmetricPressResult result;
  result.nodes = static_cast<std::size_t>(m.nr()) * m.nz();
  Eigen::VectorXd reaction;
  for (bool changed = true; changed;) {
    if (++result.activeSetPasses > kMaxPasses)
      throw std::runtime_error("axisymmetricPress: the contact's active set did not settle");
    std::vector<char> prescribed = supported;
    Eigen::VectorXd value = Eigen::VectorXd::Zero(m.dofs());
    for (int i = 0; i < m.nr(); ++i) {
      if (!held[i]) continue;
      prescribed[m.dof(i, top, 1)] = 1;
      value[m.dof(i, top, 1)] = -reach[i];
    }
    const Eigen::VectorXd u = solvePrescribed(K, prescribed, value);
    reaction = K * u;
    changed = false;
    for (int i = 0; i < m.nr(); ++i) {
      const int dof = m.dof(i, top, 1);
      const bool pulls = held[i] && reaction[dof] > 0.0;                  // would pull the body up
      const bool crosses = !held[i] && u[dof] > -reach[i] + 1e-12 * d;  // the body crosses the surface
      if (pulls || crosses) {
        held[i] = !held[i];
        changed = true;
      }
    }
  }
  for (int i = 0; i < m.nr(); ++i) {
    if (!held[i]) continue;
    result.force -= reaction[m.dof(i, top, 1)];
    result.contactRadius = std::max(result.contactRadius, m.rs[i]);
  }
  return result;
}

}  // namespace deformable_flsm
