/// @file mass_spring.h
/// The explicit mass-spring baseline of the study: springs between the FastLSM particles along
/// lattice links, face diagonals and body diagonals, advanced by symplectic Euler.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "study/method.h"
#include "study/metrics.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

/// A link between two particles of a lattice whose cells touch (26-neighbourhood).
struct LatticeLink {
  std::uint32_t a = 0, b = 0;
  /// rest length |x0_b - x0_a| (m): h, sqrt(2) h or sqrt(3) h
  double restLength = 0.0;
  /// min(fill_a, fill_b): the smaller inside fraction of the two cells (Voxelization::
  /// fillFraction, recovered as m / (rho h^3)), i.e. how much material the link stands for
  double fill = 1.0;
};

/// Every pair of particles whose cells share a face (lattice link), an edge (face diagonal) or a
/// corner (body diagonal), each pair once: of the 26 offsets around a cell, the 13 whose z
/// component, or y when z is 0, or x when both are 0, is positive.
/// @param[in] lattice  particles and cells
/// @return the links, ordered by first particle
inline std::vector<LatticeLink> latticeLinks(const Lattice& lattice) {
  std::vector<Eigen::Vector3i> offsets;
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        const Eigen::Vector3i d(dx, dy, dz);
        const int lead = dz != 0 ? dz : (dy != 0 ? dy : dx);
        if (lead > 0) offsets.push_back(d);
      }
  std::vector<LatticeLink> links;
  const auto& x0 = lattice.restPositions();
  // fill fraction = m / (rho h^3) = m / (largest mass), interior cells being full
  const double full = *std::max_element(lattice.masses().begin(), lattice.masses().end());
  std::vector<double> fill(lattice.size());
  for (std::size_t i = 0; i < lattice.size(); ++i) fill[i] = lattice.masses()[i] / full;
  for (std::size_t i = 0; i < lattice.size(); ++i)
    for (const Eigen::Vector3i& d : offsets) {
      const std::int32_t j = lattice.particleAt(lattice.cells()[i] + d);
      if (j == Lattice::kNone) continue;
      links.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j), (x0[j] - x0[i]).norm(),
                       std::min(fill[i], fill[j])});
    }
  return links;
}

struct MassSpringParams {
  /// kappa (N/m^2): a spring has stiffness k = kappa * spacing * fill (N/m), fill the smaller
  /// inside fraction of its two cells (LatticeLink::fill). Stiffness proportional to the
  /// spacing keeps the lattice's elastic modulus (~ k / h) the same at every resolution; the
  /// fill factor gives a sliver of a surface cell a spring as weak as its mass is small, so that
  /// it does not set the highest frequency of the lattice.
  double springModulus = 1.0;
  /// beta (s): a dashpot c = beta * k (N s/m) acts along every spring on the relative velocity
  /// (stiffness-proportional damping, rate beta omega^2 / 2 for a mode of frequency omega).
  double dashpotTime = 0.0;
  /// Rate (1/s) of drag towards rest in the world frame, v <- v exp(-rate h) per sub-step: the
  /// same ambient damping as SolverParams::ambientDamping.
  double ambientDamping = 0.5;
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  /// Frame step (s) and sub-steps per frame.
  double timeStep = 1.0 / 60.0;
  int substeps = 1;
};

/// Explicit mass-spring lattice: particle i has the mass of the FastLSM particle; the force of
/// the spring (a, b) on a is
///   f = fill (k (|d| - l0) + c (v_b - v_a) . n) n,  d = x_b - x_a,  n = d / |d|
/// and b feels -f. Symplectic (semi-implicit) Euler per sub-step h:
///   v <- v + h (f / m + g),  v <- v exp(-ambientDamping h),  x <- x + h v.
/// Stable only while h < 2 / omega_max, omega_max the highest frequency of the lattice
/// (maxFrequency()); beyond it the highest modes grow without bound.
class MassSpringLattice {
 public:
  MassSpringLattice(std::shared_ptr<const Lattice> lattice, const MassSpringParams& params)
      : lattice_(std::move(lattice)), params_(params), links_(latticeLinks(*lattice_)) {
    if (!(params_.springModulus > 0.0) || !(params_.dashpotTime >= 0.0) || !(params_.ambientDamping >= 0.0) ||
        !(params_.timeStep > 0.0) || params_.substeps < 1)
      throw std::invalid_argument("mass-spring: modulus, time step and sub-steps must be > 0, damping >= 0");
    const std::size_t n = lattice_->size();
    x_ = lattice_->restPositions();
    v_.assign(n, Eigen::Vector3d::Zero());
    f_.assign(n, Eigen::Vector3d::Zero());
    pinned_.assign(n, 0);
    pinPosition_ = x_;
  }

  const Lattice& lattice() const { return *lattice_; }
  const MassSpringParams& params() const { return params_; }
  const std::vector<LatticeLink>& links() const { return links_; }
  /// Stiffness of a spring between two full cells, k = kappa h (N/m).
  double springStiffness() const { return params_.springModulus * lattice_->spacing(); }

  /// Highest angular frequency (rad/s) of the linearised lattice at rest, free of pins:
  /// sqrt(largest eigenvalue of M^-1 K), by power iteration on M^-1/2 K M^-1/2.
  /// @param[in] iterations  power iterations (the estimate approaches from below)
  double maxFrequency(int iterations = 200) const {
    const std::size_t n = lattice_->size();
    const auto& m = lattice_->masses();
    const double k = springStiffness();
    const auto& x0 = lattice_->restPositions();
    std::vector<Eigen::Vector3d> u(n), Ku(n);
    for (std::size_t i = 0; i < n; ++i)  // a checkerboard start: close to the highest mode
      u[i] = Eigen::Vector3d(1.0, 0.7, 0.4) * ((lattice_->cells()[i].sum() % 2) ? 1.0 : -1.0) / std::sqrt(m[i]);
    double lambda = 0.0;
    for (int it = 0; it < iterations; ++it) {
      std::fill(Ku.begin(), Ku.end(), Eigen::Vector3d::Zero());
      for (const LatticeLink& l : links_) {
        const Eigen::Vector3d nrm = (x0[l.b] - x0[l.a]).normalized();
        const Eigen::Vector3d ua = u[l.a] / std::sqrt(m[l.a]), ub = u[l.b] / std::sqrt(m[l.b]);
        const Eigen::Vector3d f = k * l.fill * nrm.dot(ub - ua) * nrm;
        Ku[l.a] += f / std::sqrt(m[l.a]);
        Ku[l.b] -= f / std::sqrt(m[l.b]);
      }
      // K is positive semi-definite with the sign convention f_a = +k n n^T (u_b - u_a), i.e.
      // Ku holds -K u: flip it.
      double norm = 0.0, dot = 0.0;
      for (std::size_t i = 0; i < n; ++i) {
        dot -= Ku[i].dot(u[i]);
        norm += Ku[i].squaredNorm();
      }
      double unorm = 0.0;
      for (const auto& ui : u) unorm += ui.squaredNorm();
      lambda = dot / unorm;
      norm = std::sqrt(norm);
      if (!(norm > 0.0)) break;
      for (std::size_t i = 0; i < n; ++i) u[i] = -Ku[i] / norm;
    }
    return std::sqrt(std::max(0.0, lambda));
  }

  void step() {
    const double h = params_.timeStep / params_.substeps;
    grabImpulse_.setZero();
    for (int s = 0; s < params_.substeps; ++s) substep(h);
    grabForce_ = grabImpulse_ / params_.timeStep;
  }
  /// The force (N) the grab exerted over the last step: the impulse that put the grabbed
  /// particles on their targets, m (v / keep - v_n - h a) summed (the update damps the new
  /// velocity, v = keep (v_n + h a)), over the step's time.
  const Eigen::Vector3d& grabForce() const { return grabForce_; }

  const std::vector<Eigen::Vector3d>& positions() const { return x_; }
  const std::vector<Eigen::Vector3d>& velocities() const { return v_; }
  void setPositions(const std::vector<Eigen::Vector3d>& x) {
    if (x.size() != x_.size()) throw std::invalid_argument("mass-spring: setPositions with the wrong size");
    x_ = x;
    std::fill(v_.begin(), v_.end(), Eigen::Vector3d::Zero());
  }
  void setPinned(std::uint32_t p, bool pinned) {
    if (pinned && !pinned_[p]) {
      pinPosition_[p] = x_[p];
      v_[p].setZero();
    }
    pinned_[p] = pinned ? 1 : 0;
  }
  /// Kinematic grab: the particles' centroid follows `target` with their present arrangement.
  void grab(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target) {
    grabbed_ = particles;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (std::uint32_t p : particles) c += x_[p];
    c /= static_cast<double>(particles.size());
    grabOffsets_.clear();
    for (std::uint32_t p : particles) grabOffsets_.push_back(x_[p] - c);
    grabTarget_ = target;
  }
  void moveGrab(const Eigen::Vector3d& target) { grabTarget_ = target; }
  void release() {
    grabbed_.clear();
    grabOffsets_.clear();
  }
  double kineticEnergy() const {
    const auto& m = lattice_->masses();
    double e = 0.0;
    for (std::size_t i = 0; i < v_.size(); ++i) e += 0.5 * m[i] * v_[i].squaredNorm();
    return e;
  }

 private:
  /// Lengths below this fraction of the spacing have no direction: such a spring (particles
  /// collapsed onto each other) exerts no force for that sub-step instead of producing NaN.
  static constexpr double kMinLengthFraction = 1e-12;

  void substep(double h) {
    const auto& m = lattice_->masses();
    const double k = springStiffness();
    const double c = params_.dashpotTime * k;
    const double minLength = kMinLengthFraction * lattice_->spacing();
    std::fill(f_.begin(), f_.end(), Eigen::Vector3d::Zero());
    for (const LatticeLink& l : links_) {
      const Eigen::Vector3d d = x_[l.b] - x_[l.a];
      const double len = d.norm();
      if (!(len > minLength)) continue;
      const Eigen::Vector3d nrm = d / len;
      const Eigen::Vector3d f = l.fill * (k * (len - l.restLength) + c * nrm.dot(v_[l.b] - v_[l.a])) * nrm;
      f_[l.a] += f;
      f_[l.b] -= f;
    }
    const std::size_t n = x_.size();
    const double keep = std::exp(-params_.ambientDamping * h);
    for (std::size_t i = 0; i < n; ++i) v_[i] = keep * (v_[i] + h * (f_[i] / m[i] + params_.gravity));
    for (std::size_t e = 0; e < grabbed_.size(); ++e) {
      const std::uint32_t p = grabbed_[e];
      const Eigen::Vector3d free = v_[p];
      v_[p] = (grabTarget_ + grabOffsets_[e] - x_[p]) / h;
      if (!pinned_[p]) grabImpulse_ += m[p] * (v_[p] - free) / keep;
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (pinned_[i]) {
        v_[i].setZero();
        x_[i] = pinPosition_[i];
      } else {
        x_[i] += h * v_[i];
      }
    }
  }

  std::shared_ptr<const Lattice> lattice_;
  MassSpringParams params_;
  std::vector<LatticeLink> links_;
  std::vector<Eigen::Vector3d> x_, v_, f_;
  std::vector<char> pinned_;
  std::vector<Eigen::Vector3d> pinPosition_;
  std::vector<std::uint32_t> grabbed_;
  std::vector<Eigen::Vector3d> grabOffsets_;
  Eigen::Vector3d grabTarget_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d grabImpulse_ = Eigen::Vector3d::Zero(), grabForce_ = Eigen::Vector3d::Zero();
};

/// The mass-spring lattice behind the study's Method interface.
class MassSpringMethod : public Method {
 public:
  MassSpringMethod(std::shared_ptr<const Lattice> lattice, const MassSpringParams& params)
      : sim_(std::move(lattice), params) {}

  std::string name() const override { return "mass-spring"; }
  int substeps() const override { return sim_.params().substeps; }
  void step() override { sim_.step(); }
  const std::vector<Eigen::Vector3d>& positions() const override { return sim_.positions(); }
  void setPositions(const std::vector<Eigen::Vector3d>& x) override { sim_.setPositions(x); }
  void setPinned(const std::vector<std::uint32_t>& particles, bool pinned) override {
    for (std::uint32_t p : particles) sim_.setPinned(p, pinned);
  }
  void grab(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target) override {
    sim_.grab(particles, target);
  }
  void moveGrab(const Eigen::Vector3d& target) override { sim_.moveGrab(target); }
  void release() override { sim_.release(); }
  Eigen::Vector3d grabForce() const override { return sim_.grabForce(); }
  double kineticEnergy() const override { return sim_.kineticEnergy(); }
  void rotations(std::vector<Eigen::Quaterniond>& out) const override {
    neighbourhoodRotations(sim_.lattice(), sim_.positions(), warm_);
    out = warm_;
  }

  const MassSpringLattice& simulator() const { return sim_; }

 private:
  MassSpringLattice sim_;
  mutable std::vector<Eigen::Quaterniond> warm_;
};

}  // namespace study
}  // namespace deformable_flsm
