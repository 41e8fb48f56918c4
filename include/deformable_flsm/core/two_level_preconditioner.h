/// @file two_level_preconditioner.h
/// The implicit step's preconditioner: Jacobi on the particles plus an exact solve on aggregates of
/// lattice cells (a two-level additive Schwarz method on the regular grid).
#pragma once

#include "deformable_flsm/core/corotated_hessian.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/region_summer.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

/// M^-1 = D^-1 + P A_c^-1 P^T with A_c = P^T A P (Galerkin), for the implicit step's matrix
/// A = D_m + sum_r c_r K_r + H_vol (CorotatedHessian, the Poisson term's Hessian). Aggregate a, the
/// free particles of an s x s x s block of lattice cells, moves rigidly to first order: six
/// unknowns, a translation u_a and a small rotation w_a about its rest centre c_a, turned with the
/// aggregate (R_a, the rotation of the region at the particle nearest c_a):
///   p_i = u_a + w_a x y_i = P_i [u_a; w_a],   P_i = [1, -[y_i]x],   y_i = R_a (q_i - c_a),
/// the rigid modes of smoothed aggregation (Vanek, Mandel & Brezina 1996) without the smoothing.
/// Jacobi alone propagates a correction by one region per iteration, so its iterations grow with
/// the lattice and with the stiffness over the mass; the aggregates carry the long-wave part of
/// the error in one solve, bending included (bending is rotation of the regions, which
/// translations alone represent only as shear between aggregates). Additive two-level Schwarz
/// (Toselli & Widlund 2005, ch. 2): M is symmetric positive definite whatever A_c is, as long as
/// A_c is, so PCG stays valid.
///
/// A_c is assembled from the region structure without a product with A. With s >= 2w every region
/// meets at most two aggregates per axis, told apart by the parity of their index, so one gather
/// of eight parity classes gives, per region r and aggregate a, the rest moments of their free
/// particles m_ra = sum m~, f_ra = sum m~ q, S_ra = sum m~ q q^T (constant while the fixed set
/// is). From them, per (r, a):
///   G_ra = sum m~ P_i^T P_i = [m 1, -[Y]x; [Y]x, tr(Q) 1 - Q],   T_ra = sum m~ P_i = [m 1, -[Y]x],
///   L_ra = sum m~ [q~_i]x P_i = [[R_r (f - m c0_r)]x, tr(X) 1 - X],
/// Y = R_a (f - m c_a), Q = R_a sum m~ (q - c_a)(q - c_a)^T R_a^T, X = R_a sum m~ (q - c_a)(q - c0_r)^T R_r^T,
/// and K_r = M~ - M~ B (B^T M~ B)^-1 B^T M~ (CorotatedHessian) gives the block (a, b)
///   c_r [ delta_ab G_ra - T_ra^T T_rb / M_r - L_ra^T J_r L_rb ],   J_r = R_r I0_r^+ R_r^T.
/// An aggregate whose free particles are collinear (or one) keeps its translation only. A_c is
/// dense (at most maxAggregates aggregates, 6 unknowns each) and factorised by Cholesky once per
/// sub-step.
class TwoLevelPreconditioner {
 public:
  /// @param[in] lattice           the lattice (cells, region half-width w)
  /// @param[in] massFractions     #P m~_i (kg)
  /// @param[in] restCentered      #P q_i = x0_i - rest centre of mass (m)
  /// @param[in] regionMass        #P M_r (kg)
  /// @param[in] regionRestCenter  #P c0_r, in the frame of restCentered (m)
  /// @param[in] maxAggregates     the aggregate edge s starts at max(2, 2w) cells and grows until
  ///                              at most this many aggregates hold particles
  TwoLevelPreconditioner(const Lattice& lattice, const std::vector<double>& massFractions,
                         const std::vector<Eigen::Vector3d>& restCentered, const std::vector<double>& regionMass,
                         const std::vector<Eigen::Vector3d>& regionRestCenter, int maxAggregates);

  /// Aggregate edge s (cells).
  int aggregateSize() const { return s_; }
  /// Aggregates holding at least one particle.
  std::size_t aggregates() const { return static_cast<std::size_t>(count_); }
  /// Aggregate of particle i, or -1 while i is fixed.
  int aggregateOf(std::size_t i) const { return fixed_[i] != 0 ? -1 : aggregate_[i]; }
  /// Unknowns per aggregate: translation (x y z), then rotation (x y z).
  static constexpr int kModes = 6;
  /// P_i (3 x 6): particle i's velocity per unit of its aggregate's unknowns (at the rotations of
  /// the last beginAssembly()); zero while i is fixed, and in the rotation columns while its
  /// aggregate moves by translation only.
  Eigen::Matrix<double, 3, kModes> prolongation(std::size_t i) const;

  /// The particles whose velocity is prescribed for the whole sub-step (pinned, hard-dragged)
  /// leave the coarse space; the region moments are gathered again (one pass of `summer`, which
  /// allocates) only when this set differs from the last one.
  /// @param[in] pinned       #P nonzero where pinned
  /// @param[in] hardDragged  #P nonzero where hard-dragged
  void setFixed(RegionSummer& summer, const std::vector<char>& pinned, const std::vector<char>& hardDragged);

  /// Whether A_c should be assembled again: never assembled, the fixed set changed, the diagonal
  /// or a region coefficient differs from the last assembly's, an aggregate's rotation turned by
  /// more than `maxTurn` (rad) since, or `maxAge` calls passed. The last factorisation is a valid
  /// preconditioner (symmetric positive definite) whatever A has become, only a less exact one, so
  /// A_c is kept while A changes little: at rest, or while the object moves without turning.
  bool needsAssembly(const std::vector<Eigen::Vector3d>& diagonal, const CorotatedHessian& hessian, double maxTurn,
                     int maxAge);
  /// Turns the aggregates with `hessian`'s region rotations and starts A_c with P^T D P.
  /// @param[in] diagonal  #P per-component diagonal of A outside the regions' stiffness (kg)
  void beginAssembly(const std::vector<Eigen::Vector3d>& diagonal, const CorotatedHessian& hessian);
  /// Adds P^T (sum_r c_r K_r) P, with K's coefficients and rotations as last set (the same as
  /// beginAssembly() saw).
  void addRegions(const CorotatedHessian& hessian);
  /// Adds P^T (weight v v^T) P for v = sum_k e_{particles[k]} (x) g[k] (a rank-one term of A
  /// between up to 8 particles).
  void addOuter(const std::uint32_t* particles, const Eigen::Vector3d* g, int count, double weight);
  /// Adds P^T of the term k |p_i - p_j|^2 / 2 (k 1 on the pair i, j).
  void addEdge(std::uint32_t i, std::uint32_t j, double k);
  /// Factorises A_c; false (and apply() is Jacobi alone) if it is not numerically positive
  /// definite.
  bool factorize();

  /// A_c as last assembled (kModes rows per aggregate), before factorize() decouples the
  /// unknowns without particles (aggregates of fixed particles only, rotations of collinear ones).
  const Eigen::MatrixXd& coarseMatrix() const { return coarse_; }

  /// z = D^-1 r + P A_c^-1 P^T r.
  /// @param[in]  invDiagonal  #P per-component inverse of the Jacobi diagonal
  /// @param[in]  r            #P residual (filtered: zero where fixed)
  /// @param[out] z            #P, sized by the caller
  void apply(const std::vector<Eigen::Vector3d>& invDiagonal, const std::vector<Eigen::Vector3d>& r,
             std::vector<Eigen::Vector3d>& z);

 private:
  /// A region meets at most 2 aggregates per axis.
  static constexpr int kPerRegion = 8;
  using Block = Eigen::Matrix<double, kModes, kModes>;
  using Columns = Eigen::Matrix<double, 3, kModes>;
  void gatherMoments(RegionSummer& summer);
  void addBlock(int a, int b, const Block& block) {
    coarse_.block<kModes, kModes>(kModes * a, kModes * b) += block;
  }

  const std::vector<double>& massFractions_;
  const std::vector<Eigen::Vector3d>& restCentered_;
  const std::vector<double>& regionMass_;
  const std::vector<Eigen::Vector3d>& regionRestCenter_;
  int s_ = 2;
  int count_ = 0;
  std::vector<int> aggregate_;          // per particle
  std::vector<char> parity_;            // per particle: bit a = parity of its aggregate index on axis a
  std::vector<int> regionAggregate_;    // per region, kPerRegion: the aggregate of each parity class
  std::vector<double> regionAggMass_;   // m_ra
  std::vector<Eigen::Vector3d> regionAggMoment_;  // f_ra
  std::vector<Eigen::Matrix3d> regionAggSecond_;  // S_ra
  std::vector<Eigen::Vector3d> center_;           // per aggregate: c_a (rest, frame of q)
  std::vector<int> representative_;               // per aggregate: the region whose rotation it takes
  std::vector<char> rotates_;                     // per aggregate: its rotation unknowns are used
  std::vector<Eigen::Matrix3d> aggregateRotation_;  // R_a
  std::vector<Eigen::Vector3d> offset_;           // per particle: y_i
  std::vector<char> fixed_;
  bool gathered_ = false;
  bool fixedChanged_ = true;
  int age_ = 0;
  std::vector<Eigen::Vector3d> assembledDiagonal_;
  std::vector<double> assembledCoefficient_;
  bool factorized_ = false;
  std::vector<double> gatherIn_, gatherOut_;
  Eigen::MatrixXd coarse_;
  Eigen::LLT<Eigen::MatrixXd> llt_;
  Eigen::VectorXd coarseRhs_;
};

}  // namespace deformable_flsm
