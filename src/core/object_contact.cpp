// Contact between deformable objects and of an object with itself (see object_contact.h).
//
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
//   friction falls below that bound. The regime changes between sub-steps only: switching
//   between mu_s and mu_k within the passes, whose normal impulses are not yet converged, made
//   resting contacts stick and slip by turns, and a pile of soft objects never came to rest.
// and each change dJ is applied equal and opposite, dv1 = w1 dJ, dv2 = -w2 dJ (w = 1/m, 0 for
// a pinned or hard-dragged particle): linear momentum is conserved exactly. A pair's normal
// impulse lies along the line of the particles at the start of the sub-step, where the
// symplectic step's kick acts (x_end = x_start + h v_end), so frictionless contact conserves
// angular momentum exactly too; a friction impulse between two particle centres 2r apart is a
// couple the particles cannot spin with (they carry no rotation), of at most 2 r |f|.
#include "deformable_flsm/core/object_contact.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/world.h"

#include <algorithm>
#include <ctime>
#include <limits>
#include <cmath>
#include <initializer_list>

namespace deformable_flsm {

namespace {

/// Pairs are found closer than (r1 + r2)(1 + kContactMargin), and colliders within
/// r kContactMargin: a pair just apart at the end of the sub-step is in the solve, so that the
/// corrections of its neighbours cannot push it into each other unseen.
constexpr double kContactMargin = 0.25;
/// Penetration up to this fraction of r1 + r2 (of r for a collider) is left alone by the
/// position push (Box2D's "linear slop"): resting contacts are not pushed every sub-step,
/// which would shake a stack. The velocity solve still lets none of them grow.
constexpr double kPenetrationSlop = 0.01;
/// Old penetration is pushed out by at most this fraction of the smaller radius per sub-step,
/// by position only (as the collider pass bounds its own at the radius).
constexpr double kPushPace = 0.5;
/// A particle's allowance around its anchor in the candidate list is this fraction of its
/// contact radius (a pile at rest keeps its list while its particles stay within it) ...
constexpr double kSkin = 0.25;
/// ... plus its motion over this many sub-steps at its speed after the build ...
constexpr int kSkinSubsteps = 2;
/// ... up to this fraction of its radius (or its motion in the sub-step of the build if that is
/// more): wider allowances make the hash's cells larger or a fast particle's search wide.
constexpr double kSkinMotion = 0.5;
/// The Gauss-Seidel passes stop when a pass changed no relative velocity by more than this
/// fraction of the smallest radius per sub-step (see solve()).
constexpr double kSolveTolerance = 1e-3;

/// The calling thread's CPU time (s): on a machine shared with other jobs, what the work took
/// rather than how long it waited for a core.
double threadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

/// Adds the time since the last lap to one of the parts (nothing when `seconds` is null); the
/// time after the last lap goes to the rest.
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

/// Grows a buffer's capacity to twice n when n exceeds it: a list whose size grows slowly (the
/// pairs of objects pressed together) allocates a few times only.
template <class V>
void reserveDoubling(V& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(2 * n);
}

bool boxesMeet(const Eigen::Vector3d& lo1, const Eigen::Vector3d& hi1, const Eigen::Vector3d& lo2,
               const Eigen::Vector3d& hi2) {
  return (lo1.array() <= hi2.array()).all() && (lo2.array() <= hi1.array()).all();
}

}  // namespace

void ObjectContactSolver::beginStep(std::size_t objects, std::size_t colliders) {
  colliderCount_ = colliders;
  colliderImpulses_.assign(objects * colliders, ColliderImpulse());
  pairs_.clear();
  std::fill(pairTable_.begin(), pairTable_.end(), -1);
}

void ObjectContactSolver::substep(const std::vector<Solver*>& objects, const std::vector<SubstepCollider>& colliders,
                                  const ObjectContactParams& params, double h, bool last) {
  for (PairImpulse& p : pairs_) p.contacts = 0;
  for (ColliderImpulse& c : colliderImpulses_) c.contacts = 0;
  if (!params.enabled && !params.selfContact) return;
  Laps laps(timing_ ? &seconds_ : nullptr);
  const Staleness stale = updateList(objects, params, h, 0.0);
  laps.lap(kListSeconds);
  takeCoupling(objects, stale != Staleness::kNone, last);
  if (candidates_.empty()) return;
  gather(objects, h);
  laps.lap(kRestSeconds);
  findPairs(params);
  laps.lap(kPairSeconds);
  if (contacts_.empty()) {
    keepFrozenColliderImpulses();  // nothing else to warm-start the next sub-step's collider contacts from
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

// Before a coupled implicit sub-step: the list built again for the objects whose particles would
// leave their allowances moving on at their velocities over the sub-step (anchors at the middle
// of that motion), so that the springs made from it keep their slots through the pass after
// the solve unless the solve itself carries a particle out of its allowance.
void ObjectContactSolver::refreshList(const std::vector<Solver*>& objects, const ObjectContactParams& params,
                                      double h) {
  if (!params.enabled && !params.selfContact) return;
  Laps laps(timing_ ? &seconds_ : nullptr);
  updateList(objects, params, h, h);
  laps.lap(kListSeconds);
}

ObjectContactSolver::Staleness ObjectContactSolver::updateList(const std::vector<Solver*>& objects,
                                                               const ObjectContactParams& params, double h,
                                                               double ahead) {
  const Staleness stale = findStale(objects, params, h, ahead);
  if (stale != Staleness::kNone) buildList(objects, params, h, stale == Staleness::kAll, ahead);
  return stale;
}

// The list holds every pair that can come within reach while each particle's end and start
// positions stay within its allowance e of its anchor a (the middle of its motion over the
// sub-step of its object's last build): two particles whose anchors are farther apart than
// reach1 + e1 + reach2 + e2 end and start a sub-step farther apart than reach1 + reach2, however
// old either anchor. So an object is stale as soon as one of its particles (listed or not) left
// its ball, and then only its own anchors and pairs are built again; the whole list when the
// objects or parameters changed.
ObjectContactSolver::Staleness ObjectContactSolver::findStale(const std::vector<Solver*>& objects,
                                                              const ObjectContactParams& params, double h,
                                                              double ahead) {
  if (!built_ || params.enabled != builtEnabled_ || params.selfContact != builtSelf_ ||
      params.selfExclusion != builtExclusion_ || objects.size() != builtObjects_.size())
    return Staleness::kAll;
  bool any = false;
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const Solver& s = *objects[o];
    const auto& x = s.positions();
    const auto& v = s.velocities();
    if (&s != builtObjects_[o] || x.size() != offset_[o + 1] - offset_[o] || s.contactRadius() != builtRadius_[o])
      return Staleness::kAll;
    const Eigen::Vector3d* a = anchor_.data() + offset_[o];
    const double* e = allowance_.data() + offset_[o];
    stale_[o] = 0;
    for (std::size_t i = 0; i < x.size(); ++i) {
      const Eigen::Vector3d d = x[i] + ahead * v[i] - a[i];
      const double e2 = e[i] * e[i];
      if (d.squaredNorm() >= e2 || (d - h * v[i]).squaredNorm() >= e2) {
        stale_[o] = 1;
        any = true;
        break;
      }
    }
  }
  return any ? Staleness::kSome : Staleness::kNone;
}

// The build, of the stale objects (all of them the first time): anchors at the middle of each
// particle's motion over this sub-step (h |v| / 2 from either end), allowances wide enough for
// it to go on for a few more sub-steps at its speed (see kSkin); the broad phase on all
// objects' bounds (a fresh object's from its new anchors, the others' from their old ones),
// then the hash of the particles it lets in where a stale object's bounds meet another's: all
// of them, not the lattice's surface only (an impact deforms the object so that particles from
// inside pass between the surface's, which have no contact with each other, into the other).
// The pairs of two objects that are not stale are kept; the hash gives the pairs with a stale
// object. Only the particles in a candidate pair stay in the list, in
// the order of their objects and indices; the pairs kept in their order, then the new ones in
// the order of their first particle and of the hash's buckets: deterministic.
void ObjectContactSolver::buildList(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h,
                                    bool all, double ahead) {
  const std::size_t N = objects.size();
  ++listBuilds_;
  // a sleeping object's pairs keep their impulses over a build of the others, for when it wakes
  // (with a sleeping partner they have no contact meanwhile): a pair of two objects not built
  // again keeps its place in the list and its impulses with it (below); the others, which the
  // search may find again, by their particles' pair
  // (keptLambda_ and its siblings are per key: sized with keys_ at the end of every build)
  const auto impulse = [&](std::size_t i) { return keptLambda_[i] != 0.0 || !keptFriction_[i].isZero(0.0); };
  carried_.clear();
  if (!all && frozen_ != nullptr) {
    for (std::size_t i = 0; i < keys_.size(); ++i) {
      const std::uint32_t o1 = owner_[keys_[i].first], o2 = owner_[keys_[i].second];
      if ((!stale_[o1] && !stale_[o2]) || (!frozen(o1) && !frozen(o2))) continue;
      if (!impulse(i)) continue;
      carried_.push_back({keys_[i], keptLambda_[i], keptFriction_[i], keptSliding_[i]});
    }
    std::sort(carried_.begin(), carried_.end(), [](const Carried& l, const Carried& r) { return l.key < r.key; });
  }
  if (all) {
    built_ = true;
    builtEnabled_ = params.enabled;
    builtSelf_ = params.selfContact;
    builtExclusion_ = params.selfExclusion;
    builtObjects_.assign(objects.begin(), objects.end());
    builtRadius_.resize(N);
    offset_.resize(N + 1);
    offset_[0] = 0;
    for (std::size_t o = 0; o < N; ++o) offset_[o + 1] = offset_[o] + objects[o]->positions().size();
    anchor_.resize(offset_[N]);
    allowance_.resize(offset_[N]);
    owner_.resize(offset_[N]);
    for (std::size_t o = 0; o < N; ++o)
      std::fill(owner_.begin() + offset_[o], owner_.begin() + offset_[o + 1], static_cast<std::uint32_t>(o));
    lo_.resize(N);
    hi_.resize(N);
    radius_.resize(N);
    reach_.resize(N);
    most_.resize(N);
    stale_.assign(N, 1);
    keys_.clear();
    // what a build of every particle needs: a later build of some objects then allocates no
    // more than the first (the pairs excepted)
    const std::size_t total = offset_[N];
    hash_.reserve(total);
    reserveDoubling(hashGlobal_, total);
    reserveDoubling(hashObject_, total);
    reserveDoubling(hashX_, total);
    reserveDoubling(hashBall_, total);
    for (std::size_t o = 0; o < N; ++o) {
      builtRadius_[o] = radius_[o] = objects[o]->contactRadius();
      reach_[o] = radius_[o] * (1.0 + kContactMargin);
    }
  }
  near_.assign(N, 0);
  // the largest reach with an allowance of a particle at most kSkinMotion r fast per sub-step: a
  // particle whose allowance is larger (a fast one) searches the hash wider
  double baseReach = 0.0;
  for (std::size_t o = 0; o < N; ++o) baseReach = std::max(baseReach, reach_[o] + (kSkin + kSkinMotion) * radius_[o]);
  for (std::size_t o = 0; o < N; ++o) {
    if (!stale_[o]) continue;
    const auto& x = objects[o]->positions();
    const auto& v = objects[o]->velocities();
    Eigen::Vector3d* a = anchor_.data() + offset_[o];
    double* e = allowance_.data() + offset_[o];
    double most = 0.0;
    const double rest = kSkin * radius_[o], motion = kSkinMotion * radius_[o];
    for (std::size_t i = 0; i < x.size(); ++i) {
      a[i] = x[i] + (ahead - 0.5 * h) * v[i];
      // beyond its h |v| / 2 at the build, room for kSkinSubsteps more sub-steps at its speed
      // up to kSkinMotion r: a faster particle has the list built again soon
      const double step = h * v[i].norm();
      e[i] = rest + std::max(0.5 * step, std::min((kSkinSubsteps + 0.5) * step, motion));
      most = std::max(most, e[i]);
    }
    most_[o] = most;
    Eigen::Vector3d lo = a[0], hi = lo;
    for (std::size_t i = 1; i < x.size(); ++i) {
      lo = lo.cwiseMin(a[i]);
      hi = hi.cwiseMax(a[i]);
    }
    lo_[o] = lo.array() - (reach_[o] + most);
    hi_[o] = hi.array() + (reach_[o] + most);
  }
  double widest = baseReach;  // the largest reach + allowance
  for (std::size_t o = 0; o < N; ++o) widest = std::max(widest, reach_[o] + most_[o]);
  // per object pair by bounds, sweeping the objects in order of their lower x bound (a pair is
  // tested only where the x intervals meet): nothing per particle of an object alone. Then each
  // object's list of the others its bounds meet (flat arrays, capacity kept).
  order_.resize(N);
  for (std::size_t o = 0; o < N; ++o) order_[o] = static_cast<std::uint32_t>(o);
  std::sort(order_.begin(), order_.end(), [&](std::uint32_t a, std::uint32_t b) {
    return lo_[a].x() != lo_[b].x() ? lo_[a].x() < lo_[b].x() : a < b;
  });
  objectPairs_.clear();
  if (params.enabled)
    for (std::size_t i = 0; i < N; ++i) {
      const std::uint32_t a = order_[i];
      for (std::size_t j = i + 1; j < N && lo_[order_[j]].x() <= hi_[a].x(); ++j) {
        const std::uint32_t b = order_[j];
        if (boxesMeet(lo_[a], hi_[a], lo_[b], hi_[b])) objectPairs_.emplace_back(a, b);
      }
    }
  neighborStart_.assign(N + 1, 0);
  for (const auto& p : objectPairs_) {
    ++neighborStart_[p.first + 1];
    ++neighborStart_[p.second + 1];
  }
  for (std::size_t o = 0; o < N; ++o) neighborStart_[o + 1] += neighborStart_[o];
  neighbors_.resize(neighborStart_[N]);
  for (const auto& p : objectPairs_) {  // neighborStart_[o] as a cursor, restored below
    neighbors_[neighborStart_[p.first]++] = p.second;
    neighbors_[neighborStart_[p.second]++] = p.first;
  }
  for (std::size_t o = N; o > 0; --o) neighborStart_[o] = neighborStart_[o - 1];
  neighborStart_[0] = 0;
  // into the hash: a stale object's particles (with self-contact, or whose ball of reach +
  // allowance meets another object's bounds), and another's whose ball meets a stale object's
  for (std::size_t o = 0; o < N; ++o) {
    bool meetsStale = false;
    for (std::uint32_t j = neighborStart_[o]; j < neighborStart_[o + 1] && !meetsStale; ++j)
      meetsStale = stale_[neighbors_[j]] != 0;
    near_[o] = stale_[o] ? params.selfContact || neighborStart_[o + 1] > neighborStart_[o] : meetsStale;
  }
  std::size_t n = 0;
  for (std::size_t o = 0; o < N; ++o) {
    if (!near_[o]) continue;
    const Eigen::Vector3d* a = anchor_.data() + offset_[o];
    const double* e = allowance_.data() + offset_[o];
    for (std::size_t i = 0; i < offset_[o + 1] - offset_[o]; ++i) {
      bool wanted = stale_[o] && params.selfContact;
      const double ball = reach_[o] + e[i];
      const Eigen::Vector3d plo = a[i].array() - ball, phi = a[i].array() + ball;
      for (std::uint32_t j = neighborStart_[o]; j < neighborStart_[o + 1] && !wanted; ++j) {
        const std::uint32_t b = neighbors_[j];
        wanted = (stale_[o] || stale_[b]) && boxesMeet(plo, phi, lo_[b], hi_[b]);
      }
      if (!wanted) continue;
      if (hashGlobal_.size() <= n) {
        const std::size_t grown = std::max<std::size_t>(64, 2 * hashGlobal_.size());
        hashGlobal_.resize(std::max(grown, hashGlobal_.capacity()));
        hashObject_.resize(hashGlobal_.size());
        hashX_.resize(hashGlobal_.size());
        hashBall_.resize(hashGlobal_.size());
      }
      hashGlobal_[n] = static_cast<std::uint32_t>(offset_[o] + i);
      hashObject_[n] = static_cast<std::uint32_t>(o);
      hashX_[n] = a[i];
      hashBall_[n] = ball;
      ++n;
    }
  }
  // the pairs of two objects that are not stale, with their impulses if one of them sleeps
  std::size_t kept = 0;
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const std::uint32_t o1 = owner_[keys_[i].first], o2 = owner_[keys_[i].second];
    if (stale_[o1] || stale_[o2]) continue;
    const bool carry = frozen_ != nullptr && (frozen(o1) || frozen(o2)) && impulse(i);
    keptLambda_[kept] = carry ? keptLambda_[i] : 0.0;
    keptFriction_[kept] = carry ? keptFriction_[i] : Eigen::Vector3d::Zero();
    keptSliding_[kept] = carry ? keptSliding_[i] : 0;
    keys_[kept++] = keys_[i];
  }
  keys_.resize(kept);
  // a slow particle's partners within ball + baseReach lie in the 27 cells around it; a fast
  // one (ball > baseReach) searches ball + widest. A pair is taken from the search of its fast
  // particle; when both are slow or both fast, of its stale one, or of its first when both are
  // stale: each pair once, none missed (a slow-slow pair is within 2 baseReach, any pair with a
  // fast particle within its ball + widest), and a slow particle of an object that is not stale
  // searches nothing.
  if (n > 0) {
    hash_.build(hashX_, n, 2.0 * baseReach);
    for (std::size_t k1 = 0; k1 < n; ++k1) {
      const std::uint32_t g1 = hashGlobal_[k1], o1 = hashObject_[k1];
      const bool fast1 = hashBall_[k1] > baseReach, stale1 = stale_[o1] != 0;
      if (!fast1 && !stale1) continue;
      auto consider = [&](std::uint32_t k2) {
        const std::uint32_t o2 = hashObject_[k2];
        if (o1 == o2 ? !params.selfContact || k2 == k1 : !params.enabled) return;
        const bool stale2 = stale_[o2] != 0;
        if (!stale1 && !stale2) return;  // kept
        const bool fast2 = hashBall_[k2] > baseReach;
        if (fast1 != fast2 ? fast2 : stale1 != stale2 ? stale2 : k2 < k1) return;  // k2's search takes it
        const std::uint32_t g2 = hashGlobal_[k2];
        if (o1 == o2) {
          const auto& cells = objects[o1]->lattice().cells();
          const Eigen::Vector3i d = cells[g1 - offset_[o1]] - cells[g2 - offset_[o2]];
          if (d.cwiseAbs().maxCoeff() <= params.selfExclusion) return;
        }
        const double R = hashBall_[k1] + hashBall_[k2];
        if ((hashX_[k1] - hashX_[k2]).squaredNorm() >= R * R) return;
        keys_.emplace_back(std::min(g1, g2), std::max(g1, g2));
      };
      if (fast1)
        hash_.forEachWithin(hashX_[k1], hashBall_[k1] + widest, scratch_, consider);
      else
        hash_.forEachNear(hashX_[k1], consider);
    }
  }
  // no warm start after a build for a pair of awake objects: with the kept pairs' impulses
  // carried over the builds, the 20-object bin of test_world still moved at 7.4 mm/s (fastest
  // particle, 10 to 12 s), against 1.2 mm/s with them dropped at every build; a sleeping
  // object's are carried (in the compaction above, and from carried_ below)
  reserveDoubling(keys_, keys_.size());
  reserveDoubling(keptLambda_, keys_.size());
  reserveDoubling(keptFriction_, keys_.size());
  reserveDoubling(keptSliding_, keys_.size());
  // the next build carries some of these keys: sized by them, not by the most carried so far
  reserveDoubling(carried_, keys_.size());
  keptLambda_.resize(kept);
  keptFriction_.resize(kept);
  keptSliding_.resize(kept);
  keptLambda_.resize(keys_.size(), 0.0);
  keptFriction_.resize(keys_.size(), Eigen::Vector3d::Zero());
  keptSliding_.resize(keys_.size(), 0);
  for (std::size_t i = kept; i < keys_.size() && !carried_.empty(); ++i) {
    const auto it = std::lower_bound(carried_.begin(), carried_.end(), keys_[i],
                                     [](const Carried& c, const std::pair<std::uint32_t, std::uint32_t>& k) { return c.key < k; });
    if (it == carried_.end() || it->key != keys_[i]) continue;
    keptLambda_[i] = it->lambda;
    keptFriction_[i] = it->friction;
    keptSliding_[i] = it->sliding;
  }
  if (all || frozen_ == nullptr)
    keptCollider_.clear();
  else
    keepFrozenColliderImpulses();  // global numbers: valid over a build of some objects
  std::fill(stale_.begin(), stale_.end(), 0);
  // the particles in a pair, in the order of their global numbers, and the pairs renumbered
  renumber_.assign(offset_[N], -1);
  for (const auto& key : keys_) renumber_[key.first] = renumber_[key.second] = 0;
  count_ = 0;
  for (std::size_t g = 0; g < offset_[N]; ++g)
    if (renumber_[g] == 0) renumber_[g] = static_cast<std::int32_t>(count_++);
  for (auto* v : {&global_, &object_, &index_}) reserveDoubling(*v, count_);
  for (auto* v : {&x_, &v_, &start_}) reserveDoubling(*v, count_);
  reserveDoubling(w_, count_);
  reserveDoubling(r_, count_);
  reserveDoubling(touched_, count_);
  reserveDoubling(candidates_, keys_.size());
  // at most a contact per pair, and (mostly) one collider contact per particle
  reserveDoubling(contacts_, keys_.size());
  reserveDoubling(colliderContacts_, count_);
  reserveDoubling(keptCollider_, count_);
  global_.resize(count_);
  object_.resize(count_);
  index_.resize(count_);
  x_.resize(count_);
  v_.resize(count_);
  w_.resize(count_);
  r_.resize(count_);
  start_.resize(count_);
  touched_.resize(count_);
  for (std::size_t g = 0; g < offset_[N]; ++g) {
    if (renumber_[g] < 0) continue;
    const std::size_t k = static_cast<std::size_t>(renumber_[g]);
    global_[k] = static_cast<std::uint32_t>(g);
    object_[k] = owner_[g];
    index_[k] = static_cast<std::uint32_t>(g - offset_[owner_[g]]);
  }
  candidates_.resize(keys_.size());
  for (std::size_t i = 0; i < keys_.size(); ++i)
    candidates_[i] = {static_cast<std::uint32_t>(renumber_[keys_[i].first]),
                      static_cast<std::uint32_t>(renumber_[keys_[i].second])};
}

// The listed particles' state after their objects' sub-step.
void ObjectContactSolver::gather(const std::vector<Solver*>& objects, double h) {
  for (std::size_t k = 0; k < count_; ++k) {
    const Solver& s = *objects[object_[k]];
    const std::uint32_t i = index_[k];
    x_[k] = s.positions()[i];
    v_[k] = s.velocities()[i];
    start_[k] = x_[k] - h * v_[k];
    w_[k] = frozen(object_[k]) || s.isPrescribed(i) ? 0.0 : 1.0 / s.lattice().masses()[i];
    r_[k] = radius_[object_[k]];
    touched_[k] = 0;
  }
}

// The candidates within the sum of their radii with the margin at the end of the sub-step or
// at its start (x - h v). A particle that passed through another within the sub-step is found
// by its start, and its contact's normal, from the start positions, puts it back on the side it
// came from; only a relative motion of more than twice the reach in one sub-step (5 r: 4 m/s
// for r = 3.5 mm and h = 4 ms) can pass unseen.
void ObjectContactSolver::findPairs(const ObjectContactParams& params) {
  contacts_.clear();
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const std::uint32_t k1 = candidates_[i].first, k2 = candidates_[i].second;
    // two objects held still: no contact, and the impulses they had kept for when one wakes
    if (frozen(object_[k1]) && frozen(object_[k2])) continue;
    // the last sub-step's impulses, read once (keep() writes this sub-step's contacts' back)
    const double lambda = keptLambda_[i];
    const Eigen::Vector3d friction = keptFriction_[i];
    const bool sliding = keptSliding_[i] != 0;
    keptLambda_[i] = 0.0;
    keptFriction_[i].setZero();
    keptSliding_[i] = 0;
    const double wsum = w_[k1] + w_[k2];
    if (!(wsum > 0.0)) continue;  // both prescribed (or held still)
    const double R = r_[k1] + r_[k2];
    const double near2 = R * R * (1.0 + kContactMargin) * (1.0 + kContactMargin);
    const Eigen::Vector3d end = x_[k1] - x_[k2];
    const Eigen::Vector3d start = start_[k1] - start_[k2];
    if (end.squaredNorm() >= near2 && start.squaredNorm() >= near2) continue;
    Contact c;
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
    c.lambda = lambda;
    c.friction = friction - friction.dot(c.n) * c.n;
    c.sliding = sliding;
    contacts_.push_back(c);
    touched_[k1] = touched_[k2] = 1;
  }
}

// Colliders of the particles in a pair: a particle of an object pressed by another onto the
// ground is held by the ground within this solve (otherwise the ground would push it back only
// in the next sub-step, and the pair would chatter).
void ObjectContactSolver::findColliderContacts(const std::vector<SubstepCollider>& colliders, double h) {
  colliderContacts_.clear();
  if (colliders.empty()) return;
  // each collider's bounds once per sub-step, not per particle
  colliderLo_.resize(colliders.size());
  colliderHi_.resize(colliders.size());
  colliderBounded_.resize(colliders.size());
  for (std::size_t ci = 0; ci < colliders.size(); ++ci)
    colliderBounded_[ci] = colliders[ci].collider->shape.type != ColliderType::HalfSpace &&
                           colliderBounds(colliders[ci].collider->shape, colliders[ci].now, colliderLo_[ci],
                                          colliderHi_[ci]);
  std::size_t kept = 0;  // walks keptCollider_, in the same (k, collider) order
  for (std::size_t k = 0; k < count_; ++k) {
    if (!touched_[k] || w_[k] == 0.0) continue;
    const double r = r_[k];
    for (std::size_t ci = 0; ci < colliders.size(); ++ci) {
      const SubstepCollider& sc = colliders[ci];
      const Collider& col = *sc.collider;
      const double margin = r * (1.0 + kContactMargin);
      if (colliderBounded_[ci]) {
        if (((x_[k].array() - margin) > colliderHi_[ci].array()).any() ||
            ((x_[k].array() + margin) < colliderLo_[ci].array()).any())
          continue;
      } else if (!boxNearCollider(col.shape, sc.now, x_[k], x_[k], margin)) {
        continue;
      }
      Eigen::Vector3d n;
      const double gap = colliderDistance(col.shape, sc.now, x_[k], n) - r;
      if (!(gap < r * kContactMargin)) continue;
      Eigen::Vector3d startNormal;
      const double startGap = colliderDistance(col.shape, sc.before, x_[k] - h * v_[k], startNormal) - r;
      Contact c;
      c.k1 = static_cast<std::uint32_t>(k);
      c.k2 = static_cast<std::uint32_t>(ci);
      c.collider = true;
      c.n = n;
      c.offset = n.dot(x_[k]) - gap;
      c.target = std::min(startGap, 0.0);
      c.wsum = w_[k];
      c.muS = col.staticFriction;
      c.muK = col.kineticFriction;
      c.vc = col.linearVelocity + col.angularVelocity.cross(x_[k] - sc.now.translation());
      const std::uint32_t g = global_[k];
      while (kept < keptCollider_.size() &&
             (keptCollider_[kept].k < g || (keptCollider_[kept].k == g && keptCollider_[kept].collider < ci)))
        ++kept;
      if (kept < keptCollider_.size() && keptCollider_[kept].k == g && keptCollider_[kept].collider == ci) {
        c.lambda = keptCollider_[kept].lambda;
        c.friction = keptCollider_[kept].friction - keptCollider_[kept].friction.dot(n) * n;
        c.sliding = keptCollider_[kept].sliding;
      }
      colliderContacts_.push_back(c);
    }
  }
}

// Warm start (Catto 2005): each contact begins with the impulses its pair (or particle and
// collider) carried in the last sub-step, applied equal and opposite as the passes apply theirs;
// a resting pile, whose impulses change little from one sub-step to the next, then starts the
// passes almost converged, and they stop early. A contact that separated has its impulse taken
// back by the first pass (lambda >= 0 is projected from the accumulated value).
void ObjectContactSolver::warmStart(double h) {
  for (const std::vector<Contact>* list : {&colliderContacts_, &contacts_})
    for (const Contact& c : *list) {
      if (c.lambda == 0.0 && c.friction.isZero(0.0)) continue;
      const Eigen::Vector3d J = c.lambda * c.n + c.friction;
      const Eigen::Vector3d dv1 = w_[c.k1] * J;
      v_[c.k1] += dv1;
      x_[c.k1] += h * dv1;
      if (c.collider) continue;
      const Eigen::Vector3d dv2 = w_[c.k2] * J;
      v_[c.k2] -= dv2;
      x_[c.k2] -= h * dv2;
    }
}

// A contact slides in the next sub-step when its friction reached the bound of its regime in
// this one (mu_s lambda sticking, mu_k lambda sliding).
bool ObjectContactSolver::slides(const Contact& c) {
  const double normal = c.lambda + c.spring;
  const double bound = (c.sliding ? c.muK : c.muS) * normal;
  return normal > 0.0 && c.friction.squaredNorm() >= bound * bound * (1.0 - 1e-9);
}

void ObjectContactSolver::keep() {
  for (const Contact& c : contacts_) {
    keptLambda_[c.slot] = c.lambda;
    keptFriction_[c.slot] = c.friction;
    keptSliding_[c.slot] = slides(c);
  }
  // the frozen objects' particles have no collider contacts now: theirs are kept, in order
  keptScratch_.swap(keptCollider_);
  keptCollider_.clear();
  reserveDoubling(keptCollider_, colliderContacts_.size() + (frozen_ != nullptr ? keptScratch_.size() : 0));
  std::size_t old = 0;
  auto carryBefore = [&](std::uint32_t g, std::size_t ci) {
    for (; old < keptScratch_.size() && (keptScratch_[old].k < g || (keptScratch_[old].k == g && keptScratch_[old].collider < ci)); ++old)
      if (frozen(owner_[keptScratch_[old].k])) keptCollider_.push_back(keptScratch_[old]);
  };
  for (const Contact& c : colliderContacts_) {
    if (c.lambda == 0.0 && c.friction.isZero(0.0)) continue;
    carryBefore(global_[c.k1], c.k2);
    KeptImpulse k;
    k.k = global_[c.k1];
    k.collider = c.k2;
    k.lambda = c.lambda;
    k.friction = c.friction;
    k.sliding = slides(c);
    keptCollider_.push_back(k);
  }
  carryBefore(std::numeric_limits<std::uint32_t>::max(), std::numeric_limits<std::size_t>::max());
}

void ObjectContactSolver::keepFrozenColliderImpulses() {
  std::size_t n = 0;
  for (const KeptImpulse& k : keptCollider_)
    if (frozen(owner_[k.k])) keptCollider_[n++] = k;
  keptCollider_.resize(n);
}

// The passes stop early once a whole pass changed no contact's relative velocity by more than
// kSolveTolerance of the smallest radius per sub-step: what is left would move a particle by less
// than that fraction of its radius, far below the penetration slop.
int ObjectContactSolver::solve(double h, int iterations) {
  double smallest = r_[contacts_.front().k1];
  for (const Contact& c : contacts_) smallest = std::min({smallest, r_[c.k1], r_[c.k2]});
  const double tolerance = kSolveTolerance * smallest / h;
  const double tolerance2 = tolerance * tolerance;
  // the colliders' contacts first: the support below is settled before the pairs above it
  for (std::vector<Contact>* list : {&colliderContacts_, &contacts_})
    for (Contact& c : *list) {
      c.invHW = 1.0 / (h * c.wsum);
      c.invW = 1.0 / c.wsum;
    }
  for (int it = 0; it < iterations; ++it) {
    double largest2 = 0.0;  // the largest change of a relative velocity in this pass, squared
    for (std::vector<Contact>* list : {&colliderContacts_, &contacts_})
      for (Contact& c : *list) {
        Eigen::Vector3d& x1 = x_[c.k1];
        Eigen::Vector3d& v1 = v_[c.k1];
        const bool pair = !c.collider;
        // normal
        const double gap = pair ? c.n.dot(x1 - x_[c.k2]) - c.offset : c.n.dot(x1) - c.offset;
        const double old = c.lambda;
        c.lambda = std::max(0.0, old + (c.target - gap) * c.invHW);
        // a contact that neither pushes nor holds (most of those found within the margin) has
        // nothing to apply
        if (c.lambda == 0.0 && old == 0.0 && c.spring == 0.0 && c.friction.isZero(0.0)) continue;
        const double w1 = w_[c.k1];
        const double w2 = pair ? w_[c.k2] : 0.0;
        Eigen::Vector3d J = (c.lambda - old) * c.n;
        // friction on the relative velocity after the normal change
        const Eigen::Vector3d u = v1 + w1 * J - (pair ? Eigen::Vector3d(v_[c.k2] - w2 * J) : c.vc);
        const Eigen::Vector3d ut = u - u.dot(c.n) * c.n;
        const Eigen::Vector3d oldF = c.friction;
        Eigen::Vector3d f = oldF - ut * c.invW;
        const double fn2 = f.squaredNorm(), cone = (c.sliding ? c.muK : c.muS) * (c.lambda + c.spring);
        if (fn2 > cone * cone) f *= cone / std::sqrt(fn2);
        c.friction = f;
        J += f - oldF;
        largest2 = std::max(largest2, c.wsum * c.wsum * J.squaredNorm());
        const Eigen::Vector3d dv1 = w1 * J;
        v1 += dv1;
        x1 += h * dv1;
        if (pair) {
          const Eigen::Vector3d dv2 = w2 * J;
          v_[c.k2] -= dv2;
          x_[c.k2] -= h * dv2;
        }
      }
    if (largest2 < tolerance2) return it + 1;
  }
  return iterations;
}

void ObjectContactSolver::pushOut() {
  for (const std::vector<Contact>* list : {&colliderContacts_, &contacts_})
    for (const Contact& c : *list) {
      Eigen::Vector3d& x1 = x_[c.k1];
      if (c.collider) {
        const double r = r_[c.k1];
        const double depth = -(c.n.dot(x1) - c.offset) - kPenetrationSlop * r;
        if (depth > 0.0) x1 += std::min(depth, kPushPace * r) * c.n;
        continue;
      }
      const double depth = -(c.n.dot(x1 - x_[c.k2]) - c.offset) - kPenetrationSlop * c.offset;
      if (!(depth > 0.0)) continue;
      const double push = std::min(depth, kPushPace * std::min(r_[c.k1], r_[c.k2]));
      x1 += (w_[c.k1] / c.wsum * push) * c.n;
      x_[c.k2] -= (w_[c.k2] / c.wsum * push) * c.n;
    }
}

void ObjectContactSolver::scatter(const std::vector<Solver*>& objects) {
  for (const std::vector<Contact>* list : {&colliderContacts_, &contacts_})
    for (const Contact& c : *list) {
      touched_[c.k1] = 2;
      if (!c.collider) touched_[c.k2] = 2;
    }
  for (std::size_t k = 0; k < count_; ++k) {
    if (touched_[k] != 2) continue;
    Solver& s = *objects[object_[k]];
    s.substepPositions()[index_[k]] = x_[k];
    s.substepVelocities()[index_[k]] = v_[k];
  }
}

// The impulses of the sub-step into the step's sums: per object pair the impulse on b from a
// (a < b) and its moment about the origin, taken at the point between the spheres' surfaces;
// per object and collider the particles' impulse and its moment about the collider's origin,
// taken at the contact point x - r n.
void ObjectContactSolver::accumulate(const std::vector<Solver*>& objects, const std::vector<SubstepCollider>& colliders,
                                     bool last) {
  for (const std::vector<Contact>* list : {&colliderContacts_, &contacts_})
    for (const Contact& c : *list) {
      const Eigen::Vector3d J = c.lambda * c.n + c.friction;  // on k1
      const bool active = c.lambda > 0.0;
      if (c.collider) {
        const double r = r_[c.k1];
        ColliderImpulse& ci = colliderImpulses_[object_[c.k1] * colliderCount_ + c.k2];
        ci.impulse += J;
        ci.moment += (x_[c.k1] - r * c.n - colliders[c.k2].now.translation()).cross(J);
        // a particle its object's own contact pass (or solve) counted on this collider is one contact
        if (last && active && !objects[object_[c.k1]]->countedContact(index_[c.k1], *colliders[c.k2].id))
          ++ci.contacts;
        continue;
      }
      const std::uint32_t o1 = object_[c.k1], o2 = object_[c.k2];
      if (o1 == o2) continue;  // self-contact: no wrench between objects
      if (!active && c.friction.isZero(0.0)) continue;
      const double r1 = r_[c.k1], r2 = r_[c.k2];
      const Eigen::Vector3d point = x_[c.k2] + (r2 / (r1 + r2)) * (x_[c.k1] - x_[c.k2]);
      // the slot holds the impulse on the object of the higher index: -J on o2, J on o1
      const Eigen::Vector3d onB = o1 < o2 ? Eigen::Vector3d(-J) : J;
      PairImpulse& p = pairSlot(std::min(o1, o2), std::max(o1, o2));
      p.impulse += onB;
      p.moment += point.cross(onB);
      if (last && active && !std::binary_search(pushingSprings_.begin(), pushingSprings_.end(), keys_[c.slot]))
        ++p.contacts;
    }
}

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

const std::vector<std::pair<std::uint32_t, std::uint32_t>>* ObjectContactSolver::currentCandidates(
    const std::vector<Solver*>& objects, const ObjectContactParams& params) const {
  if (!built_ || params.enabled != builtEnabled_ || params.selfContact != builtSelf_ ||
      params.selfExclusion != builtExclusion_ || objects.size() != builtObjects_.size())
    return nullptr;
  for (std::size_t o = 0; o < objects.size(); ++o)
    if (objects[o] != builtObjects_[o] || objects[o]->positions().size() != offset_[o + 1] - offset_[o] ||
        objects[o]->contactRadius() != builtRadius_[o])
      return nullptr;
  return &keys_;
}

void ObjectContactSolver::takeCoupling(const std::vector<Solver*>& objects, bool rebuilt, bool last) {
  springLambda_.clear();
  pushingSprings_.clear();
  if (coupling_ == nullptr || coupling_->empty()) return;
  // sized by the springs, not by the most that pushed so far (which varies with the rounding)
  reserveDoubling(pushingSprings_, coupling_->size());
  if (!rebuilt) {
    springLambda_.resize(keys_.size(), 0.0);
    for (const CouplingImpulse& ci : *coupling_)
      if (ci.slot < keys_.size() && keys_[ci.slot].first == std::min(ci.g1, ci.g2) &&
          keys_[ci.slot].second == std::max(ci.g1, ci.g2))
        springLambda_[ci.slot] = std::max(0.0, ci.lambda);  // a pulling spring bounds no friction
  }
  for (const CouplingImpulse& ci : *coupling_) {
    const std::uint32_t o1 = owner_[ci.g1], o2 = owner_[ci.g2];
    if (o1 == o2) continue;  // self-contact: no wrench between objects
    const Solver& s1 = *objects[o1];
    const Solver& s2 = *objects[o2];
    const Eigen::Vector3d& x1 = s1.positions()[ci.g1 - offset_[o1]];
    const Eigen::Vector3d& x2 = s2.positions()[ci.g2 - offset_[o2]];
    const double r1 = s1.contactRadius(), r2 = s2.contactRadius();
    const Eigen::Vector3d point = x2 + (r2 / (r1 + r2)) * (x1 - x2);
    const Eigen::Vector3d J = ci.lambda * ci.n;  // on o1
    const Eigen::Vector3d onB = o1 < o2 ? Eigen::Vector3d(-J) : J;
    PairImpulse& p = pairSlot(std::min(o1, o2), std::max(o1, o2));
    p.impulse += onB;
    p.moment += point.cross(onB);
    if (last && ci.lambda > 0.0) {  // a contact that pushes, as the passes count theirs
      ++p.contacts;
      pushingSprings_.emplace_back(std::min(ci.g1, ci.g2), std::max(ci.g1, ci.g2));
    }
  }
  std::sort(pushingSprings_.begin(), pushingSprings_.end());
}

void ObjectContactSolver::endStep() {
  std::sort(pairs_.begin(), pairs_.end(),
            [](const PairImpulse& l, const PairImpulse& r) { return l.a != r.a ? l.a < r.a : l.b < r.b; });
}

}  // namespace deformable_flsm
