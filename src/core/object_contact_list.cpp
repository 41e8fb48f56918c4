// The object contact's candidate list (see ObjectContactSolver::substep() in object_contact.h): a
// Verlet list of particle pairs, kept while every particle stays within its allowance of its
// anchor and built again for the objects one of whose particles left it.
//
// The list holds every pair that can come within reach while each particle's end and start
// positions stay within its allowance e of its anchor a (the middle of its motion over the
// sub-step of its object's last build): two particles whose anchors are farther apart than
// reach1 + e1 + reach2 + e2 end and start a sub-step farther apart than reach1 + reach2, however
// old either anchor.
#include "deformable_flsm/core/object_contact.h"

#include "object_contact_internal.h"

#include "deformable_flsm/core/world.h"

#include <algorithm>
#include <cmath>
#include <initializer_list>

namespace deformable_flsm {

using object_contact::kContactMargin;
using object_contact::reserveDoubling;

namespace {

/// A particle's allowance around its anchor: this fraction of its radius (a pile at rest keeps its list) ...
constexpr double kSkin = 0.25;
/// ... plus its motion over this many sub-steps at its speed after the build ...
constexpr int kSkinSubsteps = 2;
/// ... up to this fraction of its radius: wider allowances make the hash's cells larger or a fast search wide.
constexpr double kSkinMotion = 0.5;

bool boxesMeet(const Eigen::Vector3d& lo1, const Eigen::Vector3d& hi1, const Eigen::Vector3d& lo2,
               const Eigen::Vector3d& hi2) {
  return (lo1.array() <= hi2.array()).all() && (lo2.array() <= hi1.array()).all();
}

}  // namespace

// A list built for other objects or parameters is of no use: built again whole, never handed out.
bool ObjectContactSolver::builtFor(const std::vector<Solver*>& objects, const ObjectContactParams& params) const {
  if (!built_ || params.enabled != builtEnabled_ || params.selfContact != builtSelf_ ||
      params.selfExclusion != builtExclusion_ || objects.size() != builtObjects_.size())
    return false;
  for (std::size_t o = 0; o < objects.size(); ++o)
    if (objects[o] != builtObjects_[o] || objects[o]->positions().size() != offset_[o + 1] - offset_[o] ||
        objects[o]->contactRadius() != builtRadius_[o])
      return false;
  return true;
}

const std::vector<std::pair<std::uint32_t, std::uint32_t>>* ObjectContactSolver::currentCandidates(
    const std::vector<Solver*>& objects, const ObjectContactParams& params) const {
  return builtFor(objects, params) ? &keys_ : nullptr;
}

ObjectContactSolver::Staleness ObjectContactSolver::updateList(const std::vector<Solver*>& objects,
                                                               const ObjectContactParams& params, double h,
                                                               double ahead) {
  const Staleness stale = findStale(objects, params, h, ahead);
  if (stale != Staleness::kNone) buildList(objects, params, h, stale == Staleness::kAll, ahead);
  return stale;
}

// Only an object one of whose particles (listed or not) left its ball needs its pairs built again.
ObjectContactSolver::Staleness ObjectContactSolver::findStale(const std::vector<Solver*>& objects,
                                                              const ObjectContactParams& params, double h,
                                                              double ahead) {
  if (!builtFor(objects, params)) return Staleness::kAll;
  bool any = false;
  for (std::size_t o = 0; o < objects.size(); ++o) {
    const auto& x = objects[o]->positions();
    const auto& v = objects[o]->velocities();
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

// Builds the stale objects' pairs and keeps the others', in a fixed order (objects, indices, buckets): deterministic.
void ObjectContactSolver::buildList(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h,
                                    bool all, double ahead) {
  const std::size_t N = objects.size();
  ++listBuilds_;
  carryFrozenPairImpulses(all);
  if (all) resetList(objects, params);
  near_.assign(N, 0);
  // the largest reach + allowance of a slow particle (at most kSkinMotion r per sub-step); a faster one searches wider
  double baseReach = 0.0;
  for (std::size_t o = 0; o < N; ++o) baseReach = std::max(baseReach, reach_[o] + (kSkin + kSkinMotion) * radius_[o]);
  anchorStale(objects, h, ahead);
  double widest = baseReach;  // the largest reach + allowance
  for (std::size_t o = 0; o < N; ++o) widest = std::max(widest, reach_[o] + most_[o]);
  findObjectPairs(params);
  const std::size_t hashed = hashNearParticles(params);
  const std::size_t kept = keepPairsOfSettledObjects();
  if (hashed > 0) searchHash(objects, params, hashed, baseReach, widest);
  restoreImpulses(kept, all);
  std::fill(stale_.begin(), stale_.end(), 0);
  renumberParticles();
}

// A sleeping object's pairs with a stale one keep their impulses for when it wakes, carried by key.
void ObjectContactSolver::carryFrozenPairImpulses(bool all) {
  carried_.clear();
  if (all || frozen_ == nullptr) return;
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const std::uint32_t o1 = owner_[keys_[i].first], o2 = owner_[keys_[i].second];
    if ((!stale_[o1] && !stale_[o2]) || (!frozen(o1) && !frozen(o2))) continue;
    if (!carries(keptPairs_[i].lambda, keptPairs_[i].friction)) continue;
    carried_.push_back({keys_[i], keptPairs_[i]});
  }
  std::sort(carried_.begin(), carried_.end(), [](const Carried& l, const Carried& r) { return l.key < r.key; });
}

// A first build sizes everything for all particles, so that later builds of some objects allocate nothing more.
void ObjectContactSolver::resetList(const std::vector<Solver*>& objects, const ObjectContactParams& params) {
  const std::size_t N = objects.size();
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

// Anchors mid-motion with room for a few sub-steps at a particle's speed, so the list outlives the build.
void ObjectContactSolver::anchorStale(const std::vector<Solver*>& objects, double h, double ahead) {
  for (std::size_t o = 0; o < objects.size(); ++o) {
    if (!stale_[o]) continue;
    const auto& x = objects[o]->positions();
    const auto& v = objects[o]->velocities();
    Eigen::Vector3d* a = anchor_.data() + offset_[o];
    double* e = allowance_.data() + offset_[o];
    double most = 0.0;
    const double rest = kSkin * radius_[o], motion = kSkinMotion * radius_[o];
    for (std::size_t i = 0; i < x.size(); ++i) {
      a[i] = x[i] + (ahead - 0.5 * h) * v[i];
      // a faster particle than kSkinMotion r per sub-step has the list built again soon
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
}

// The broad phase, a sweep on the lower x bound: an object alone costs nothing per particle.
void ObjectContactSolver::findObjectPairs(const ObjectContactParams& params) {
  const std::size_t N = lo_.size();
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
}

// Hashes the particles that may meet a stale object's, inner ones too (an impact lets them through the surface).
std::size_t ObjectContactSolver::hashNearParticles(const ObjectContactParams& params) {
  const std::size_t N = near_.size();
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
  return n;
}

// Pairs of two settled objects need no search; an awake pair restarts cold after a build (a pile then rests sooner).
std::size_t ObjectContactSolver::keepPairsOfSettledObjects() {
  std::size_t kept = 0;
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const std::uint32_t o1 = owner_[keys_[i].first], o2 = owner_[keys_[i].second];
    if (stale_[o1] || stale_[o2]) continue;
    const bool sleeping = frozen_ != nullptr && (frozen(o1) || frozen(o2));
    const bool carry = sleeping && carries(keptPairs_[i].lambda, keptPairs_[i].friction);
    keptPairs_[kept] = carry ? keptPairs_[i] : Impulses();
    keys_[kept++] = keys_[i];
  }
  keys_.resize(kept);
  return kept;
}

// The new pairs of a stale object, each found once and none missed.
void ObjectContactSolver::searchHash(const std::vector<Solver*>& objects, const ObjectContactParams& params,
                                     std::size_t hashed, double baseReach, double widest) {
  // a slow particle's partners lie in the 27 cells around it, a fast one (ball > baseReach) searches
  // ball + widest; a pair is taken by its fast particle, else its stale one, else its first
  hash_.build(hashX_, hashed, 2.0 * baseReach);
  for (std::size_t e1 = 0; e1 < hashed; ++e1) {  // e: an entry of the hash
    const std::uint32_t g1 = hashGlobal_[e1], o1 = hashObject_[e1];
    const bool fast1 = hashBall_[e1] > baseReach, stale1 = stale_[o1] != 0;
    if (!fast1 && !stale1) continue;
    auto consider = [&](std::uint32_t e2) {
      const std::uint32_t o2 = hashObject_[e2];
      if (o1 == o2 ? !params.selfContact || e2 == e1 : !params.enabled) return;
      const bool stale2 = stale_[o2] != 0;
      if (!stale1 && !stale2) return;  // kept
      const bool fast2 = hashBall_[e2] > baseReach;
      if (fast1 != fast2 ? fast2 : stale1 != stale2 ? stale2 : e2 < e1) return;  // e2's search takes it
      const std::uint32_t g2 = hashGlobal_[e2];
      if (o1 == o2) {
        const auto& cells = objects[o1]->lattice().cells();
        const Eigen::Vector3i d = cells[g1 - offset_[o1]] - cells[g2 - offset_[o2]];
        if (d.cwiseAbs().maxCoeff() <= params.selfExclusion) return;
      }
      const double R = hashBall_[e1] + hashBall_[e2];
      if ((hashX_[e1] - hashX_[e2]).squaredNorm() >= R * R) return;
      keys_.emplace_back(std::min(g1, g2), std::max(g1, g2));
    };
    if (fast1)
      hash_.forEachWithin(hashX_[e1], hashBall_[e1] + widest, scratch_, consider);
    else
      hash_.forEachNear(hashX_[e1], consider);
  }
}

// The warm start's impulses line up with the new keys: zero for a new pair unless carried_ holds its impulses.
void ObjectContactSolver::restoreImpulses(std::size_t kept, bool all) {
  reserveDoubling(keys_, keys_.size());
  reserveDoubling(keptPairs_, keys_.size());
  // the next build carries some of these keys: sized by them, not by the most carried so far
  reserveDoubling(carried_, keys_.size());
  keptPairs_.resize(kept);
  keptPairs_.resize(keys_.size());
  for (std::size_t i = kept; i < keys_.size() && !carried_.empty(); ++i) {
    const auto it = std::lower_bound(carried_.begin(), carried_.end(), keys_[i],
                                     [](const Carried& c, const Key& k) { return c.key < k; });
    if (it == carried_.end() || it->key != keys_[i]) continue;
    keptPairs_[i] = it->impulses;
  }
  if (all || frozen_ == nullptr)
    keptCollider_.clear();
  else
    keepFrozenColliderImpulses();  // global numbers: valid over a build of some objects
}

// The passes work on dense arrays of the listed particles only, in the order of their global numbers.
void ObjectContactSolver::renumberParticles() {
  const std::size_t total = offset_.back();
  renumber_.assign(total, -1);
  for (const auto& key : keys_) renumber_[key.first] = renumber_[key.second] = 0;
  count_ = 0;
  for (std::size_t g = 0; g < total; ++g)
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
  for (std::size_t g = 0; g < total; ++g) {
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

}  // namespace deformable_flsm
