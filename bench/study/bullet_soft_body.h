/// @file bullet_soft_body.h
/// Bullet's soft body (btSoftBody, position-based link constraints) on the FastLSM particles, as
/// the study's external peer. Needs Bullet (libbullet-dev: BulletSoftBody, BulletDynamics,
/// BulletCollision, LinearMath); include only where it is linked.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "study/mass_spring.h"
#include "study/method.h"
#include "study/metrics.h"

#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>

#include <Eigen/Core>

#include <cmath>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

struct BulletParams {
  /// Material linear stiffness kLST in (0, 1]: the fraction of a link's length error that one
  /// position iteration removes (Bullet's btSoftBody::Material::m_kLST).
  double linearStiffness = 1.0;
  /// Position-solver iterations per sub-step (btSoftBody::Config::piterations).
  int positionIterations = 4;
  /// Rate (1/s) of drag towards rest, as SolverParams::ambientDamping: Bullet's kDP = 1 -
  /// exp(-rate h) (btSoftBody::Config::kDP scales every velocity by 1 - kDP per sub-step).
  double ambientDamping = 0.5;
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  /// Frame step (s) and sub-steps per frame.
  double timeStep = 1.0 / 60.0;
  int substeps = 1;
};

/// btSoftBody with one node per lattice particle (same masses) and one link per pair of touching
/// cells (latticeLinks(): lattice links, face and body diagonals), advanced per sub-step by the
/// sequence Bullet's default soft-body solver runs for each body: predictMotion() (gravity and
/// explicit velocity integration), solveConstraints() (piterations Gauss-Seidel sweeps over the
/// links, then v = (x - x_old) / h (1 - kDP)), integrateMotion(). No collision world: no
/// scenario has contacts. Bullet works in single precision (btScalar = float) as packaged.
///
/// Pins and grabs make nodes kinematic (inverse mass 0), written directly into the node rather
/// than through btSoftBody::setMass(), which would also re-take the rest lengths of all links
/// from the current, deformed positions.
class BulletSoftBodyMethod : public Method {
 public:
  BulletSoftBodyMethod(std::shared_ptr<const Lattice> lattice, const BulletParams& params)
      : lattice_(std::move(lattice)), params_(params) {
    if (!(params_.linearStiffness > 0.0) || params_.linearStiffness > 1.0 || params_.positionIterations < 1 ||
        !(params_.timeStep > 0.0) || params_.substeps < 1 || !(params_.ambientDamping >= 0.0))
      throw std::invalid_argument("bullet: kLST must be in (0, 1], iterations, step and sub-steps > 0");
    const Lattice& L = *lattice_;
    const std::size_t n = L.size();
    info_.m_gravity = toBt(params_.gravity);
    info_.m_sparsesdf.Initialize();
    std::vector<btVector3> x(n);
    std::vector<btScalar> m(n);
    for (std::size_t i = 0; i < n; ++i) {
      x[i] = toBt(L.restPositions()[i]);
      m[i] = static_cast<btScalar>(L.masses()[i]);
    }
    body_ = std::make_unique<btSoftBody>(&info_, static_cast<int>(n), x.data(), m.data());
    btSoftBody::Material* material = body_->m_materials[0];
    material->m_kLST = static_cast<btScalar>(params_.linearStiffness);
    for (const LatticeLink& l : latticeLinks(L)) body_->appendLink(static_cast<int>(l.a), static_cast<int>(l.b), material);
    body_->m_cfg.piterations = params_.positionIterations;
    body_->m_cfg.kDP = static_cast<btScalar>(1.0 - std::exp(-params_.ambientDamping * substep()));
    // Rest lengths and link constants from the rest positions, now, so that a state set
    // before the first step (setPositions) is not taken as the rest shape.
    body_->updateConstants();
    body_->m_bUpdateRtCst = false;
    inverseMass_.resize(n);
    for (std::size_t i = 0; i < n; ++i) inverseMass_[i] = body_->m_nodes[static_cast<int>(i)].m_im;
    pinned_.assign(n, 0);
    x_ = L.restPositions();
  }

  std::string name() const override { return "bullet"; }
  int substeps() const override { return params_.substeps; }
  double substep() const { return params_.timeStep / params_.substeps; }

  void step() override {
    const double h = substep();
    for (int s = 0; s < params_.substeps; ++s) {
      // kinematic nodes: a velocity that lands them on their target in this sub-step
      for (std::size_t e = 0; e < grabbed_.size(); ++e) {
        btSoftBody::Node& node = body_->m_nodes[static_cast<int>(grabbed_[e])];
        node.m_v = (toBt(grabTarget_ + grabOffsets_[e]) - node.m_x) / static_cast<btScalar>(h);
      }
      for (std::size_t i = 0; i < pinned_.size(); ++i)
        if (pinned_[i]) body_->m_nodes[static_cast<int>(i)].m_v.setZero();
      body_->predictMotion(static_cast<btScalar>(h));
      body_->solveConstraints();
      body_->integrateMotion();
    }
    const std::size_t n = x_.size();
    for (std::size_t i = 0; i < n; ++i) x_[i] = toEigen(body_->m_nodes[static_cast<int>(i)].m_x);
  }

  const std::vector<Eigen::Vector3d>& positions() const override { return x_; }
  void setPositions(const std::vector<Eigen::Vector3d>& x) override {
    for (std::size_t i = 0; i < x.size(); ++i) {
      btSoftBody::Node& node = body_->m_nodes[static_cast<int>(i)];
      node.m_x = node.m_q = toBt(x[i]);
      node.m_v.setZero();
    }
    x_ = x;
  }
  void setPinned(const std::vector<std::uint32_t>& particles, bool pinned) override {
    for (std::uint32_t p : particles) pinned_[p] = pinned ? 1 : 0;
    refreshInverseMasses();
  }
  void grab(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target) override {
    grabbed_ = particles;
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (std::uint32_t p : particles) c += x_[p];
    c /= static_cast<double>(particles.size());
    grabOffsets_.clear();
    for (std::uint32_t p : particles) grabOffsets_.push_back(x_[p] - c);
    grabTarget_ = target;
    refreshInverseMasses();
  }
  void moveGrab(const Eigen::Vector3d& target) override { grabTarget_ = target; }
  /// Position-based links exert no force that a kinematic node could read: NaN (the study's
  /// indentation reads the legacy body through BulletVolumeMethod's anchors).
  Eigen::Vector3d grabForce() const override {
    return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  }
  void release() override {
    grabbed_.clear();
    grabOffsets_.clear();
    refreshInverseMasses();
  }
  double kineticEnergy() const override {
    const auto& m = lattice_->masses();
    double e = 0.0;
    for (std::size_t i = 0; i < m.size(); ++i)
      e += 0.5 * m[i] * toEigen(body_->m_nodes[static_cast<int>(i)].m_v).squaredNorm();
    return e;
  }
  void rotations(std::vector<Eigen::Quaterniond>& out) const override {
    neighbourhoodRotations(*lattice_, x_, warm_);
    out = warm_;
  }

 private:
  static btVector3 toBt(const Eigen::Vector3d& v) {
    return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
  }
  static Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

  // Inverse mass 0 for pinned and grabbed nodes, the particle's otherwise; then the links'
  // constants, which depend on the inverse masses of their ends (rest lengths untouched).
  void refreshInverseMasses() {
    for (std::size_t i = 0; i < pinned_.size(); ++i)
      body_->m_nodes[static_cast<int>(i)].m_im = pinned_[i] ? btScalar(0) : inverseMass_[i];
    for (std::uint32_t p : grabbed_) body_->m_nodes[static_cast<int>(p)].m_im = 0;
    body_->updateLinkConstants();
  }

  std::shared_ptr<const Lattice> lattice_;
  BulletParams params_;
  btSoftBodyWorldInfo info_;
  std::unique_ptr<btSoftBody> body_;
  std::vector<btScalar> inverseMass_;
  std::vector<char> pinned_;
  std::vector<Eigen::Vector3d> x_;
  std::vector<std::uint32_t> grabbed_;
  std::vector<Eigen::Vector3d> grabOffsets_;
  Eigen::Vector3d grabTarget_ = Eigen::Vector3d::Zero();
  mutable std::vector<Eigen::Quaterniond> warm_;
};

}  // namespace study
}  // namespace deformable_flsm
