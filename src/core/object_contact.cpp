// Contact between deformable objects and of an object with itself (see object_contact.h).
//
// The passes that update the contacts (the candidate list is object_contact_list.cpp; the per-contact
// arithmetic is pairUpdate() and colliderUpdate() in object_contact.h).
// Each contact is a constraint on the gap at the end of the sub-step, linear in the velocity
// corrections because a correction dv moves the end position by h dv (x = x_start + h v):
//   pair      g = n . (x1 - x2) - (r1 + r2),   n the unit direction from x2 to x1 at the start
//                                              of the sub-step (x - h v)
//   collider  g = n . x1 - offset,             n the collider's outward normal at x1, offset so
//                                              that g = phi(x1) - r1 (the surface as a plane)
// and asks g >= min(g_start, 0): a particle that came from outside ends touching, one that was
// already inside (penetration from a start, a large step, a collider's push) goes no deeper;
// its old penetration becomes no velocity (see contactVelocityChange() in contact.h for why)
// and is pushed out by position after the solve, at a bounded pace.
// The normal impulse lambda >= 0 and the friction impulse f (tangential, |f| <= mu lambda) of
// each contact are found by projected Gauss-Seidel with accumulated impulses (Catto 2005,
// "Iterative Dynamics with Temporal Coherence"; Erleben 2007): per contact in a fixed order,
//   dlambda = (target - g) / (h (w1 + w2)),  lambda <- max(0, lambda + dlambda)
//   f <- f - u_t / (w1 + w2), u_t the tangential relative velocity; kept if |f| <= mu_s lambda
//   (static friction: the contact sticks), else scaled to mu_s lambda; a contact whose friction
//   reached its bound in the last sub-step slides in this one, bounded by mu_k lambda, until its
//   friction falls below that bound. The regime changes between sub-steps only, so that resting
//   contacts do not stick and slip by turns while the passes' normal impulses converge.
// and each change dJ is applied equal and opposite, dv1 = w1 dJ, dv2 = -w2 dJ (w = 1/m, 0 for
// a pinned or hard-dragged particle): linear momentum is conserved exactly. A pair's normal
// impulse lies along the line of the particles at the start of the sub-step, where the
// symplectic step's kick acts (x_end = x_start + h v_end), so frictionless contact conserves
// angular momentum exactly too; a friction impulse between two particle centres 2r apart is a
// couple the particles cannot spin with (they carry no rotation), of at most 2 r |f|.
#include "deformable_flsm/core/object_contact.h"

#include "object_contact_internal.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/world.h"

#include <algorithm>
#include <ctime>
#include <limits>
#include <cmath>
#include <initializer_list>

namespace deformable_flsm {

using object_contact::kContactMargin;
using object_contact::reserveDoubling;

namespace {

/// Penetration up to this fraction of r1 + r2 (of r for a collider) is left alone by the
/// position push (Box2D's "linear slop"): resting contacts are not pushed every sub-step,
/// which would shake a stack. The velocity solve still lets none of them grow.
constexpr double kPenetrationSlop = 0.01;
/// Old penetration is pushed out by at most this fraction of the smaller radius per sub-step,
/// by position only (as the collider pass bounds its own at the radius).
constexpr double kPushPace = 0.5;
/// The passes stop when one after the first changed no relative velocity by more than this fraction of the
/// least radius per sub-step. The first pass of a sub-step corrects its warm start: stopped there, a light
/// corner particle of a resting pile whose warm start came from the other phase of a sub-step-to-sub-step
/// tremble kept trembling for good, and a stack pushed and let go never fell asleep.
constexpr double kSolveTolerance = 1e-3;

/// The calling thread's CPU time (s): what the work took, not how long it waited for a core.
double threadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

/// Splits the time between laps among the parts (nothing when `seconds` is null); the rest after the last lap.
class Laps {
 public:
  explicit Laps(std::array<double, 4>* seconds) : seconds_(seconds), last_(seconds ? threadSeconds() : 0.0) {}
  ~Laps() { lap(ObjectContactSolver::kRestSeconds); }
  Laps(const Laps&) = delete;
  Laps& operator=(const Laps&) = delete;
  void lap(int part) {
    if (seconds_ == nullptr) return;
    const double now = threadSeconds();
    (*seconds_)[static_cast<std::size_t>(part)] += now - last_;
    last_ = now;
  }

 private:
  std::array<double, 4>* seconds_;
  double last_;
};

/// A contact's whole impulse on its particle 1: what the warm start applies and the sums count.
Eigen::Vector3d impulseOf(const ContactRow& c) { return c.lambda * c.n + c.friction; }

/// A particle pair by global numbers, the lower first: how the list and the springs name it.
std::pair<std::uint32_t, std::uint32_t> keyOf(std::uint32_t g1, std::uint32_t g2) {
  return {std::min(g1, g2), std::max(g1, g2)};
}

}  // namespace

// The step's sums start from zero.
void ObjectContactSolver::beginStep(std::size_t objects, std::size_t colliders) {
  colliderCount_ = colliders;
  colliderImpulses_.assign(objects * colliders, ColliderImpulse());
  pairs_.clear();
  std::fill(pairTable_.begin(), pairTable_.end(), -1);
}

// The pass after every object's sub-step (see object_contact.h).
void ObjectContactSolver::substep(const std::vector<Solver*>& objects, const std::vector<PosedCollider>& colliders,
                                  const ObjectContactParams& params, double h, bool last) {
  for (PairImpulse& p : pairs_) p.contacts = 0;
  if (!params.enabled && !params.selfContact) return;
  Laps laps(timing_ ? &seconds_ : nullptr);
  const Staleness stale = updateList(objects, params, h, 0.0);
  laps.lap(kListSeconds);
  takeCoupling(objects, stale != Staleness::kNone, last);
  if (candidates_.empty()) return;
  selectAwake();
  gather(objects, h);
  laps.lap(kRestSeconds);
  findPairs(params);
  laps.lap(kPairSeconds);
  if (contacts_.empty()) {
    keepAsleepColliderImpulses();  // nothing else to warm-start the next sub-step's collider contacts from
    return;
  }
  findColliderContacts(colliders, h);
  warmStart(h);
  laps.lap(kRestSeconds);
  passes_ += static_cast<std::size_t>(solve(h, params.iterations));
  ++solves_;
  laps.lap(kPassSeconds);
  keep();
  pushOut();
  scatter(objects);
  accumulate(objects, colliders, last);
}

// Built for the motion to come, so that the springs made from the list keep their slots through the pass after it.
void ObjectContactSolver::refreshList(const std::vector<Solver*>& objects, const ObjectContactParams& params,
                                      double h) {
  if (!params.enabled && !params.selfContact) return;
  Laps laps(timing_ ? &seconds_ : nullptr);
  updateList(objects, params, h, h);
  laps.lap(kListSeconds);
}

// The passes work on copies of the listed particles' state, in dense arrays.
void ObjectContactSolver::gather(const std::vector<Solver*>& objects, double h) {
  for (const std::uint32_t k : awakeParticles_) {
    const Solver& s = *objects[object_[k]];
    const std::uint32_t i = index_[k];
    x_[k] = s.positions()[i];
    v_[k] = s.velocities()[i];
    start_[k] = x_[k] - h * v_[k];
    w_[k] = asleep(object_[k]) || s.isPrescribed(i) ? 0.0 : 1.0 / s.lattice().masses()[i];
    r_[k] = radius_[object_[k]];
    touched_[k] = 0;
  }
}

// Candidates within reach at the end or the start of the sub-step: one that passed through another is caught.
void ObjectContactSolver::findPairs(const ObjectContactParams& params) {
  contacts_.clear();
  // two objects held still (not among the awake slots): no contact, and the impulses they had kept for when one wakes
  for (const std::uint32_t i : awakeSlots_) {
    const std::uint32_t k1 = candidates_[i].first, k2 = candidates_[i].second;
    // the last sub-step's impulses, read once (keep() writes this sub-step's contacts' back)
    const Impulses kept = keptPairs_[i];
    keptPairs_[i] = Impulses();
    const double wsum = w_[k1] + w_[k2];
    if (!(wsum > 0.0)) continue;  // both prescribed (or held still)
    const double R = r_[k1] + r_[k2];
    const double near2 = R * R * (1.0 + kContactMargin) * (1.0 + kContactMargin);
    const Eigen::Vector3d end = x_[k1] - x_[k2];
    const Eigen::Vector3d start = start_[k1] - start_[k2];
    // only a relative motion of more than twice the reach in one sub-step passes unseen
    if (end.squaredNorm() >= near2 && start.squaredNorm() >= near2) continue;
    PairContact c;
    c.k1 = k1;
    c.k2 = k2;
    double len = start.norm();
    if (len > 1e-9 * R) {
      c.n = start / len;
    } else {  // centres met at the start: the end positions' direction, or any
      c.n = end.norm() > 1e-9 * R ? Eigen::Vector3d(end.normalized()) : Eigen::Vector3d::UnitZ();
      len = c.n.dot(start);
    }
    c.offset = R;
    c.target = std::min(len - R, 0.0);
    c.wsum = wsum;
    c.muS = params.staticFriction;
    c.muK = params.kineticFriction;
    c.slot = static_cast<std::uint32_t>(i);
    if (!springLambda_.empty()) c.spring = springLambda_[i];
    resume(c, kept);
    contacts_.push_back(c);
    touched_[k1] = touched_[k2] = 1;
  }
}

// A particle pressed onto the ground by another object is held by the ground in this solve, not a sub-step later.
void ObjectContactSolver::findColliderContacts(const std::vector<PosedCollider>& colliders, double h) {
  colliderContacts_.clear();
  if (colliders.empty()) return;
  std::size_t kept = 0;  // walks keptCollider_, in the same (g, collider) order
  for (const std::uint32_t k : awakeParticles_) {
    if (!touched_[k] || w_[k] == 0.0) continue;
    const double r = r_[k];
    for (std::size_t ci = 0; ci < colliders.size(); ++ci) {
      const PosedCollider& sc = colliders[ci];
      const Collider& col = *sc.collider;
      if (!sc.near(x_[k], r * (1.0 + kContactMargin))) continue;
      Eigen::Vector3d n;
      const double gap = sc.gap(x_[k], r, n);
      if (!(gap < r * kContactMargin)) continue;
      Eigen::Vector3d startNormal;
      const double startGap = sc.startGap(x_[k] - h * v_[k], r, startNormal);
      ColliderContact c;
      c.k = static_cast<std::uint32_t>(k);
      c.collider = static_cast<std::uint32_t>(ci);
      c.n = n;
      c.offset = n.dot(x_[k]) - gap;
      c.target = std::min(startGap, 0.0);
      c.wsum = w_[k];
      c.muS = col.staticFriction;
      c.muK = col.kineticFriction;
      c.vc = sc.surfaceVelocity(x_[k]);
      const std::uint32_t g = global_[k];
      while (kept < keptCollider_.size() &&
             (keptCollider_[kept].g < g || (keptCollider_[kept].g == g && keptCollider_[kept].collider < ci)))
        ++kept;
      if (kept < keptCollider_.size() && keptCollider_[kept].g == g && keptCollider_[kept].collider == ci)
        resume(c, keptCollider_[kept].impulses);
      colliderContacts_.push_back(c);
    }
  }
}

// A contact takes up its kept impulses with its friction tangential to its new normal.
void ObjectContactSolver::resume(ContactRow& c, const Impulses& kept) {
  c.lambda = kept.lambda;
  c.friction = kept.friction - kept.friction.dot(c.n) * c.n;
  c.sliding = kept.sliding;
}

// Warm start (Catto 2005): a resting pile starts the passes almost converged, and they stop early.
void ObjectContactSolver::warmStart(double h) {
  for (const ColliderContact& c : colliderContacts_) {
    if (!carries(c.lambda, c.friction)) continue;
    move(c.k, w_[c.k] * impulseOf(c), h);
  }
  for (const PairContact& c : contacts_) {
    if (!carries(c.lambda, c.friction)) continue;
    const Eigen::Vector3d J = impulseOf(c);
    move(c.k1, w_[c.k1] * J, h);
    move(c.k2, -(w_[c.k2] * J), h);
  }
}

// The friction regime changes between sub-steps only: a contact slides next when its friction reached its bound now.
bool ObjectContactSolver::slides(const ContactRow& c) {
  const double normal = c.lambda + c.spring;
  const double bound = (c.sliding ? c.muK : c.muS) * normal;
  return normal > 0.0 && c.friction.squaredNorm() >= bound * bound * (1.0 - 1e-9);
}

// The impulses for the next sub-step's warm start; a sleeping object's collider impulses are carried for when it wakes.
void ObjectContactSolver::keep() {
  for (const PairContact& c : contacts_) keptPairs_[c.slot] = keptOf(c);
  keptScratch_.swap(keptCollider_);
  keptCollider_.clear();
  reserveDoubling(keptCollider_, colliderContacts_.size() + (asleep_ != nullptr ? keptScratch_.size() : 0));
  std::size_t old = 0;
  auto carryBefore = [&](std::uint32_t g, std::size_t ci) {
    for (; old < keptScratch_.size() &&
           (keptScratch_[old].g < g || (keptScratch_[old].g == g && keptScratch_[old].collider < ci));
         ++old)
      if (asleep(owner_[keptScratch_[old].g])) keptCollider_.push_back(keptScratch_[old]);
  };
  for (const ColliderContact& c : colliderContacts_) {
    if (!carries(c.lambda, c.friction)) continue;
    carryBefore(global_[c.k], c.collider);
    keptCollider_.push_back({global_[c.k], c.collider, keptOf(c)});
  }
  carryBefore(std::numeric_limits<std::uint32_t>::max(), std::numeric_limits<std::size_t>::max());
}

// A sleeping object's collider impulses outlive the sub-steps in which it has no contacts.
void ObjectContactSolver::keepAsleepColliderImpulses() {
  std::size_t n = 0;
  for (const KeptImpulse& k : keptCollider_)
    if (asleep(owner_[k.g])) keptCollider_[n++] = k;
  keptCollider_.resize(n);
}

// Projected Gauss-Seidel, stopped once a pass changes the contacts by far less than the penetration slop.
int ObjectContactSolver::solve(double h, int iterations) {
  double smallest = r_[contacts_.front().k1];
  for (const PairContact& c : contacts_) smallest = std::min({smallest, r_[c.k1], r_[c.k2]});
  const double tolerance = kSolveTolerance * smallest / h;
  const double tolerance2 = tolerance * tolerance;
  for (ColliderContact& c : colliderContacts_) c.prepare(h);
  for (PairContact& c : contacts_) c.prepare(h);
  for (int it = 0; it < iterations; ++it) {
    double largest2 = 0.0;  // the largest change of a relative velocity in this pass, squared
    // the colliders' contacts first: the support below is settled before the pairs above it
    for (ColliderContact& c : colliderContacts_) {
      const ContactCorrection u = colliderUpdate(c, x_[c.k], v_[c.k], w_[c.k], c.vc);
      if (!u.applies) continue;
      c.lambda = u.lambda;
      c.friction = u.friction;
      largest2 = std::max(largest2, c.wsum * c.wsum * u.impulse.squaredNorm());
      move(c.k, u.dv1, h);
    }
    for (PairContact& c : contacts_) {
      const ContactCorrection u = pairUpdate(c, x_[c.k1], v_[c.k1], w_[c.k1], x_[c.k2], v_[c.k2], w_[c.k2]);
      if (!u.applies) continue;
      c.lambda = u.lambda;
      c.friction = u.friction;
      largest2 = std::max(largest2, c.wsum * c.wsum * u.impulse.squaredNorm());
      move(c.k1, u.dv1, h);
      move(c.k2, u.dv2, h);
    }
    if (largest2 < tolerance2 && it > 0) return it + 1;
  }
  return iterations;
}

// Penetration the velocity solve only kept from growing, pushed out by position at a bounded pace.
void ObjectContactSolver::pushOut() {
  for (const ColliderContact& c : colliderContacts_) {
    Eigen::Vector3d& x = x_[c.k];
    const double r = r_[c.k];
    const double depth = -(c.n.dot(x) - c.offset) - kPenetrationSlop * r;
    if (depth > 0.0) x += std::min(depth, kPushPace * r) * c.n;
  }
  for (const PairContact& c : contacts_) {
    Eigen::Vector3d& x1 = x_[c.k1];
    const double depth = -(c.n.dot(x1 - x_[c.k2]) - c.offset) - kPenetrationSlop * c.offset;
    if (!(depth > 0.0)) continue;
    const double push = std::min(depth, kPushPace * std::min(r_[c.k1], r_[c.k2]));
    x1 += (w_[c.k1] / c.wsum * push) * c.n;
    x_[c.k2] -= (w_[c.k2] / c.wsum * push) * c.n;
  }
}

// Only the particles in a contact changed: only they go back into their objects.
void ObjectContactSolver::scatter(const std::vector<Solver*>& objects) {
  for (const ColliderContact& c : colliderContacts_) touched_[c.k] = 2;
  for (const PairContact& c : contacts_) touched_[c.k1] = touched_[c.k2] = 2;
  for (const std::uint32_t k : awakeParticles_) {
    if (touched_[k] != 2) continue;
    Solver& s = *objects[object_[k]];
    s.substepPositions()[index_[k]] = x_[k];
    s.substepVelocities()[index_[k]] = v_[k];
  }
}

// The step's wrenches: per object and collider (at the contact point x - r n), and per object pair (addPairWrench()).
void ObjectContactSolver::accumulate(const std::vector<Solver*>& objects, const std::vector<PosedCollider>& colliders,
                                     bool last) {
  for (const ColliderContact& c : colliderContacts_) {
    const Eigen::Vector3d J = impulseOf(c);
    const double r = r_[c.k];
    ColliderImpulse& ci = colliderImpulses_[object_[c.k] * colliderCount_ + c.collider];
    ci.impulse += J;
    ci.moment += (x_[c.k] - r * c.n - colliders[c.collider].now.translation()).cross(J);
    if (last && c.lambda > 0.0) objects[object_[c.k]]->touchCollider(index_[c.k], c.collider);
  }
  for (const PairContact& c : contacts_) {
    const std::uint32_t o1 = object_[c.k1], o2 = object_[c.k2];
    if (o1 == o2) continue;  // self-contact: no wrench between objects
    const bool active = c.lambda > 0.0;
    if (!active && c.friction.isZero(0.0)) continue;
    PairImpulse& p = addPairWrench(o1, o2, x_[c.k1], x_[c.k2], r_[c.k1], r_[c.k2], impulseOf(c));
    if (last && active && !std::binary_search(pushingSprings_.begin(), pushingSprings_.end(), keys_[c.slot]))
      ++p.contacts;
  }
}

// The one rule of a pair wrench, for the passes' contacts and the springs alike: J on o1's particle, taken at
// the point between the spheres' surfaces, into the pair's slot (the impulse on the higher object).
PairImpulse& ObjectContactSolver::addPairWrench(std::uint32_t o1, std::uint32_t o2, const Eigen::Vector3d& x1,
                                                const Eigen::Vector3d& x2, double r1, double r2,
                                                const Eigen::Vector3d& J) {
  const Eigen::Vector3d point = x2 + (r2 / (r1 + r2)) * (x1 - x2);
  const Eigen::Vector3d onB = o1 < o2 ? Eigen::Vector3d(-J) : J;
  PairImpulse& p = pairSlot(std::min(o1, o2), std::max(o1, o2));
  p.impulse += onB;
  p.moment += point.cross(onB);
  return p;
}

// An open-addressing table finds a pair's sum without allocating once grown.
PairImpulse& ObjectContactSolver::pairSlot(std::uint32_t a, std::uint32_t b) {
  if (pairTable_.size() < 2 * (pairs_.size() + 1)) {
    // grow the open-addressing table (a power of two, at most half full) and re-enter the pairs
    std::size_t size = std::max<std::size_t>(64, pairTable_.size());
    while (size < 4 * (pairs_.size() + 1)) size *= 2;
    pairTable_.assign(size, -1);
    for (std::size_t i = 0; i < pairs_.size(); ++i) {
      std::size_t slot = (pairs_[i].a * 2654435761u + pairs_[i].b) & (size - 1);
      while (pairTable_[slot] >= 0) slot = (slot + 1) & (size - 1);
      pairTable_[slot] = static_cast<std::int32_t>(i);
    }
  }
  const std::size_t mask = pairTable_.size() - 1;
  std::size_t slot = (a * 2654435761u + b) & mask;
  while (pairTable_[slot] >= 0) {
    PairImpulse& p = pairs_[static_cast<std::size_t>(pairTable_[slot])];
    if (p.a == a && p.b == b) return p;
    slot = (slot + 1) & mask;
  }
  pairTable_[slot] = static_cast<std::int32_t>(pairs_.size());
  PairImpulse p;
  p.a = a;
  p.b = b;
  pairs_.push_back(p);
  return pairs_.back();
}

// The implicit step's springs pushed pairs in its solve: they bound the pass's friction and count in the wrenches.
void ObjectContactSolver::takeCoupling(const std::vector<Solver*>& objects, bool rebuilt, bool last) {
  springLambda_.clear();
  pushingSprings_.clear();
  if (coupling_ == nullptr || coupling_->empty()) return;
  // sized by the springs, not by the most that pushed so far (which varies with the rounding)
  reserveDoubling(pushingSprings_, coupling_->size());
  if (!rebuilt) {
    springLambda_.resize(keys_.size(), 0.0);
    for (const CouplingImpulse& ci : *coupling_)
      if (ci.slot < keys_.size() && keys_[ci.slot] == keyOf(ci.g1, ci.g2))
        springLambda_[ci.slot] = contact_update::springBound(ci.lambda);
  }
  for (const CouplingImpulse& ci : *coupling_) {
    const std::uint32_t o1 = owner_[ci.g1], o2 = owner_[ci.g2];  // g: global particle numbers
    if (o1 == o2) continue;  // self-contact: no wrench between objects
    const Solver& s1 = *objects[o1];
    const Solver& s2 = *objects[o2];
    PairImpulse& p = addPairWrench(o1, o2, s1.positions()[ci.g1 - offset_[o1]], s2.positions()[ci.g2 - offset_[o2]],
                                   s1.contactRadius(), s2.contactRadius(), ci.lambda * ci.n);
    if (last && ci.lambda > 0.0) {  // a contact that pushes, as the passes count theirs
      ++p.contacts;
      pushingSprings_.push_back(keyOf(ci.g1, ci.g2));
    }
  }
  std::sort(pushingSprings_.begin(), pushingSprings_.end());
}

// The wrenches come out in a fixed order, whatever order the contacts found them in.
void ObjectContactSolver::endStep() {
  std::sort(pairs_.begin(), pairs_.end(),
            [](const PairImpulse& l, const PairImpulse& r) { return l.a != r.a ? l.a < r.a : l.b < r.b; });
}

}  // namespace deformable_flsm
