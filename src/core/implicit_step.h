// The implicit step of one object: linearly implicit backward Euler and BDF2 on its material, its
// collider contacts by an active set, its preconditioned CG solve; the state it keeps from one
// sub-step to the next (warm start, contact states, BDF2's last state). The object (Solver) owns
// it, made with the implicit integrator, and drives it through substep(), or begin() and
// endCoupled() around a solve of several objects (ImplicitCoupling). Internal to the core;
// solver_implicit.cpp (the system, the solve, the momenta) and solver_implicit_contact.cpp (the
// contacts) define it.
#pragma once

#include "deformable_flsm/core/corotated_hessian.h"
#include "deformable_flsm/core/pcg.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/two_level_preconditioner.h"
#include "integrator_step.h"

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <vector>

namespace deformable_flsm {

/// Reads and moves the object's particles (o_): its positions, velocities, pins, drags, forces,
/// material and contact bodies are the object's; what only this step needs is its own.
class Solver::ImplicitStep final : public Solver::IntegratorStep {
 public:
  explicit ImplicitStep(Solver& object);

  /// The buffers sized for the object and its parameters (after a change of either); BDF2 starts
  /// again from backward Euler.
  void configure();
  /// Forgets the last sub-step: warm start, contact states, BDF2's history (Solver::reset()).
  void forgetMemory();
  /// BDF2 starts again from a backward Euler step (the state was set, or the object slept).
  void forgetHistory() override { bdf2Ready_ = false; }

  /// One sub-step of length h: begin(), the solve with its contact passes, end(); BDF2 solves 2/3
  /// of it from its extrapolated start.
  void substep(double h) override;
  /// The sub-step's system (right-hand side, diagonal, preconditioner, collider contacts, the
  /// warm start) and the solve's floor (floor_).
  void begin(double h);
  /// After a solve of several objects (`result`, its residual b - A v at residual[offset + i]),
  /// `couplingImpulse` the other objects' impulse on each particle: end().
  void endCoupled(double h, const PcgResult& result, const std::vector<Eigen::Vector3d>& residual,
                  std::size_t offset, const std::vector<Eigen::Vector3d>& couplingImpulse);
  /// y = A p, A the step's matrix M + h C + h^2 K (rows of fixed entries meaningless).
  void product(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y);
  /// z = P^-1 r, the two-level preconditioner with `invDiagonal` as its Jacobi part.
  void precondition(const std::vector<Eigen::Vector3d>& invDiagonal, const std::vector<Eigen::Vector3d>& r,
                    std::vector<Eigen::Vector3d>& z);
  /// The contact active set after a solve: lets go of pulling contacts, turns sticking ones out
  /// of the friction cone into sliding ones, adds particles the solution carries into a
  /// collider; returns whether it changed (never without colliders). Sets guessChanged when it
  /// prescribed a velocity (the next solve then needs its residual computed again).
  /// The solve's residual is pcg.residual()[offset + i].
  bool updateContactSet(double h, bool& guessChanged, Pcg& pcg, std::size_t offset);

  // the system of the sub-step begun (Solver's accessors of the same names)
  std::vector<Eigen::Vector3d>& velocity() { return velocity_; }
  const std::vector<Eigen::Vector3d>& rhs() const { return rhs_; }
  const std::vector<PcgConstraint>& constraints() const { return constraint_; }
  const std::vector<Eigen::Vector3d>& normals() const { return normal_; }
  const std::vector<Eigen::Vector3d>& invDiagonal() const { return invPrecond_; }
  double rhsNorm2() const { return rhsNorm2_; }
  double gravityNorm2() const { return gravityNorm2_; }
  std::size_t freeCount() const { return freeCount_; }
  const PcgResult& lastSolve() const { return lastSolve_; }
  /// The goals of the sub-step's region pass at x_n (the contact pass's, as the explicit step's).
  const std::vector<Eigen::Vector3d>& goals() const override { return goals_; }

 private:
  /// begin()'s parts: the Poisson term's Hessian at x_n (volumetricLinear_), the drags in the
  /// system (a spring's stiffness on the diagonal, a hard drag's velocity prescribed), the
  /// Poisson term's diagonal added to the preconditioner.
  void linearizeVolumetric();
  void addDragsToSystem(double h);
  void addVolumetricPreconditioner(double h);
  /// After the solve (its residual b - A v at residual[offset + i]): the contacts' impulses, the
  /// rigid modes of a free object, v+ and x+, the contact pass.
  /// elapsed: the simulated time the sub-step advances, when it is not h (BDF2's solve of 2h/3);
  /// 0 for h.
  void end(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset, double elapsed = 0.0);
  /// Adds the Poisson term's Gauss-Newton Hessian times p, h^2 H_vol p, to y.
  void addVolumetricProduct(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) const;
  /// Counts each hard drag's impulse in the solve (its reaction on the prescribed rows) into it.
  void sumDragImpulses(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset);
  /// Restores the linear and angular momentum the external forces give (free object only).
  void correctRigidModes(double h);
  /// ImplicitScheme::Bdf2 at the start of a sub-step of length h: keeps (x_n, v_n) for the next
  /// one and, with the last sub-step's kept, moves x and v to BDF2's extrapolated start
  /// ((4 x_n - x_{n-1}) / 3, likewise v) and returns 2h/3, the backward Euler step from there
  /// that is BDF2's; without (the first sub-step, after reset() or a change of the state or the
  /// parameters) returns h: a backward Euler step.
  double bdf2Begin(double h);
  /// After a BDF2 sub-step of length h: a particle a contact, a pin or a hard drag moved keeps
  /// as its last state the one its present velocity gives, x - h v and v, so that it starts
  /// again from that velocity rather than extrapolating a motion the contact stopped.
  void bdf2End(double h);
  /// Assembles and factorises the preconditioner's coarse matrix for the sub-step h.
  void assembleCoarse(double h);
  /// Constrains the free particles that v_n + h g would carry into a collider (see
  /// solver_implicit_contact.cpp); returns whether any is.
  bool constrainContacts(double h);
  /// A free particle the solution carries into a collider joins the contact set (sticking, or
  /// sliding when it was let go of and comes back slipping); returns whether it joined.
  bool joinContact(std::size_t i, double h, double slop);
  /// phi - r of particle i at the start of the sub-step against contact body b at its pose then
  /// (negative: a penetration the sub-step did not make).
  double startDepth(std::size_t i, int b) const;
  /// The collider (index into the object's contact bodies, at body.now) x is deepest in,
  /// counting a depth phi - r below `within` (0: inside; a small positive value: touching), or
  /// -1; its depth, outward normal and surface velocity at x.
  int deepestContact(const Eigen::Vector3d& x, double within, Eigen::Vector3d& normal, double& depth,
                     Eigen::Vector3d& colliderVelocity) const;
  /// Every contact's impulse on its collider after the last solve.
  void sumContactImpulses(double h, const std::vector<Eigen::Vector3d>& residual, std::size_t offset);

  Solver& o_;  // the object stepped
  std::unique_ptr<CorotatedHessian> hessian_;
  /// PCG's preconditioner: Jacobi plus the aggregates' coarse solve
  std::unique_ptr<TwoLevelPreconditioner> coarse_;
  Pcg pcg_;
  PcgResult lastSolve_;  // the last sub-step's, iterations summed over its contact passes
  double h_ = 0.0;                      // the sub-step being solved (s)
  double floor_ = 0.0;                  // CG stops at this residual (begin())
  std::size_t freeCount_ = 0;           // particles not prescribed, and the squared
  double rhsNorm2_ = 0.0;               // P-norms of h f(x_n) and of M g h over them
  double gravityNorm2_ = 0.0;
  /// impulses another object gave the particles within the solve (endCoupled()), which
  /// correctRigidModes() counts as external; null when none
  const std::vector<Eigen::Vector3d>* couplingImpulse_ = nullptr;
  std::vector<double> weightSum_;           // sum_{r contains i} beta_r
  std::vector<Eigen::Vector3d> goals_;      // goals at the start of the sub-step
  std::vector<Eigen::Vector3d> rhs_;        // M v_n + h f(x_n)
  std::vector<Eigen::Vector3d> velocity_;   // v_{n+1}, the unknown
  std::vector<Eigen::Vector3d> diagonal_;   // M (1 + h c for a free object) + h^2 spring stiffness
  std::vector<Eigen::Vector3d> invPrecond_; // inverse of the Jacobi diagonal
  /// the last sub-step's v_{n+1} - v_n - h g (warm start: the next guess is v_n + h g + this)
  std::vector<Eigen::Vector3d> lastDv_;
  /// Fixed: pinned, hard-dragged or a sticking contact; Normal: a sliding contact (normal
  /// velocity prescribed)
  std::vector<PcgConstraint> constraint_;
  std::vector<Eigen::Vector3d> normal_;    // contact normal (Normal constraints)
  std::vector<int> contactBody_;           // the contact body of a contact, else -1
  /// per particle: no contact, sticking, sliding or released (pulling) in the last sub-step
  std::vector<char> contactState_;
  std::vector<Eigen::Vector3d> friction_;  // kinetic friction impulse of a sliding contact
  /// ImplicitScheme::Bdf2: x and v at the start of the last sub-step (x_{n-1}, v_{n-1} for the
  /// next), valid while bdf2Ready_
  std::vector<Eigen::Vector3d> bdf2LastX_, bdf2LastV_;
  bool bdf2Ready_ = false;
  bool bdf2Step_ = false;  // this sub-step solves BDF2 from its extrapolated start
  /// the largest change of a particle's goal - x over the last sub-step (cells), and each
  /// particle's goal - x at its start
  double bdf2GapChange_ = 0.0;
  std::vector<Eigen::Vector3d> bdf2LastGap_;
  Eigen::Vector3d bdf2P_, bdf2Spin_;  // its linear momentum and spin (about the centre of mass) at x_n
  /// Per stencil of the Poisson term at x_n: its difference vectors F_ia scaled by 1 / d_ia, and
  /// the weights of its Gauss-Newton Hessian (0 where the strain is clamped).
  struct VolumetricLinearisation {
    Eigen::Vector3d gradient[3];  // F_ia / d_ia
    double weight = 0.0;          // lambda V_i, or 0
    double deficit[3] = {0.0, 0.0, 0.0};
    double stretch[3] = {0.0, 0.0, 0.0};  // max(0, sigma_a) / d_a^2, sigma_a = w e + D_a e_aa
  };
  std::vector<VolumetricLinearisation> volumetricLinear_;
};

}  // namespace deformable_flsm
