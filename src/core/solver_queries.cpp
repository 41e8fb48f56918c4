// What an observer reads off the solver's state: the particles near a point, the kinetic energy,
// the momenta, the largest displacement from rest, the best-fit rigid frame and the shape error
// about it.
#include "deformable_flsm/core/polar.h"
#include "deformable_flsm/core/solver.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace deformable_flsm {

std::vector<std::uint32_t> Solver::nearestParticles(const Eigen::Vector3d& point, std::size_t count) const {
  std::vector<std::uint32_t> idx(x_.size());
  std::iota(idx.begin(), idx.end(), 0u);
  count = std::min(count, idx.size());
  auto closer = [&](std::uint32_t a, std::uint32_t b) {
    return (x_[a] - point).squaredNorm() < (x_[b] - point).squaredNorm();
  };
  std::partial_sort(idx.begin(), idx.begin() + static_cast<std::ptrdiff_t>(count), idx.end(), closer);
  idx.resize(count);
  return idx;
}

std::vector<std::uint32_t> Solver::particlesWithin(const Eigen::Vector3d& point, double radius) const {
  std::vector<std::uint32_t> out;
  const double r2 = radius * radius;
  for (std::size_t i = 0; i < x_.size(); ++i)
    if ((x_[i] - point).squaredNorm() <= r2) out.push_back(static_cast<std::uint32_t>(i));
  return out;
}

double Solver::kineticEnergy() const {
  const auto& m = lattice_->masses();
  double e = 0.0;
  for (std::size_t i = 0; i < v_.size(); ++i) e += 0.5 * m[i] * v_[i].squaredNorm();
  return e;
}

Eigen::Vector3d Solver::linearMomentum() const {
  const auto& m = lattice_->masses();
  Eigen::Vector3d P = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < v_.size(); ++i) P += m[i] * v_[i];
  return P;
}

Eigen::Vector3d Solver::angularMomentum() const {
  const auto& m = lattice_->masses();
  Eigen::Vector3d L = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < v_.size(); ++i) L += m[i] * x_[i].cross(v_[i]);
  return L;
}

double Solver::maxDisplacement() const {
  const auto& x0 = lattice_->restPositions();
  double d = 0.0;
  for (std::size_t i = 0; i < x_.size(); ++i) d = std::max(d, (x_[i] - x0[i]).squaredNorm());
  return std::sqrt(d);
}

Eigen::Isometry3d Solver::rigidFrame() const {
  const auto& m = lattice_->masses();
  Eigen::Vector3d c = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < x_.size(); ++i) c += m[i] * x_[i];
  c /= lattice_->totalMass();
  Eigen::Matrix3d A = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < x_.size(); ++i) A.noalias() += m[i] * (x_[i] - c) * restCentered_[i].transpose();
  const Eigen::Matrix3d R = extractRotation(A, frameRotation_);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = c - R * restCom_;
  return T;
}

double Solver::shapeError() const {
  const Eigen::Isometry3d T = rigidFrame();
  const auto& x0 = lattice_->restPositions();
  double e = 0.0;
  for (std::size_t i = 0; i < x_.size(); ++i) e += (x_[i] - T * x0[i]).squaredNorm();
  return std::sqrt(e / static_cast<double>(x_.size()));
}

}  // namespace deformable_flsm
