/// @file implicit_coupling.h
/// The implicit sub-step of several objects solved as one system: each object's backward Euler
/// system (Solver's, with its collider contacts, pins and drags) plus one-sided springs between
/// the particles of different objects (or of one object, with self-contact) that touch, in one
/// preconditioned conjugate-gradient solve. World runs it for its implicit objects, before the
/// object contact pass, which then keeps the particles apart and adds the friction between them.
#pragma once

#include "deformable_flsm/core/pcg.h"

#include <Eigen/Core>

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

namespace deformable_flsm {

class Solver;

/// A contact spring's impulse over the last sub-step, for the object contact pass (friction,
/// wrenches): on particle g1 from g2 (global numbers, World's order), lambda n; lambda < 0 for
/// a spring the solve's last pass left pulling.
struct CouplingImpulse {
  std::uint32_t g1 = 0, g2 = 0;
  std::uint32_t slot = 0;  // its place in the candidate list it was made from
  Eigen::Vector3d n = Eigen::Vector3d::Zero();
  double lambda = 0.0;  // N s
};

/// The coupling's contact spring between two particles, as pure functions (each tested alone,
/// test_implicit_coupling): a one-sided spring along n, at rest a skin outside the spheres'
/// touching distance, as stiff as the material about it.
namespace coupling_spring {

/// The spring is at rest this fraction of r_1 + r_2 outside the spheres' touching distance.
constexpr double kSkin = 0.05;
/// h^2 k is kStiffness times the reduced diagonal of its particles' systems (mass, damping and the
/// material's stiffness bound: as stiff as the material about it, a little more), at most
/// kMassCap times their reduced mass. Stiffer springs spread the system's spectrum and cost CG
/// iterations; the cap keeps a stiff material's springs from pushing a pair that strayed inside
/// the skin out faster than the speed that closes it in one sub-step (docs/method.md).
constexpr double kStiffness = 3.0;
constexpr double kMassCap = 100.0;

/// The normal from particle 2 to particle 1 and the gap less the skin, at centres x1, x2 with
/// radii r1, r2; false when the centres met (the contact pass sorts that out).
inline bool geometry(const Eigen::Vector3d& x1, double r1, const Eigen::Vector3d& x2, double r2, Eigen::Vector3d& n,
                     double& gap) {
  const Eigen::Vector3d d = x1 - x2;
  const double len = d.norm();
  const double R = r1 + r2;
  if (!(len > 1e-9 * R)) return false;
  n = d / len;
  gap = len - R * (1.0 + kSkin);
  return true;
}

/// h^2 k of a spring between particles whose systems' diagonals are d1, d2 and masses m1, m2; a
/// fixed particle (its velocity prescribed) leaves the other's alone.
inline double stiffness(double d1, double m1, bool fixed1, double d2, double m2, bool fixed2) {
  const double reducedD = fixed1 ? d2 : fixed2 ? d1 : d1 * d2 / (d1 + d2);
  const double reducedM = fixed1 ? m2 : fixed2 ? m1 : m1 * m2 / (m1 + m2);
  return std::min(kStiffness * reducedD, kMassCap * reducedM);
}

/// The gap (less the skin) at the end of a sub-step h from `gap`, the particles' relative velocity
/// along n being n . dv (dv = v1 - v2).
inline double gapAfter(double gap, const Eigen::Vector3d& n, const Eigen::Vector3d& dv, double h) {
  return gap + h * n.dot(dv);
}

/// One-sided: an active spring whose gap ends above the skin (it pulls) lets go; an inactive one
/// that the solution carries within the skin joins.
inline bool activeAfter(bool active, double gapAfter) { return active ? !(gapAfter > 0.0) : gapAfter < 0.0; }

/// h times the force the spring applies on particle 1 along n (negative: pulling).
inline double impulse(double k, double gapAfter, double h) { return -k * gapAfter / h; }

}  // namespace coupling_spring

class ImplicitCoupling {
 public:
  /// One implicit sub-step s of length h of the objects marked in `coupled` (Integrator::Implicit;
  /// the others are left alone), as one system:
  ///   A_o v_o + sum_springs h^2 k n n^T (v_1 - v_2) = b_o - (h k)(gap - skin) n   (per object o)
  /// with A_o, b_o each object's (Solver::beginCoupledSubstep()), and a spring for each candidate pair
  /// (`candidates`, global particle numbers in World's order: object o's particle i is
  /// offset[o] + i) whose gap at the end of the sub-step, x + h v with v = v_n (gravity's
  /// increment left out: the same for two free particles of one world; a pair with a pinned
  /// particle is caught by the solution, one pass later), is predicted below the skin:
  /// gap = n . (x_1 - x_2) - (r_1 + r_2), n the
  /// direction between the particles at the start of the sub-step. One-sided, by an active set
  /// shared with each object's collider contacts: a spring whose solution gap ends above the
  /// skin (it pulls) is let go of, a pair the solution carries into each other joins.
  /// A pair of a coupled object and a sleeping one (`asleep`, World's sleeping objects: not
  /// stepped) has its spring too, the sleeping particle held where it is (velocity 0), as a
  /// collider contact holds a particle: the sleeping object carries what rests on it within the
  /// solve.
  /// @param pairCandidates  of the object contact pass's list (ObjectContactSolver), valid for
  ///                        the objects' positions now; a pair has a spring when both its
  ///                        objects are coupled or one is coupled and the other asleep (none
  ///                        with an awake object that is not coupled, or two asleep)
  /// @param asleep  per object, 1 for a sleeping one (may be null: none)
  void substep(const std::vector<Solver*>& objects, const std::vector<char>& coupled,
               const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairCandidates, int s, double h,
               const std::vector<char>* asleep = nullptr);

  /// The springs that carried an impulse in the last substep().
  const std::vector<CouplingImpulse>& impulses() const { return impulses_; }

 private:
  struct Spring {
    std::uint32_t row1 = 0, row2 = 0;  // rows of the joint system (places in the solve's vectors)
    std::uint32_t o1 = 0, o2 = 0;   // objects
    std::uint32_t i1 = 0, i2 = 0;   // particles of their objects
    std::uint32_t slot = 0;         // candidate index
    Eigen::Vector3d n = Eigen::Vector3d::Zero();
    double gap = 0.0;    // at the start of the sub-step, less the skin
    double k = 0.0;      // h^2 times the stiffness
    bool active = false;
  };
  // substep()'s stages:
  /// members_, start_, globalStart_ and place_ for the coupled objects; the vectors sized
  void placeMembers(const std::vector<Solver*>& objects, const std::vector<char>& coupled);
  /// each member's system (Solver::beginCoupledSubstep()); returns the joint solve's floor
  double beginMembers(const std::vector<Solver*>& objects, int s, double h);
  /// springs_ (and held_) for the candidate pairs, active where predicted within the skin
  void buildSprings(const std::vector<Solver*>& objects,
                    const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairCandidates, double h,
                    const std::vector<char>* asleep);
  /// the joint solve with the members' contacts and the springs in one active set; each member's
  /// implicitVelocity() set; the last pass's result with the iterations of all passes
  PcgResult solve(const std::vector<Solver*>& objects, double h, double floor);
  /// the active springs' impulses on the members (impulseOn_) and in impulses_
  void sumSpringImpulses(double h);
  void gather(const std::vector<Solver*>& objects);
  void product(const std::vector<Solver*>& objects, const std::vector<Eigen::Vector3d>& p,
               std::vector<Eigen::Vector3d>& y);
  void precondition(const std::vector<Solver*>& objects, const std::vector<Eigen::Vector3d>& r,
                    std::vector<Eigen::Vector3d>& z);
  /// For each member: its segment of `in` into in_[m], apply(solver, m) (which fills out_[m]),
  /// out_[m] into its segment of `out`.
  template <class Apply>
  void perMember(const std::vector<Solver*>& objects, const std::vector<Eigen::Vector3d>& in,
                 std::vector<Eigen::Vector3d>& out, Apply&& apply);
  /// A spring for candidate `slot` (sp: its objects and particles) when one of its objects is
  /// coupled and the other asleep, into held_.
  void holdSpring(const std::vector<Solver*>& objects, const std::vector<char>& asleep, Spring sp, std::size_t slot,
                  double h);
  /// The spring's impulse lambda n on particle 1 into impulses_ (global numbers).
  void recordImpulse(const Spring& sp, double lambda);
  /// The springs' active set after a solve; returns whether it changed.
  bool updateSprings(double h);

  std::vector<std::uint32_t> members_;  // the coupled objects
  std::vector<std::size_t> start_;      // per object, its first coupled number (members only)
  std::size_t size_ = 0;
  Pcg pcg_;
  std::vector<Eigen::Vector3d> velocity_, rhs_, normal_, springDiagonal_;
  std::vector<PcgConstraint> constraint_;
  std::vector<std::vector<Eigen::Vector3d>> in_, out_, inv_;  // per member: its segments
  /// per member: the springs' impulse on each particle in the last solve (m dv, N s)
  std::vector<std::vector<Eigen::Vector3d>> impulseOn_;
  std::vector<Spring> springs_;
  /// the springs to sleeping objects: particle 2 (o2, i2) held still, row2 unused
  std::vector<Spring> held_;
  std::vector<CouplingImpulse> impulses_;
  std::vector<std::size_t> globalStart_;  // per object, its first global number
  std::vector<std::int64_t> place_;       // per object, its place among the members or -1
  double h_ = 0.0;
};

}  // namespace deformable_flsm
