/// @file object_contact.h
/// Contact between deformable objects, and of an object with itself, in one sub-step: the
/// particles are spheres (each object's Solver::contactRadius()), found near each other through
/// a spatial hash, and their contacts are resolved together with the colliders' contacts of the
/// same particles by projected Gauss-Seidel on impulses, with Coulomb friction. World runs it
/// after every object's sub-step; the pair and collider impulses it sums become the wrenches.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/collider_scene.h"
#include "deformable_flsm/core/implicit_coupling.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/spatial_hash.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {

struct ObjectContactParams;

/// What one object pair's contacts did over a step: the impulse on the object of the higher
/// index (b) from the lower (a), its moment about the origin, and the contacts of the last
/// sub-step.
struct PairImpulse {
  std::uint32_t a = 0, b = 0;
  Eigen::Vector3d impulse = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
  std::size_t contacts = 0;
};

/// What the object contact pass gave one object's particles against one collider over a step
/// (sum of m dv, and its moment about the collider's origin); its contacts are the object's
/// (Solver::touchCollider()).
struct ColliderImpulse {
  Eigen::Vector3d impulse = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();
};

/// A contact as a Gauss-Seidel pass updates it (ObjectContactSolver's passes, and pairUpdate() and
/// colliderUpdate() below): the constraint gap >= target at the end of the sub-step, linear in the
/// velocity corrections dv because a correction moves the end position by h dv.
struct ContactRow {
  Eigen::Vector3d n = Eigen::Vector3d::Zero();  // unit normal, from particle 2 (or the collider) to particle 1
  double offset = 0.0;  // the gap is n . (x1 - x2) - offset, or n . x1 - offset against a collider
  double target = 0.0;  // the least gap at the end of the sub-step: min(start gap, 0)
  double wsum = 0.0;    // w1 + w2 (w = 1 / m, 0 for a particle held still; w2 = 0 against a collider)
  double invW = 0.0, invHW = 0.0;  // 1 / wsum, 1 / (h wsum): prepare() sets them once per sub-step
  double muS = 0.0, muK = 0.0;     // static and kinetic friction coefficients
  double spring = 0.0;  // the implicit step's spring impulse that bounds friction (contact_update::springBound())
  double lambda = 0.0;  // accumulated normal impulse on particle 1 (N s, >= 0)
  Eigen::Vector3d friction = Eigen::Vector3d::Zero();  // accumulated friction impulse on particle 1 (N s)
  bool sliding = false;  // its friction reached its bound in the last sub-step: bounded by muK, else muS

  /// The divisions of every update, done once for a sub-step of length h.
  void prepare(double h) {
    invHW = 1.0 / (h * wsum);
    invW = 1.0 / wsum;
  }
};

/// What one update of a contact changes: its accumulated impulses, and the velocity corrections
/// of its particles (their end positions move by h dv).
struct ContactCorrection {
  bool applies = false;  // false: the contact neither pushes nor holds, and nothing changes
  double lambda = 0.0;   // the normal impulse after the update
  Eigen::Vector3d friction = Eigen::Vector3d::Zero();  // the friction impulse after the update
  Eigen::Vector3d impulse = Eigen::Vector3d::Zero();   // the change of particle 1's impulse, J
  Eigen::Vector3d dv1 = Eigen::Vector3d::Zero();       // w1 J
  Eigen::Vector3d dv2 = Eigen::Vector3d::Zero();       // -w2 J (zero against a collider)
};

namespace contact_update {

/// The normal impulse that brings the gap to the target, never pulling (Signorini).
inline double normal(const ContactRow& c, double gap) { return std::max(0.0, c.lambda + (c.target - gap) * c.invHW); }

/// A contact that neither pushes nor holds (most of those found within the margin) has nothing to apply.
inline bool idle(const ContactRow& c, double lambda) {
  return lambda == 0.0 && c.lambda == 0.0 && c.spring == 0.0 && c.friction.isZero(0.0);
}

/// Coulomb friction on the relative velocity u after the normal change: what stops u's tangential
/// part, within the regime's cone mu (lambda + spring), else scaled onto it.
inline Eigen::Vector3d friction(const ContactRow& c, double lambda, const Eigen::Vector3d& u) {
  const Eigen::Vector3d ut = u - u.dot(c.n) * c.n;
  Eigen::Vector3d f = c.friction - ut * c.invW;
  const double fn2 = f.squaredNorm(), cone = (c.sliding ? c.muK : c.muS) * (lambda + c.spring);
  if (fn2 > cone * cone) f *= cone / std::sqrt(fn2);
  return f;
}

/// The part of the implicit step's spring impulse on a pair that bounds its friction: a pulling
/// spring (lambda < 0) holds nothing.
inline double springBound(double lambda) { return std::max(0.0, lambda); }

}  // namespace contact_update

/// One projected Gauss-Seidel update of a contact between particles 1 and 2 (end positions x,
/// velocities v, inverse masses w): non-penetration, then friction on the relative velocity
/// after it, applied equal and opposite (momentum is conserved). The masses are read only by a
/// contact that is not idle (references: no load for most contacts of a pass).
inline ContactCorrection pairUpdate(const ContactRow& c, const Eigen::Vector3d& x1, const Eigen::Vector3d& v1,
                                    const double& w1, const Eigen::Vector3d& x2, const Eigen::Vector3d& v2,
                                    const double& w2) {
  ContactCorrection r;
  r.lambda = contact_update::normal(c, c.n.dot(x1 - x2) - c.offset);
  if (contact_update::idle(c, r.lambda)) return r;
  Eigen::Vector3d J = (r.lambda - c.lambda) * c.n;
  r.friction = contact_update::friction(c, r.lambda, v1 + w1 * J - Eigen::Vector3d(v2 - w2 * J));
  J += r.friction - c.friction;
  r.applies = true;
  r.impulse = J;
  r.dv1 = w1 * J;
  r.dv2 = -(w2 * J);
  return r;
}

/// The same update of a contact between particle 1 and a collider's surface moving at vc.
inline ContactCorrection colliderUpdate(const ContactRow& c, const Eigen::Vector3d& x1, const Eigen::Vector3d& v1,
                                        const double& w1, const Eigen::Vector3d& vc) {
  ContactCorrection r;
  r.lambda = contact_update::normal(c, c.n.dot(x1) - c.offset);
  if (contact_update::idle(c, r.lambda)) return r;
  Eigen::Vector3d J = (r.lambda - c.lambda) * c.n;
  r.friction = contact_update::friction(c, r.lambda, v1 + w1 * J - vc);
  J += r.friction - c.friction;
  r.applies = true;
  r.impulse = J;
  r.dv1 = w1 * J;
  return r;
}

class ObjectContactSolver {
 public:
  /// Clears the step's sums for `objects` objects and `colliders` colliders.
  void beginStep(std::size_t objects, std::size_t colliders);

  /// Makes the next substep() rebuild its candidate list: call when an object is added or
  /// removed (a new object could take a removed one's place in memory).
  void invalidate() { built_ = false; }

  /// How many times the candidate list was built (for all objects or for some) since this
  /// solver was made.
  std::size_t listBuilds() const { return listBuilds_; }
  /// How many Gauss-Seidel passes over the contacts the sub-steps with contacts ran, and how
  /// many such sub-steps, since this solver was made.
  std::size_t solvePasses() const { return passes_; }
  std::size_t solvedSubsteps() const { return solves_; }
  /// Where substep() and refreshList() spend their time, a figure for benchmarks: the calling
  /// thread's CPU seconds since the solver was made, while timing was on (off by default:
  /// reading that clock is a system call, a few of them per sub-step), in kListSeconds the
  /// candidate list's checks and builds, kPairSeconds finding the contacts among the
  /// candidates, kPassSeconds the Gauss-Seidel passes, kRestSeconds the rest (gathering, warm
  /// start, collider contacts, keeping the impulses, push-out, scattering, the sums, the
  /// implicit step's spring impulses taken in).
  enum { kListSeconds, kPairSeconds, kPassSeconds, kRestSeconds };
  void setTiming(bool on) { timing_ = on; }
  const std::array<double, 4>& seconds() const { return seconds_; }
  /// The candidate pairs of the last substep() (for tests): particles by their global numbers
  /// (object o's particle i is i plus the particles of the objects before o), the lower first.
  const std::vector<std::pair<std::uint32_t, std::uint32_t>>& candidatePairs() const { return keys_; }

  /// The candidate list as substep() left it, in global numbers, when it was built for these
  /// objects and parameters: what ImplicitCoupling makes its springs of before the objects'
  /// sub-step; nullptr otherwise. (Positions set between steps, a reset, are not checked: the
  /// springs then miss for one sub-step the pairs the contact pass after the solve still finds.)
  const std::vector<std::pair<std::uint32_t, std::uint32_t>>* currentCandidates(
      const std::vector<Solver*>& objects, const ObjectContactParams& params) const;
  /// Before ImplicitCoupling's sub-step of length h: builds the list again for the objects whose
  /// particles would leave their allowances moving on at their velocities, so that
  /// currentCandidates() stays the list of the pass after the solve unless the solve carries a
  /// particle farther (the springs' impulses then bound their pairs' friction in that pass).
  void refreshList(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h);
  /// The impulses the implicit step's contact springs carried in this sub-step (nullptr: none),
  /// for the next substep(): they bound the friction of their pairs as the pass's own normal
  /// impulses do, and count into the pair wrenches. The list must live until then.
  void setCouplingImpulses(const std::vector<CouplingImpulse>* impulses) { coupling_ = impulses; }
  /// Per object, whether it is held still in this step (a World's sleeping object): its
  /// particles take part as immovable (infinite mass), so the others rest on it or bounce off
  /// it and nothing of it moves. nullptr (or a shorter list): none. The list must live until
  /// the next substep().
  void setAsleep(const std::vector<char>* asleep) { asleep_ = asleep; }

  /// The contact pass after every object's sub-step of length h:
  ///  1. a candidate list of particle pairs (a Verlet list: Verlet 1967), kept over sub-steps
  ///     and steps while every particle stays within its allowance (a fraction of its radius,
  ///     more for a fast one) of its anchor, measured against its own object's motion (the mean
  ///     of its particles), and every two objects near each other within their allowance of
  ///     where they were relative to each other (object_contact_list.cpp): a pile that falls or
  ///     slides as one keeps its list. Built again for the objects that left them, the pairs of
  ///     two other objects kept: a broad phase of each object's bounds (a sweep) pairs the
  ///     objects, and per pair with a rebuilt object only the particles within reach of the
  ///     other's bounds are swept against each other (an object's own particles are never
  ///     visited), giving the pairs closer than the sum of their reaches and allowances; with
  ///     params.selfContact, a spatial hash of a rebuilt object's particles gives its pairs
  ///     farther apart than params.selfExclusion cells in its rest lattice. The list is kept in
  ///     the order of its particles' global numbers, whatever builds made it;
  ///  2. of the candidates, the pairs closer than the sum of their radii with the margin at the
  ///     end or at the start of the sub-step (a sphere that passed through another is caught);
  ///     each particle in such a pair also gets a contact with every collider it touches, so
  ///     that an object pressed onto the ground by another is held by the ground in the same
  ///     solve;
  ///  3. projected Gauss-Seidel over the contacts in a fixed order (see object_contact.cpp);
  ///  4. penetration left (from a start, a large step, a collider pushing) pushed out by
  ///     position only, at most kPushPace of the smaller radius per sub-step.
  /// @param[in,out] objects    the objects, their states after their own sub-step
  /// @param[in]     colliders  the colliders at this sub-step, in the same order as for
  ///                           beginStep()
  /// @param[in]     last       whether this is the step's last sub-step (the contacts counted)
  void substep(const std::vector<Solver*>& objects, const std::vector<PosedCollider>& colliders,
               const ObjectContactParams& params, double h, bool last);

  /// The object pairs whose contacts carried an impulse in the step, in increasing (a, b).
  const std::vector<PairImpulse>& pairImpulses() const { return pairs_; }
  /// What object o's particles got from collider c in this pass over the step.
  const ColliderImpulse& colliderImpulse(std::size_t o, std::size_t c) const {
    return colliderImpulses_[o * colliderCount_ + c];
  }
  /// Sorts pairImpulses() by (a, b): call at the end of the step (the next beginStep() clears
  /// them).
  void endStep();

 private:
  using Key = std::pair<std::uint32_t, std::uint32_t>;  // a particle pair by global numbers, the lower first
  /// A contact's impulses kept for the next sub-step's warm start.
  struct Impulses {
    double lambda = 0.0;
    Eigen::Vector3d friction = Eigen::Vector3d::Zero();
    bool sliding = false;
  };
  /// Whether a contact carries an impulse, to warm-start from or to keep.
  static bool carries(double lambda, const Eigen::Vector3d& friction) { return lambda != 0.0 || !friction.isZero(0.0); }
  /// A contact of two particles, by their places k1, k2 in the gathered arrays.
  struct PairContact : ContactRow {
    std::uint32_t k1 = 0, k2 = 0;
    std::uint32_t slot = 0;  // its candidate pair
  };
  /// A contact of a particle (its place k in the gathered arrays) with a collider.
  struct ColliderContact : ContactRow {
    std::uint32_t k = 0;
    std::uint32_t collider = 0;  // the collider's index
    Eigen::Vector3d vc = Eigen::Vector3d::Zero();  // the collider's surface velocity at the particle
  };
  /// A collider contact's impulses kept for the next sub-step, by the particle's global number.
  struct KeptImpulse {
    std::uint32_t g = 0, collider = 0;
    Impulses impulses;
  };
  /// A pair's impulses carried over a build by its particles' pair (see carryAsleepPairImpulses()).
  struct Carried {
    Key key;
    Impulses impulses;
  };
  enum class Staleness { kNone, kSome, kAll };

  // --- the candidate list (object_contact_list.cpp) ---
  /// Marks in stale_ the objects whose particles left their allowances; kAll when the objects
  /// or the parameters changed since the build.
  /// `ahead`: 0 after the objects' sub-step (positions x, the sub-step began at x - h v); h
  /// before it, for the motion to come (x + h v, x).
  Staleness findStale(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h, double ahead);
  /// findStale(), then buildList() for what it found, with the same `ahead`; returns what it found.
  Staleness updateList(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h, double ahead);
  /// Builds the list again for the stale objects (all of them with `all`), anchors at the middle
  /// of the motion findStale() checked with the same `ahead`.
  void buildList(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h, bool all,
                 double ahead);
  void carryAsleepPairImpulses(bool all);
  void resetList(const std::vector<Solver*>& objects, const ObjectContactParams& params);
  void anchorStale(const std::vector<Solver*>& objects, double h, double ahead);
  void findObjectPairs(const ObjectContactParams& params, double h);
  std::size_t hashSelfContact(const ObjectContactParams& params);
  std::size_t keepPairsOfSettledObjects();
  /// A particle in a sweep of one object pair: its anchor shifted to where its object is, its
  /// reach + allowance + its object's share of the pair's allowance, its global number.
  struct SweepEntry {
    Eigen::Vector3d x = Eigen::Vector3d::Zero();
    double ball = 0.0;
    std::uint32_t g = 0;
  };
  void searchObjectPairs();
  double selectNear(std::uint32_t o, std::uint32_t other, int axis, std::vector<SweepEntry>& out);
  void searchSelfContact(const std::vector<Solver*>& objects, const ObjectContactParams& params, std::size_t hashed);
  void orderNewPairs(std::size_t kept);
  void mergeKeptAndNew(std::size_t kept);
  void restoreImpulses(std::size_t kept, bool all);
  void renumberParticles();
  /// awakeSlots_ and awakeParticles_ for the list and the sleeping objects of this sub-step
  /// (worked out again only when either changed since the last call)
  void selectAwake();
  bool builtFor(const std::vector<Solver*>& objects, const ObjectContactParams& params) const;

  // --- the passes (object_contact.cpp) ---
  void gather(const std::vector<Solver*>& objects, double h);
  void findPairs(const ObjectContactParams& params);
  void findColliderContacts(const std::vector<PosedCollider>& colliders, double h);
  void warmStart(double h);
  /// @return the passes it ran
  int solve(double h, int iterations);
  void keep();
  static bool slides(const ContactRow& c);
  static Impulses keptOf(const ContactRow& c) { return {c.lambda, c.friction, slides(c)}; }
  static void resume(ContactRow& c, const Impulses& kept);
  void move(std::uint32_t k, const Eigen::Vector3d& dv, double h) {
    v_[k] += dv;
    x_[k] += h * dv;
  }
  void pushOut();
  void scatter(const std::vector<Solver*>& objects);
  void accumulate(const std::vector<Solver*>& objects, const std::vector<PosedCollider>& colliders, bool last);
  PairImpulse& pairSlot(std::uint32_t a, std::uint32_t b);
  PairImpulse& addPairWrench(std::uint32_t o1, std::uint32_t o2, const Eigen::Vector3d& x1,
                             const Eigen::Vector3d& x2, double r1, double r2, const Eigen::Vector3d& J);
  /// The coupling impulses into springLambda_ (by candidate slot, when the list was not built
  /// again since they were found; refreshList() makes that rare: in a sub-step with a build the
  /// springs bound no friction) and into the pair sums.
  void takeCoupling(const std::vector<Solver*>& objects, bool rebuilt, bool last);

  const std::vector<CouplingImpulse>* coupling_ = nullptr;
  const std::vector<char>* asleep_ = nullptr;
  bool asleep(std::uint32_t object) const {
    return asleep_ != nullptr && object < asleep_->size() && (*asleep_)[object] != 0;
  }
  /// keptCollider_ without the entries of objects that are not asleep (scratch: keptScratch_)
  void keepAsleepColliderImpulses();
  std::vector<KeptImpulse> keptScratch_;
  /// over a build (buildList()), the impulses of the pairs of a stale object with a sleeping one,
  /// which its search may find again (the kept pairs carry theirs in place), sorted by pair
  std::vector<Carried> carried_;
  std::vector<double> springLambda_;  // per candidate slot, this sub-step's spring impulse
  /// the particle pairs whose spring pushed in the step's last sub-step, sorted: a pair contact
  /// of the passes among them is not counted again (accumulate())
  std::vector<Key> pushingSprings_;

  // the candidate list (a Verlet list): what it was built for, and every particle's anchor
  bool built_ = false;
  std::size_t listBuilds_ = 0;
  std::size_t passes_ = 0, solves_ = 0;
  bool timing_ = false;
  std::array<double, 4> seconds_{};
  bool builtEnabled_ = false, builtSelf_ = false;
  int builtExclusion_ = 0;
  std::vector<const Solver*> builtObjects_;
  std::vector<double> builtRadius_;
  std::vector<std::size_t> offset_;      // per object, its first particle's global number (#objects + 1)
  std::vector<std::uint32_t> owner_;     // per particle (global number), its object
  std::vector<Eigen::Vector3d> anchor_;  // every particle's mid-sub-step position at its object's build
  std::vector<double> allowance_;        // how far each particle may move from its anchor
  std::vector<char> stale_;              // per object, whether its anchors are built again
  // the candidate pairs (anchors closer than reach + allowance, summed): by global numbers, and
  // by their places in the gathered arrays
  std::vector<Key> keys_, candidates_;
  std::vector<std::uint32_t> scratch_;   // the buckets of a wide search
  std::vector<SweepEntry> sweepA_, sweepB_;  // the two sides of an object pair's sweep
  std::vector<std::uint32_t> firstCount_;  // scratch of orderNewPairs(): a counting sort's counts
  std::vector<Key> keyScratch_;            // and its output, and mergeKeptAndNew()'s
  std::vector<Impulses> impulseScratch_;
  // the particles hashed in a build: global number, object, anchor, reach + allowance
  std::vector<std::uint32_t> hashGlobal_, hashObject_;
  std::vector<Eigen::Vector3d> hashX_;
  std::vector<double> hashBall_;
  // the last sub-step's impulses: per candidate pair (over a build, only those of a pair with a
  // sleeping object), and per collider contact in (global number, collider) order
  std::vector<Impulses> keptPairs_;
  std::vector<KeptImpulse> keptCollider_;
  // per object, at the build
  std::vector<Eigen::Vector3d> lo_, hi_;  // bounds of the anchors inflated by reach_ + the largest allowance
  std::vector<double> radius_, reach_;    // contact radius, and radius with the margin
  std::vector<double> most_;              // the largest allowance of its particles
  std::vector<Eigen::Vector3d> meanV_;  // its particles' mean velocity (at the last check or build)
  // how far the mean of its particles moved from its anchors', at the end and the start of the
  // sub-step checked last, and in the middle; the least and most of the end and start
  std::vector<Eigen::Vector3d> shiftEnd_, shiftStart_, shiftMid_, shiftLo_, shiftHi_;
  std::vector<double> fastest_;  // scratch: its fastest motion relative to an object near it, per sub-step
  std::vector<double> half_;  // its share of its pairs' allowance for drifting (each particle's ball holds it)
  std::vector<std::uint32_t> order_;  // objects by their lower x bound
  // the pairs of objects whose bounds met (a < b, sorted), with the shift of a relative to b when
  // their pairs were searched and how far it may drift from it (and the last build's, scratch)
  using ObjectPair = std::pair<std::uint32_t, std::uint32_t>;
  std::vector<ObjectPair> objectPairs_, oldPairs_, newPairs_;
  std::vector<Eigen::Vector3d> pairShift_, oldShift_;
  std::vector<double> pairSlack_, oldSlack_;
  std::vector<std::int32_t> renumber_;  // per particle (global number), its place in the list or -1
  // the particles of the candidate list, object by object, each object's in index order
  std::size_t count_ = 0;
  std::vector<std::uint32_t> global_, object_, index_;
  std::vector<Eigen::Vector3d> x_, v_;
  std::vector<double> w_, r_;
  std::vector<Eigen::Vector3d> start_;  // x - h v: where the particles began the sub-step
  std::vector<char> touched_;
  // the part of the list the passes visit: the candidates with an object not asleep (their slots
  // in candidates_, ascending), the particles they name (ascending), and what they were chosen for
  std::vector<std::uint32_t> awakeSlots_, awakeParticles_;
  std::vector<char> slotsAsleep_;
  std::size_t awakeBuild_ = 0;  // listBuilds_ when they were chosen (the passes run after a build: 1 or more)
  // per object, whether its last check found it asleep, at rest (every velocity zero) and within
  // its allowances, and the state it checked (Solver::stateVersion()): while it stays so, its
  // particles are not visited again (findStale())
  std::vector<char> restChecked_;
  std::vector<std::uint64_t> restVersion_;
  SpatialHash hash_;  // of the anchors, at the build
  std::vector<ColliderContact> colliderContacts_;  // solved first: the support below settles before the pairs above
  std::vector<PairContact> contacts_;
  // the step's sums
  std::size_t colliderCount_ = 0;
  std::vector<ColliderImpulse> colliderImpulses_;  // #objects x #colliders
  std::vector<PairImpulse> pairs_;
  std::vector<std::int32_t> pairTable_;  // open addressing: index into pairs_, or -1
};

}  // namespace deformable_flsm
