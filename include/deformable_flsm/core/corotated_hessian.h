/// @file corotated_hessian.h
/// The product of FastLSM's co-rotated region stiffness with a vector, as one region pass
/// (RegionKernel): the matrix of the implicit step's linear system without assembling it.
#pragma once

#include "deformable_flsm/core/region_summer.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstddef>
#include <vector>

namespace deformable_flsm {

/// y = D p + sum_r c_r K_r p, where K_r is region r's shape-matching stiffness with its rigid
/// motions projected out, co-rotated by the region's rotation R_r:
///   (K_r p)_i = m~_i (p_i - t_r - theta_r x q~_i),   i in region r,   q~_i = R_r (x0_i - c0_r),
/// (t_r, theta_r) the m~-weighted best rigid motion of p over the region:
///   t_r = sum m~ p / M_r,   theta_r = (R_r I0_r R_r^T)^+ sum m~ q~ x p,
/// I0_r the region's rest inertia about c0_r. K_r = M~ - M~ B (B^T M~ B)^-1 B^T M~ with B the
/// region's six rigid modes (co-rotated): symmetric positive semi-definite, zero on rigid motions,
/// the Hessian of the region energy m~/2 |T x0 - x|^2 with the rotation free (Rivers & James 2007's
/// energy linearised about the current rotation). Every sum is a window sum: gather m~ p (3) and
/// m~ p q^T (9), with q the rest positions relative to the rest centre of mass, then
///   sum m~ q~ x p = vec(A) - (R c0) x sum m~ p,   A = (sum m~ p q^T) R^T,
///   vec(A) = (A_zy - A_yz, A_xz - A_zx, A_yx - A_xy);
/// scatter c_r [theta_r]x R_r (9) and c_r (t_r - theta_r x R_r c0_r) (3). O(1) per particle
/// whatever the region half-width, like the region pass.
class CorotatedHessian : public RegionKernel {
 public:
  /// Rest data of the lattice; precomputes every region's rest inertia (one gather on `summer`).
  /// @param[in] massFractions     #P m~_i (kg)
  /// @param[in] restCentered      #P q_i = x0_i - rest centre of mass (m)
  /// @param[in] regionMass        #P M_r (kg)
  /// @param[in] regionRestCenter  #P c0_r, in the frame of restCentered (m)
  CorotatedHessian(RegionSummer& summer, const std::vector<double>& massFractions,
                   const std::vector<Eigen::Vector3d>& restCentered, const std::vector<double>& regionMass,
                   const std::vector<Eigen::Vector3d>& regionRestCenter);

  /// The linearisation point: region rotations R_r (#P).
  void setRotations(const std::vector<Eigen::Quaterniond>& rotations);
  /// Region coefficients c_r = a beta_r + b and their per-particle sums
  /// sum_{r contains i} c_r = a weightSum_i + b n_i.
  /// @param[in] beta       #P region weights beta_r
  /// @param[in] weightSum  #P sum_{r contains i} beta_r
  /// @param[in] invCount   #P 1 / n_i
  void setCoefficients(double a, double b, const std::vector<double>& beta, const std::vector<double>& weightSum,
                       const std::vector<double>& invCount);
  /// y = D p + sum_r c_r K_r p in one region pass of `summer`.
  /// @param[in]  diagonal  #P per-component diagonal D (kg)
  /// @param[in]  p         #P vector (m/s)
  /// @param[out] y         #P result (kg m/s), sized by the caller; must not alias p
  void apply(RegionSummer& summer, const std::vector<Eigen::Vector3d>& diagonal,
             const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y);
  /// sum_{r contains i} c_r m~_i: the diagonal of sum_r c_r K_r without its projection part, an
  /// upper bound of that diagonal (for a Jacobi preconditioner).
  double diagonalBound(std::size_t i) const { return coefficientSum_[i] * massFractions_[i]; }
  /// Region r's coefficient c_r, rotation R_r and rotated inverse rest inertia R_r I0_r^+ R_r^T
  /// (as last set): what an assembly of P^T K P needs (TwoLevelPreconditioner).
  double regionCoefficient(std::size_t r) const { return coefficient_[r]; }
  const Eigen::Matrix3d& regionRotation(std::size_t r) const { return rotation_[r]; }
  Eigen::Matrix3d rotatedInertiaInverse(std::size_t r) const {
    const std::array<double, 6>& J = rotatedInertiaInverse_[r];
    Eigen::Matrix3d M;
    M << J[0], J[3], J[4], J[3], J[1], J[5], J[4], J[5], J[2];
    return M;
  }

  int gatherChannels() const override { return 12; }
  int scatterChannels() const override { return 12; }
  void particleData(std::size_t begin, std::size_t end, double* out) override;
  void regionData(std::size_t begin, std::size_t end, const double* sums, double* out) override;
  void particleResult(std::size_t begin, std::size_t end, const double* sums) override;

 private:
  const std::vector<double>& massFractions_;
  const std::vector<Eigen::Vector3d>& restCentered_;
  const std::vector<double>& regionMass_;
  const std::vector<Eigen::Vector3d>& regionRestCenter_;
  std::vector<Eigen::Matrix3d> restInertiaInverse_;  // (I0_r)^+, about c0_r
  std::vector<Eigen::Matrix3d> rotation_;            // R_r
  std::vector<Eigen::Vector3d> rotatedCenter_;       // R_r c0_r
  std::vector<std::array<double, 6>> rotatedInertiaInverse_;  // R_r I0_r^+ R_r^T: xx yy zz xy xz yz
  std::vector<double> coefficient_;                  // c_r
  std::vector<double> coefficientPerMass_;           // c_r / M_r
  std::vector<double> coefficientSum_;               // sum_{r contains i} c_r
  const std::vector<Eigen::Vector3d>* diagonal_ = nullptr;
  const std::vector<Eigen::Vector3d>* input_ = nullptr;
  std::vector<Eigen::Vector3d>* output_ = nullptr;
};

}  // namespace deformable_flsm
