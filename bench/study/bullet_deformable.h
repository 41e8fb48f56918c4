/// @file bullet_deformable.h
/// Bullet's implicit deformable body (btDeformableMultiBodyDynamicsWorld with
/// btDeformableLinearElasticityForce: corotated linear elasticity on tetrahedra, backward Euler
/// solved by Newton and conjugate gradients) on the voxels of a FastLSM lattice, as the study's
/// finite-element peer. It takes the material as FastLSM does: Young's modulus E and Poisson's
/// ratio nu, nothing calibrated. Needs Bullet (libbullet-dev); include only where it is linked.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "study/method.h"
#include "study/metrics.h"
#include "study/setting.h"

#include <btBulletDynamicsCommon.h>
#include <BulletSoftBody/btDeformableBodySolver.h>
#include <BulletSoftBody/btDeformableGravityForce.h>
#include <BulletSoftBody/btDeformableLinearElasticityForce.h>
#include <BulletSoftBody/btDeformableMultiBodyConstraintSolver.h>
#include <BulletSoftBody/btDeformableMultiBodyDynamicsWorld.h>
#include <BulletSoftBody/btSoftBody.h>
#include <BulletSoftBody/btSoftBodyHelpers.h>
#include <BulletSoftBody/btSoftBodyRigidBodyCollisionConfiguration.h>

#include <Eigen/Core>

#include <array>
#include <cmath>
#include <cstdint>
#include <algorithm>
#include <limits>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <tuple>
#include <vector>

namespace deformable_flsm {
namespace study {

struct BulletDeformableParams {
  /// Young's modulus E (Pa) and Poisson's ratio nu of the material.
  double youngsModulus = 1e4;
  double poissonRatio = 0.3;
  /// Stiffness-proportional damping beta (s) of btDeformableLinearElasticityForce: a damping
  /// stress beta (2 mu sym(dF/dt) + lambda tr(dF/dt) I).
  double stiffnessDamping = 0.0;
  /// Rate (1/s) of drag towards rest in the world frame, v <- v exp(-rate h) per sub-step, as
  /// SolverParams::ambientDamping.
  double ambientDamping = 0.5;
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  /// Frame step (s) and sub-steps per frame.
  double timeStep = 1.0 / 60.0;
  int substeps = 1;
};

/// Corner nodes and tetrahedra of the occupied cells of a lattice: every cell is split into the
/// 6 tetrahedra of Kuhn's triangulation (the paths from corner 000 to 111 along the axes in each
/// of the 6 orders), which is conforming across cells because every cell uses the same diagonal.
struct VoxelTetMesh {
  /// #N node rest positions (m), the cell corners
  std::vector<Eigen::Vector3d> nodes;
  /// #N node masses (kg): each cell's mass shared equally by its 8 corners
  std::vector<double> nodeMasses;
  /// #T node index quadruples, positively oriented
  std::vector<std::array<int, 4>> tets;
  /// #T index of the cell each tetrahedron belongs to
  std::vector<std::uint32_t> tetCell;
  /// #P x 8 node of each corner of each cell, corner k = (k & 1, k >> 1 & 1, k >> 2 & 1)
  std::vector<std::array<int, 8>> cellCorners;
};

inline VoxelTetMesh voxelTetMesh(const Lattice& lattice) {
  VoxelTetMesh m;
  const double h = lattice.spacing();
  std::map<std::tuple<int, int, int>, int> index;
  m.cellCorners.resize(lattice.size());
  for (std::size_t i = 0; i < lattice.size(); ++i) {
    const Eigen::Vector3i& c = lattice.cells()[i];
    for (int k = 0; k < 8; ++k) {
      const Eigen::Vector3i d(k & 1, (k >> 1) & 1, (k >> 2) & 1);
      const auto key = std::make_tuple(c.x() + d.x(), c.y() + d.y(), c.z() + d.z());
      auto it = index.find(key);
      if (it == index.end()) {
        it = index.emplace(key, static_cast<int>(m.nodes.size())).first;
        m.nodes.push_back(lattice.restPositions()[i] + h * (d.cast<double>() - Eigen::Vector3d::Constant(0.5)));
        m.nodeMasses.push_back(0.0);
      }
      m.cellCorners[i][k] = it->second;
      m.nodeMasses[it->second] += lattice.masses()[i] / 8.0;
    }
  }
  static const int kOrders[6][3] = {{0, 1, 2}, {0, 2, 1}, {1, 0, 2}, {1, 2, 0}, {2, 0, 1}, {2, 1, 0}};
  for (std::size_t i = 0; i < lattice.size(); ++i)
    for (const auto& order : kOrders) {
      std::array<int, 4> t{};
      int k = 0;
      t[0] = m.cellCorners[i][k];
      for (int s = 0; s < 3; ++s) {
        k |= 1 << order[s];
        t[s + 1] = m.cellCorners[i][k];
      }
      const Eigen::Vector3d& p = m.nodes[t[0]];
      if ((m.nodes[t[1]] - p).dot((m.nodes[t[2]] - p).cross(m.nodes[t[3]] - p)) < 0.0) std::swap(t[2], t[3]);
      m.tets.push_back(t);
      m.tetCell.push_back(static_cast<std::uint32_t>(i));
    }
  return m;
}

/// The corner nodes of a voxel tetrahedral mesh held in a btSoftBody, and what every Bullet peer
/// on it shares: particle positions as cell centres (the mean of their 8 corners), pins and
/// grabs as kinematic corners (inverse mass 0), and setPositions() from cell centres. A derived
/// class builds the body (body_) and advances it (advance()).
class VoxelBulletBody : public Method {
 public:
  int substeps() const override { return substeps_; }
  /// Nodes of the tetrahedral mesh (cell corners).
  std::size_t nodeCount() const { return mesh_.nodes.size(); }

  void step() override {
    const double h = frameStep_ / substeps_;
    for (int s = 0; s < substeps_; ++s) {
      // kinematic nodes: the velocity that lands them on their target in this sub-step
      for (std::size_t e = 0; e < grabbedNodes_.size(); ++e) {
        btSoftBody::Node& node = body_->m_nodes[grabbedNodes_[e]];
        node.m_v = (toBt(grabTarget_ + grabOffsets_[e]) - node.m_x) / static_cast<btScalar>(h);
      }
      for (std::size_t v = 0; v < pinnedNodes_.size(); ++v)
        if (pinnedNodes_[v]) body_->m_nodes[static_cast<int>(v)].m_v.setZero();
      advance(h);
      for (std::size_t e = 0; e < grabbedNodes_.size(); ++e) {
        btSoftBody::Node& node = body_->m_nodes[grabbedNodes_[e]];
        node.m_x = node.m_q = toBt(grabTarget_ + grabOffsets_[e]);
        node.m_v.setZero();
      }
    }
    updateCentres();
  }

  const std::vector<Eigen::Vector3d>& positions() const override { return x_; }

  /// Cell centres are given; each corner goes to the mean over its cells of (centre + rest
  /// offset of the corner from that centre), so that a scrambled or collapsed start moves the
  /// cells as the particles of the other methods move.
  void setPositions(const std::vector<Eigen::Vector3d>& x) override {
    const std::size_t n = mesh_.nodes.size();
    std::vector<Eigen::Vector3d> sum(n, Eigen::Vector3d::Zero());
    std::vector<int> count(n, 0);
    for (std::size_t i = 0; i < x.size(); ++i)
      for (int k = 0; k < 8; ++k) {
        const int v = mesh_.cellCorners[i][k];
        sum[v] += x[i] + mesh_.nodes[v] - lattice_->restPositions()[i];
        ++count[v];
      }
    for (std::size_t v = 0; v < n; ++v) {
      btSoftBody::Node& node = body_->m_nodes[static_cast<int>(v)];
      node.m_x = node.m_q = toBt(sum[v] / count[v]);
      node.m_v.setZero();
    }
    updateCentres();
  }
  void setPinned(const std::vector<std::uint32_t>& particles, bool pinned) override {
    for (std::uint32_t p : particles)
      for (int v : mesh_.cellCorners[p]) pinnedNodes_[v] = pinned ? 1 : 0;
    refreshInverseMasses();
  }
  void grab(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target) override {
    std::vector<char> mark(mesh_.nodes.size(), 0);
    grabbedNodes_.clear();
    for (std::uint32_t p : particles)
      for (int v : mesh_.cellCorners[p])
        if (!mark[v]) {
          mark[v] = 1;
          grabbedNodes_.push_back(v);
        }
    Eigen::Vector3d c = Eigen::Vector3d::Zero();
    for (std::uint32_t p : particles) c += x_[p];
    c /= static_cast<double>(particles.size());
    grabOffsets_.clear();
    for (int v : grabbedNodes_) grabOffsets_.push_back(toEigen(body_->m_nodes[v].m_x) - c);
    grabTarget_ = target;
    refreshInverseMasses();
  }
  /// Holds only the grabbed cells' corners on their face towards `outward`.
  void grabFace(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target,
                const Eigen::Vector3d& outward) override {
    grab(particles, target);
    const std::vector<char> face = faceCorners(particles, outward);
    std::vector<int> nodes;
    std::vector<Eigen::Vector3d> offsets;
    for (std::size_t e = 0; e < grabbedNodes_.size(); ++e)
      if (face[static_cast<std::size_t>(grabbedNodes_[e])]) {
        nodes.push_back(grabbedNodes_[e]);
        offsets.push_back(grabOffsets_[e]);
      }
    grabbedNodes_ = nodes;
    grabOffsets_ = offsets;
    refreshInverseMasses();
  }
  /// Pins only the cells' corners on their face towards `outward`.
  void pinFace(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& outward) override {
    const std::vector<char> face = faceCorners(particles, outward);
    for (std::size_t v = 0; v < face.size(); ++v)
      if (face[v]) pinnedNodes_[v] = 1;
    refreshInverseMasses();
  }
  void moveGrab(const Eigen::Vector3d& target) override { grabTarget_ = target; }
  void release() override {
    grabbedNodes_.clear();
    grabOffsets_.clear();
    refreshInverseMasses();
  }
  double kineticEnergy() const override {
    double e = 0.0;
    for (std::size_t v = 0; v < mesh_.nodes.size(); ++v)
      e += 0.5 * mesh_.nodeMasses[v] * toEigen(body_->m_nodes[static_cast<int>(v)].m_v).squaredNorm();
    return e;
  }
  void rotations(std::vector<Eigen::Quaterniond>& out) const override {
    neighbourhoodRotations(*lattice_, x_, warm_);
    out = warm_;
  }

 protected:
  VoxelBulletBody(std::shared_ptr<const Lattice> lattice, double frameStep, int substeps)
      : lattice_(std::move(lattice)), mesh_(voxelTetMesh(*lattice_)), frameStep_(frameStep), substeps_(substeps) {
    if (!(frameStep_ > 0.0) || substeps_ < 1)
      throw std::invalid_argument("bullet: the frame step and the sub-steps must be > 0");
    x_ = lattice_->restPositions();
    pinnedNodes_.assign(mesh_.nodes.size(), 0);
  }

  /// Advances the body by one sub-step h (s).
  virtual void advance(double h) = 0;
  /// Per node, 1 where it is a corner of one of the cells `particles` on that cell's face towards
  /// `outward`.
  std::vector<char> faceCorners(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& outward) const {
    std::vector<char> face(mesh_.nodes.size(), 0);
    for (std::uint32_t p : particles)
      for (int v : mesh_.cellCorners[p])
        if ((mesh_.nodes[v] - lattice_->restPositions()[p]).dot(outward) > 0.0) face[static_cast<std::size_t>(v)] = 1;
    return face;
  }
  /// Called after inverse masses changed (pins, grabs).
  virtual void inverseMassesChanged() {}

  /// A btSoftBody on the mesh's nodes (masses lumped on the corners) with its tetrahedra.
  btSoftBody* newBody(btSoftBodyWorldInfo& info) {
    const std::size_t n = mesh_.nodes.size();
    std::vector<btVector3> x(n);
    std::vector<btScalar> m(n);
    for (std::size_t i = 0; i < n; ++i) {
      x[i] = toBt(mesh_.nodes[i]);
      m[i] = static_cast<btScalar>(mesh_.nodeMasses[i]);
    }
    auto* body = new btSoftBody(&info, static_cast<int>(n), x.data(), m.data());
    for (const auto& t : mesh_.tets) body->appendTetra(t[0], t[1], t[2], t[3]);
    return body;
  }
  /// Remembers the body's inverse masses as the free ones (call once the body is built).
  void takeInverseMasses() {
    inverseMass_.resize(mesh_.nodes.size());
    for (std::size_t i = 0; i < inverseMass_.size(); ++i) inverseMass_[i] = body_->m_nodes[static_cast<int>(i)].m_im;
  }

  static btVector3 toBt(const Eigen::Vector3d& v) {
    return btVector3(static_cast<btScalar>(v.x()), static_cast<btScalar>(v.y()), static_cast<btScalar>(v.z()));
  }
  static Eigen::Vector3d toEigen(const btVector3& v) { return Eigen::Vector3d(v.x(), v.y(), v.z()); }

  std::shared_ptr<const Lattice> lattice_;
  VoxelTetMesh mesh_;
  double frameStep_;
  int substeps_;
  btSoftBody* body_ = nullptr;
  /// the grabbed nodes (kinematic), their offsets from the grab's target, the target
  std::vector<int> grabbedNodes_;
  std::vector<Eigen::Vector3d> grabOffsets_;
  Eigen::Vector3d grabTarget_ = Eigen::Vector3d::Zero();

 private:
  void refreshInverseMasses() {
    for (std::size_t v = 0; v < pinnedNodes_.size(); ++v)
      body_->m_nodes[static_cast<int>(v)].m_im = pinnedNodes_[v] ? btScalar(0) : inverseMass_[v];
    for (int v : grabbedNodes_) body_->m_nodes[v].m_im = 0;
    inverseMassesChanged();
  }

  void updateCentres() {
    for (std::size_t i = 0; i < x_.size(); ++i) {
      Eigen::Vector3d c = Eigen::Vector3d::Zero();
      for (int v : mesh_.cellCorners[i]) c += toEigen(body_->m_nodes[v].m_x);
      x_[i] = c / 8.0;
    }
  }

  std::vector<btScalar> inverseMass_;
  std::vector<char> pinnedNodes_;
  std::vector<Eigen::Vector3d> x_;
  mutable std::vector<Eigen::Quaterniond> warm_;
};

/// Bullet's btDeformableBody on the voxels (VoxelBulletBody): 6 tetrahedra per cell, each
/// tetrahedron's elastic measure scaled by its cell's fill fraction (m / (rho h^3)) so that a
/// sliver of a surface cell is as weak as it is light, as in FastLSM; corotated linear
/// elasticity with the material's E and nu; the world set up as Bullet's own volumetric
/// examples do (implicit, no line search, projection; no collisions since no scenario has
/// contacts).
/// Single precision (btScalar = float) as packaged.
class BulletDeformableMethod : public VoxelBulletBody {
 public:
  BulletDeformableMethod(std::shared_ptr<const Lattice> lattice, const BulletDeformableParams& params)
      : VoxelBulletBody(std::move(lattice), params.timeStep, params.substeps), params_(params) {
    if (!(params_.youngsModulus > 0.0) || !(params_.poissonRatio > -1.0 && params_.poissonRatio < 0.5) ||
        !(params_.ambientDamping >= 0.0) || !(params_.stiffnessDamping >= 0.0))
      throw std::invalid_argument("bullet-fem: need E > 0, -1 < nu < 0.5, damping >= 0");
    config_ = std::make_unique<btSoftBodyRigidBodyCollisionConfiguration>();
    dispatcher_ = std::make_unique<btCollisionDispatcher>(config_.get());
    broadphase_ = std::make_unique<btDbvtBroadphase>();
    bodySolver_ = std::make_unique<btDeformableBodySolver>();
    constraintSolver_ = std::make_unique<btDeformableMultiBodyConstraintSolver>();
    constraintSolver_->setDeformableSolver(bodySolver_.get());
    world_ = std::make_unique<btDeformableMultiBodyDynamicsWorld>(dispatcher_.get(), broadphase_.get(),
                                                                  constraintSolver_.get(), config_.get(),
                                                                  bodySolver_.get());
    world_->setGravity(toBt(params_.gravity));
    world_->getWorldInfo().m_gravity = toBt(params_.gravity);
    world_->getWorldInfo().m_sparsesdf.Initialize();

    body_ = newBody(world_->getWorldInfo());
    body_->initializeDmInverse();
    // Bullet's TetraScratch leaves its matrices uninitialised until the first step fills them
#pragma GCC diagnostic push
#pragma GCC diagnostic ignored "-Wmaybe-uninitialized"
    body_->m_tetraScratches.resize(body_->m_tetras.size());
    body_->m_tetraScratchesTn.resize(body_->m_tetras.size());
#pragma GCC diagnostic pop
    const double h = lattice_->spacing();
    const double full = h * h * h * kStudyDensity;
    for (int t = 0; t < body_->m_tetras.size(); ++t)
      body_->m_tetras[t].m_element_measure *=
          static_cast<btScalar>(lattice_->masses()[mesh_.tetCell[static_cast<std::size_t>(t)]] / full);
    body_->m_cfg.collisions = 0;
    body_->m_sleepingThreshold = 0;
    body_->setActivationState(DISABLE_DEACTIVATION);
    world_->addSoftBody(body_);

    const double E = params_.youngsModulus, nu = params_.poissonRatio;
    const double mu = E / (2.0 * (1.0 + nu)), lambda = E * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
    elasticity_ = std::make_unique<btDeformableLinearElasticityForce>(
        static_cast<btScalar>(mu), static_cast<btScalar>(lambda), btScalar(0),
        static_cast<btScalar>(params_.stiffnessDamping));
    world_->addForce(body_, elasticity_.get());
    if (params_.gravity.squaredNorm() > 0.0) {
      gravity_ = std::make_unique<btDeformableGravityForce>(toBt(params_.gravity));
      world_->addForce(body_, gravity_.get());
    }
    // as Bullet's volumetric examples (LargeDeformation): implicit, no line search, fixed nodes
    // and contacts as velocity projections (without projection, Bullet 3.24's implicit solve
    // through Lagrange multipliers leaves every velocity at zero)
    world_->setImplicit(true);
    world_->setLineSearch(false);
    world_->setUseProjection(true);
    takeInverseMasses();
  }

  ~BulletDeformableMethod() override {
    world_->removeSoftBodyForce(body_);
    world_->removeSoftBody(body_);
    delete body_;
  }
  BulletDeformableMethod(const BulletDeformableMethod&) = delete;
  BulletDeformableMethod& operator=(const BulletDeformableMethod&) = delete;

  std::string name() const override { return "bullet-fem"; }
  /// The grab's force from statics: minus the elastic force (Bullet's own,
  /// btDeformableLinearElasticityForce::addScaledElasticForce) on the grabbed nodes, at the end of
  /// the frame. Exact at rest, where no inertia or damping force acts; what the punch reads.
  Eigen::Vector3d grabForce() const override {
    if (grabbedNodes_.empty()) return Eigen::Vector3d::Zero();
    btAlignedObjectArray<btVector3> f;
    f.resize(body_->m_nodes.size());
    for (int i = 0; i < f.size(); ++i) f[i].setZero();
    elasticity_->addScaledElasticForce(btScalar(1), f);
    Eigen::Vector3d sum = Eigen::Vector3d::Zero();
    for (int v : grabbedNodes_) sum -= toEigen(f[body_->m_nodes[v].index]);
    return sum;
  }

 protected:
  void advance(double h) override {
    world_->stepSimulation(static_cast<btScalar>(h), 0, static_cast<btScalar>(h));
    const btScalar keep = static_cast<btScalar>(std::exp(-params_.ambientDamping * h));
    for (int i = 0; i < body_->m_nodes.size(); ++i) body_->m_nodes[i].m_v *= keep;
  }

 private:
  BulletDeformableParams params_;
  std::unique_ptr<btSoftBodyRigidBodyCollisionConfiguration> config_;
  std::unique_ptr<btCollisionDispatcher> dispatcher_;
  std::unique_ptr<btDbvtBroadphase> broadphase_;
  std::unique_ptr<btDeformableBodySolver> bodySolver_;
  std::unique_ptr<btDeformableMultiBodyConstraintSolver> constraintSolver_;
  std::unique_ptr<btDeformableMultiBodyDynamicsWorld> world_;
  std::unique_ptr<btDeformableLinearElasticityForce> elasticity_;
  std::unique_ptr<btDeformableGravityForce> gravity_;
};

struct BulletVolumeParams {
  /// Material linear stiffness kLST in (0, 1] of the links (btSoftBody::Material::m_kLST).
  double linearStiffness = 1.0;
  /// Pose matching kMT in [0, 1] (btSoftBody::Config::kMT): each sub-step moves every free
  /// node by this fraction towards the best rigid fit of the whole rest shape (a global goal:
  /// its pull per second grows with the number of sub-steps).
  double poseMatching = 0.05;
  /// Bulk modulus K (Pa) of the volume conservation: btSoftBody::Config::kVC = K / V0, so that
  /// the pressure kVC (V0 - V) on the boundary faces is K times the relative volume loss.
  double bulkModulus = 0.0;
  /// Position-solver iterations per sub-step (btSoftBody::Config::piterations).
  int positionIterations = 4;
  /// As BulletParams::ambientDamping (kDP = 1 - exp(-rate h)).
  double ambientDamping = 0.5;
  Eigen::Vector3d gravity = Eigen::Vector3d::Zero();
  double timeStep = 1.0 / 60.0;
  int substeps = 1;
};

/// The legacy btSoftBody as its users build a volumetric body (btSoftBodyHelpers::
/// CreateFromTetGenData: tetrahedra, a link per tetrahedron edge, the boundary faces), with
/// pose matching (setPose(volume, frame), kMT) and volume conservation (kVC) switched on, on
/// the same corner nodes as BulletDeformableMethod. Advanced per sub-step by Bullet's default
/// soft-body sequence: predictMotion() (gravity, volume forces, pose matching), solveConstraints()
/// (piterations sweeps over the links), integrateMotion().
class BulletVolumeMethod : public VoxelBulletBody {
 public:
  BulletVolumeMethod(std::shared_ptr<const Lattice> lattice, const BulletVolumeParams& params)
      : VoxelBulletBody(std::move(lattice), params.timeStep, params.substeps), params_(params) {
    if (!(params_.linearStiffness > 0.0) || params_.linearStiffness > 1.0 || !(params_.poseMatching >= 0.0) ||
        params_.poseMatching > 1.0 || !(params_.bulkModulus >= 0.0) || params_.positionIterations < 1 ||
        !(params_.ambientDamping >= 0.0))
      throw std::invalid_argument("bullet: kLST in (0, 1], kMT in [0, 1], bulk modulus >= 0, iterations > 0");
    info_.m_gravity = toBt(params_.gravity);
    info_.m_sparsesdf.Initialize();
    body_ = newBody(info_);
    btSoftBody::Material* material = body_->m_materials[0];
    material->m_kLST = static_cast<btScalar>(params_.linearStiffness);
    std::map<std::pair<int, int>, bool> edges;
    for (const auto& t : mesh_.tets)
      for (int a = 0; a < 4; ++a)
        for (int b = a + 1; b < 4; ++b) edges[std::minmax(t[a], t[b])] = true;
    for (const auto& e : edges) body_->appendLink(e.first.first, e.first.second, material);
    btSoftBodyHelpers::generateBoundaryFaces(body_);
    body_->m_cfg.piterations = params_.positionIterations;
    body_->m_cfg.kDP = static_cast<btScalar>(1.0 - std::exp(-params_.ambientDamping * frameStep_ / substeps_));
    body_->m_cfg.kMT = static_cast<btScalar>(params_.poseMatching);
    body_->m_cfg.collisions = 0;
    body_->setPose(params_.bulkModulus > 0.0, params_.poseMatching > 0.0);
    body_->m_cfg.kVC = static_cast<btScalar>(params_.bulkModulus / std::abs(body_->getVolume()));
    body_->updateConstants();
    body_->m_bUpdateRtCst = false;
    takeInverseMasses();
  }
  ~BulletVolumeMethod() override { delete body_; }
  BulletVolumeMethod(const BulletVolumeMethod&) = delete;
  BulletVolumeMethod& operator=(const BulletVolumeMethod&) = delete;

  std::string name() const override { return "bullet"; }
  /// Rest volume (m^3) of the boundary faces, as Bullet measures it (btSoftBody::getVolume()).
  double restVolume() const { return body_->m_pose.m_volume; }

  /// Position-based links move nodes without a force: a kinematic node feels none, so there is
  /// no force to read (NaN). Bullet's anchors to a rigid handle read one that depends on the
  /// sub-step, even in sign (docs/study.md, indentation).
  Eigen::Vector3d grabForce() const override {
    return Eigen::Vector3d::Constant(std::numeric_limits<double>::quiet_NaN());
  }

 protected:
  void advance(double h) override {
    body_->predictMotion(static_cast<btScalar>(h));
    body_->solveConstraints();
    body_->integrateMotion();
  }
  void inverseMassesChanged() override { body_->updateLinkConstants(); }

 private:
  BulletVolumeParams params_;
  btSoftBodyWorldInfo info_;
};

}  // namespace study
}  // namespace deformable_flsm
