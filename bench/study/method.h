/// @file method.h
/// The interface every simulation method of the study is driven through, and its FastLSM
/// implementation (fast or naive summation, explicit or implicit step).
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/solver.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

/// A deformable-object simulator on the particles of a Lattice (one particle per occupied cell),
/// advanced frame by frame. Scenarios drive every method through this interface only, so that
/// all methods see the same pins, drags and initial states.
class Method {
 public:
  virtual ~Method() = default;
  /// Short name used in the CSV files ("fastlsm", "fastlsm-implicit", "naive-lsm", "mass-spring",
  /// "bullet", "bullet-fem").
  virtual std::string name() const = 0;
  /// Sub-steps per frame (for the cost per particle-step).
  virtual int substeps() const = 0;
  /// Advances one frame.
  virtual void step() = 0;
  /// #P particle positions (m), in the order of the lattice.
  virtual const std::vector<Eigen::Vector3d>& positions() const = 0;
  /// Overwrites the positions (m) and sets every velocity to zero.
  virtual void setPositions(const std::vector<Eigen::Vector3d>& x) = 0;
  /// Pins or unpins particles: a pinned particle stays where it is.
  virtual void setPinned(const std::vector<std::uint32_t>& particles, bool pinned) = 0;
  /// Grabs particles: from the next frame on their centroid follows `target` (m) exactly,
  /// keeping their arrangement at the time of the grab. Replaces an earlier grab.
  virtual void grab(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target) = 0;
  /// Moves the grab target (m).
  virtual void moveGrab(const Eigen::Vector3d& target) = 0;
  /// Lets the grabbed particles go.
  virtual void release() = 0;
  /// As grab(), for a punch on a surface: a method of one particle per cell holds the particles
  /// (grab()); one whose nodes are the cells' corners holds only the corners on the cells' face
  /// towards `outward` (a unit axis), the face the punch meets.
  virtual void grabFace(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target,
                        const Eigen::Vector3d& outward) {
    (void)outward;
    grab(particles, target);
  }
  /// As setPinned(particles, true), for a support under a face: a method of corner nodes pins
  /// only the corners on the cells' face towards `outward`.
  virtual void pinFace(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& outward) {
    (void)outward;
    setPinned(particles, true);
  }
  /// The force (N) the grab exerted on the object, the mean over the last frame; at rest, what
  /// holds the grabbed particles where they are. Zero without a grab.
  virtual Eigen::Vector3d grabForce() const = 0;
  /// Kinetic energy sum 1/2 m |v|^2 (J).
  virtual double kineticEnergy() const = 0;
  /// #P rotations used for the embedding's ghost nodes (see Embedding).
  virtual void rotations(std::vector<Eigen::Quaterniond>& out) const = 0;
};

/// FastLSM (Rivers & James 2007) through the package's Solver, with SolverKind::Fast or Naive and
/// Integrator::Explicit or Implicit.
class FlsmMethod : public Method {
 public:
  /// @param[in] lattice  particles and regions (its w must equal params.regionHalfWidth)
  /// @param[in] params   solver parameters (study::flsmParams())
  FlsmMethod(std::shared_ptr<const Lattice> lattice, const SolverParams& params)
      : solver_(std::move(lattice), params) {}

  std::string name() const override {
    if (solver_.params().kind == SolverKind::Naive) return "naive-lsm";
    return solver_.params().integrator == Integrator::Implicit ? "fastlsm-implicit" : "fastlsm";
  }
  int substeps() const override { return solver_.params().substeps; }
  void step() override {
    solver_.step();
    if (solver_.params().integrator == Integrator::Implicit) {
      iterations_ += solver_.lastImplicitSolve().iterations;
      ++frames_;
    }
  }
  /// Implicit step only: the conjugate-gradient iterations of each frame's last sub-step
  /// (Solver::lastImplicitSolve(), its contact passes summed), averaged over the frames so far;
  /// 0 before the first frame and with the explicit step.
  double meanIterations() const { return frames_ ? double(iterations_) / double(frames_) : 0.0; }
  const std::vector<Eigen::Vector3d>& positions() const override { return solver_.positions(); }
  void setPositions(const std::vector<Eigen::Vector3d>& x) override {
    solver_.setPositions(x);
    solver_.setVelocities(std::vector<Eigen::Vector3d>(x.size(), Eigen::Vector3d::Zero()));
  }
  void setPinned(const std::vector<std::uint32_t>& particles, bool pinned) override {
    for (std::uint32_t p : particles) solver_.setPinned(p, pinned);
  }
  void grab(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& target) override {
    solver_.grab(kGrabId, particles, target, 0.0);
  }
  void moveGrab(const Eigen::Vector3d& target) override { solver_.moveDrag(kGrabId, target); }
  void release() override { solver_.release(kGrabId); }
  /// the hard drag's force (Drag::force)
  Eigen::Vector3d grabForce() const override {
    const auto d = solver_.drags().find(kGrabId);
    return d == solver_.drags().end() ? Eigen::Vector3d::Zero() : d->second.force;
  }
  double kineticEnergy() const override { return solver_.kineticEnergy(); }
  void rotations(std::vector<Eigen::Quaterniond>& out) const override {
    out = solver_.regionRotations();
  }

  const Solver& solver() const { return solver_; }

 private:
  static constexpr const char* kGrabId = "study";
  Solver solver_;
  long long iterations_ = 0;
  long long frames_ = 0;
};

}  // namespace study
}  // namespace deformable_flsm
