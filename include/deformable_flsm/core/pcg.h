/// @file pcg.h
/// Preconditioned conjugate gradients on a field of 3-vectors, with prescribed entries (filtered
/// CG, Baraff & Witkin 1998): the implicit step's linear solver.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace deformable_flsm {

struct PcgResult {
  int iterations = 0;
  /// ||r||_P at the end over the larger of ||r_0||_P and the floor (P the preconditioner)
  double relativeResidual = 0.0;
  bool converged = false;
  /// ||r_0||_P, the initial guess's filtered residual
  double initialResidual = 0.0;
};

/// How an entry of the unknown is constrained (PCG's filter S_i).
enum class PcgConstraint : char {
  /// free: S_i = 1
  Free = 0,
  /// prescribed: x_i keeps its value, S_i = 0
  Fixed = 1,
  /// component along a unit normal n_i prescribed, the rest free: S_i = 1 - n_i n_i^T
  Normal = 2,
};

/// Solves A x = b for a symmetric positive definite A given as a product y = A p, with a diagonal
/// (Jacobi) preconditioner, on the entries and directions the constraints leave free: the
/// residual, the preconditioned residual and the search directions are filtered by S (Baraff &
/// Witkin 1998's modified PCG), so the constrained parts of x keep the values they have on entry.
/// The unfiltered residual b - A x is kept as well (residual()): at the constrained entries it is
/// what the constraints must supply, and a caller that changes b only (not x) between two solves
/// can correct it (addToResidual()) and start the next solve without a product with A.
/// Buffers are sized by resize(), so that solve() allocates nothing. Dot products are summed in
/// chunks of fixed size, in order: the result does not depend on how the products are computed
/// in parallel.
class Pcg {
 public:
  /// Entries per chunk of a dot product.
  static constexpr std::size_t kChunk = 1024;

  void resize(std::size_t n) {
    residual_.assign(n, Eigen::Vector3d::Zero());
    r_.assign(n, Eigen::Vector3d::Zero());
    z_.assign(n, Eigen::Vector3d::Zero());
    p_.assign(n, Eigen::Vector3d::Zero());
    q_.assign(n, Eigen::Vector3d::Zero());
  }

  /// @param[in]     apply        apply(p, y): y = A p for #P vectors (y sized)
  /// @param[in]     invDiagonal  #P per-component inverse of the preconditioner's diagonal
  /// @param[in]     constraint   #P constraint of each entry
  /// @param[in]     normal       #P unit normals (read where the constraint is Normal)
  /// @param[in]     b            #P right-hand side
  /// @param[in,out] x            #P initial guess (prescribed values at fixed entries); solution
  /// @param[in]     floor        stop when ||r||_P <= floor ...
  /// @param[in]     tolerance    ... or ||r||_P <= tolerance ||r_0||_P (r_0 the initial guess's)
  /// @param[in]     maxIterations  at most this many products with A
  /// @param[in]     keepResidual   start from residual() as b - A x instead of computing it (x
  ///                               unchanged since the last solve, b changed only through
  ///                               addToResidual())
  template <class Apply>
  PcgResult solve(Apply&& apply, const std::vector<Eigen::Vector3d>& invDiagonal,
                  const std::vector<PcgConstraint>& constraint, const std::vector<Eigen::Vector3d>& normal,
                  const std::vector<Eigen::Vector3d>& b, std::vector<Eigen::Vector3d>& x, double floor,
                  double tolerance, int maxIterations, bool keepResidual = false) {
    const auto jacobi = [&invDiagonal](const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
      for (std::size_t i = 0; i < r.size(); ++i) z[i] = invDiagonal[i].cwiseProduct(r[i]);
    };
    return solveWith(apply, jacobi, constraint, normal, b, x, floor, tolerance, maxIterations, keepResidual);
  }

  /// As solve(), with a general symmetric positive definite preconditioner:
  /// precondition(r, z) sets z = P^-1 r for #P vectors (z sized, not aliasing r); the result is
  /// filtered, so PCG runs with S P^-1 S.
  template <class Apply, class Precondition>
  PcgResult solveWith(Apply&& apply, Precondition&& precondition, const std::vector<PcgConstraint>& constraint,
                      const std::vector<Eigen::Vector3d>& normal, const std::vector<Eigen::Vector3d>& b,
                      std::vector<Eigen::Vector3d>& x, double floor, double tolerance, int maxIterations,
                      bool keepResidual = false) {
    const auto filter = [&](std::size_t i, const Eigen::Vector3d& v) -> Eigen::Vector3d {
      switch (constraint[i]) {
        case PcgConstraint::Free: return v;
        case PcgConstraint::Fixed: return Eigen::Vector3d::Zero();
        case PcgConstraint::Normal: return v - normal[i].dot(v) * normal[i];
      }
      return v;
    };
    const std::size_t n = b.size();
    PcgResult result;
    if (!keepResidual) {
      apply(x, q_);
      for (std::size_t i = 0; i < n; ++i) residual_[i] = b[i] - q_[i];
    }
    for (std::size_t i = 0; i < n; ++i) r_[i] = filter(i, residual_[i]);
    precondition(r_, z_);
    for (std::size_t i = 0; i < n; ++i) {
      z_[i] = filter(i, z_[i]);
      p_[i] = z_[i];
    }
    double rz = dot(r_, z_);
    const double goal = std::max(tolerance * tolerance * rz, floor * floor);
    const double reference = std::sqrt(std::max(rz, floor * floor));
    result.initialResidual = std::sqrt(std::max(rz, 0.0));
    // the vectors' storage, held locally: the loops below then keep it in registers
    Eigen::Vector3d* const xv = x.data();
    Eigen::Vector3d* const res = residual_.data();
    Eigen::Vector3d* const rv = r_.data();
    Eigen::Vector3d* const zv = z_.data();
    Eigen::Vector3d* const pv = p_.data();
    const Eigen::Vector3d* const qv = q_.data();
    while (!(rz <= goal) && result.iterations < maxIterations) {
      apply(p_, q_);
      ++result.iterations;
      // p is filtered (S p = p, S an orthogonal projection), so p . A p = p . S A p
      const double pq = dot(p_, q_);
      if (!(pq > 0.0)) break;  // A not positive on p: round-off at convergence
      const double step = rz / pq;
      for (std::size_t i = 0; i < n; ++i) {
        xv[i] += step * pv[i];
        res[i] -= step * qv[i];
        rv[i] = filter(i, res[i]);
      }
      precondition(r_, z_);
      // z filtered and r . z in one pass (the chunks of dot())
      double rzNext = 0.0;
      for (std::size_t c = 0; c < n; c += kChunk) {
        const std::size_t end = std::min(n, c + kChunk);
        double partial = 0.0;
        for (std::size_t i = c; i < end; ++i) {
          zv[i] = filter(i, zv[i]);
          partial += rv[i].dot(zv[i]);
        }
        rzNext += partial;
      }
      const double beta = rzNext / rz;
      rz = rzNext;
      for (std::size_t i = 0; i < n; ++i) pv[i] = zv[i] + beta * pv[i];
    }
    result.relativeResidual = std::sqrt(std::max(0.0, rz)) / reference;
    result.converged = rz <= goal;
    return result;
  }

  /// b - A x at the end of the last solve (unfiltered; from the recurrence, not a product).
  const std::vector<Eigen::Vector3d>& residual() const { return residual_; }
  /// Keeps residual() consistent with a change d of b at entry i.
  void addToResidual(std::size_t i, const Eigen::Vector3d& d) { residual_[i] += d; }

  /// sum a_i . b_i in chunks of kChunk entries, added in order.
  static double dot(const std::vector<Eigen::Vector3d>& a, const std::vector<Eigen::Vector3d>& b) {
    double total = 0.0;
    for (std::size_t c = 0; c < a.size(); c += kChunk) {
      const std::size_t end = std::min(a.size(), c + kChunk);
      double partial = 0.0;
      for (std::size_t i = c; i < end; ++i) partial += a[i].dot(b[i]);
      total += partial;
    }
    return total;
  }

 private:
  std::vector<Eigen::Vector3d> residual_, r_, z_, p_, q_;
};

}  // namespace deformable_flsm
