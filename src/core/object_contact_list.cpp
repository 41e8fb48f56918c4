// The object contact's candidate list (see ObjectContactSolver::substep() in object_contact.h): a
// Verlet list of particle pairs, kept while every particle stays within its allowance of its
// anchor, measured against its own object's motion, and every pair of objects near each other
// within its allowance of where it was relative to the other; built again for the objects that
// left them.
//
// Each object o carries a shift s_o: how far the mean of its particles moved since its anchors
// were set. Particle i of o is at a_i + s_o + d_i, d_i its own motion, kept within its allowance
// e_i (|d_i| < e_i, at the end and at the start of each sub-step). A pair of objects (a, b) near
// each other is searched with their anchors shifted to where the objects were then, and its pairs
// listed when closer than reach_i + e_i + reach_j + e_j + f_ab; it holds while the objects' shift
// relative to each other moved by less than f_ab from what it was then (its drift). Two particles
// not listed then stay farther apart than reach_i + reach_j:
//   |x_i - x_j| >= |a_i + s_a - a_j - s_b|_then - drift - e_i - e_j > reach_i + reach_j.
// Objects whose bounds did not meet then are watched by their bounds, shifted, every sub-step. A
// pile that falls together, or slides on as one, keeps its list.
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

/// A particle's allowance around its anchor, in its object: this fraction of its radius (a pile at rest keeps its list) ...
constexpr double kSkin = 0.15;
/// ... plus its motion in its object over this many sub-steps at its speed after the build ...
constexpr int kSkinSubsteps = 2;
/// ... up to this fraction of its radius: wider allowances make the list long.
constexpr double kSkinMotion = 0.5;
/// A pair of objects' allowance for drifting from each other: each object's share is half of this
/// fraction of its radius plus its motion relative to the objects near it, as for a particle.
constexpr double kPairSkin = 0.1;
/// Objects are paired when their bounds come within this fraction of their radii of each other (more
/// than their allowances reach), so that a pile does not build again for every pair that nears.
constexpr double kPairPad = 0.1;

/// The allowance of a motion of `step` per sub-step around an anchor set mid-motion, with `rest` for
/// a motion that stops: the end and start of the sub-step lie half a step away, and room for
/// kSkinSubsteps more, up to `most`.
double allowanceOf(double rest, double step, double most) {
  return rest + std::max(0.5 * step, std::min((kSkinSubsteps + 0.5) * step, most));
}

/// Calls f(a, b), a < b, for every two boxes that meet, the boxes being lo/hi plus shift, inflated by
/// padScale times each object's radius, by a sweep on the lower x bound with `order` as scratch.
template <typename F>
void forMeetingBoxes(const std::vector<Eigen::Vector3d>& lo, const std::vector<Eigen::Vector3d>& hi,
                     const std::vector<Eigen::Vector3d>& shiftLo, const std::vector<Eigen::Vector3d>& shiftHi,
                     const std::vector<double>& radius, double padScale, std::vector<std::uint32_t>& order, F&& f) {
  const std::size_t N = lo.size();
  auto lower = [&](std::uint32_t o) -> Eigen::Vector3d {
    return lo[o] + shiftLo[o] - Eigen::Vector3d::Constant(padScale * radius[o]);
  };
  auto upper = [&](std::uint32_t o) -> Eigen::Vector3d {
    return hi[o] + shiftHi[o] + Eigen::Vector3d::Constant(padScale * radius[o]);
  };
  order.resize(N);
  for (std::size_t o = 0; o < N; ++o) order[o] = static_cast<std::uint32_t>(o);
  std::sort(order.begin(), order.end(), [&](std::uint32_t a, std::uint32_t b) {
    const double la = lower(a).x(), lb = lower(b).x();
    return la != lb ? la < lb : a < b;
  });
  for (std::size_t i = 0; i < N; ++i) {
    const std::uint32_t a = order[i];
    const Eigen::Vector3d loA = lower(a), hiA = upper(a);
    for (std::size_t j = i + 1; j < N; ++j) {
      const std::uint32_t b = order[j];
      const Eigen::Vector3d loB = lower(b);
      if (loB.x() > hiA.x()) break;
      if ((loA.array() <= upper(b).array()).all() && (loB.array() <= hiA.array()).all()) f(std::min(a, b), std::max(a, b));
    }
  }
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

// An object one of whose particles (listed or not) left its allowance, either object of a pair that
// drifted, and two objects that came near without being paired need their pairs built again.
ObjectContactSolver::Staleness ObjectContactSolver::findStale(const std::vector<Solver*>& objects,
                                                              const ObjectContactParams& params, double h,
                                                              double ahead) {
  if (!builtFor(objects, params)) return Staleness::kAll;
  bool any = false;
  for (std::size_t o = 0; o < objects.size(); ++o) {
    // a sleeping object at rest that was within its allowances still is: nothing of it moved since
    // (a change from outside moves its state version), and with no velocity h and ahead do not count
    const bool held = asleep(o);
    if (held && restChecked_[o] && restVersion_[o] == objects[o]->stateVersion()) {
      stale_[o] = 0;
      continue;
    }
    restChecked_[o] = 0;
    const auto& x = objects[o]->positions();
    const auto& v = objects[o]->velocities();
    const Eigen::Vector3d* a = anchor_.data() + offset_[o];
    const double* e = allowance_.data() + offset_[o];
    const std::size_t n = x.size();
    Eigen::Vector3d sumX = Eigen::Vector3d::Zero(), sumV = Eigen::Vector3d::Zero();
    bool still = held;  // every velocity zero (looked at only for a sleeping object)
    for (std::size_t i = 0; i < n; ++i) {
      sumX += x[i] + ahead * v[i] - a[i];
      sumV += v[i];
      still = still && v[i].isZero(0.0);
    }
    const Eigen::Vector3d meanV = meanV_[o] = sumV / double(n);
    shiftEnd_[o] = sumX / double(n);
    shiftStart_[o] = shiftEnd_[o] - h * meanV;
    stale_[o] = 0;
    for (std::size_t i = 0; i < n; ++i) {
      const Eigen::Vector3d d = x[i] + ahead * v[i] - a[i] - shiftEnd_[o];
      const double e2 = e[i] * e[i];
      if (d.squaredNorm() >= e2 || (d - h * (v[i] - meanV)).squaredNorm() >= e2) {
        stale_[o] = 1;
        any = true;
        break;
      }
    }
    if (held && still && !stale_[o]) {
      restChecked_[o] = 1;
      restVersion_[o] = objects[o]->stateVersion();
    }
  }
  for (std::size_t p = 0; p < objectPairs_.size(); ++p) {
    const std::uint32_t a = objectPairs_[p].first, b = objectPairs_[p].second;
    const double f2 = pairSlack_[p] * pairSlack_[p];
    if ((shiftEnd_[a] - shiftEnd_[b] - pairShift_[p]).squaredNorm() >= f2 ||
        (shiftStart_[a] - shiftStart_[b] - pairShift_[p]).squaredNorm() >= f2) {
      stale_[a] = stale_[b] = 1;
      any = true;
    }
  }
  if (params.enabled) {
    for (std::size_t o = 0; o < objects.size(); ++o) {
      shiftLo_[o] = shiftEnd_[o].cwiseMin(shiftStart_[o]);
      shiftHi_[o] = shiftEnd_[o].cwiseMax(shiftStart_[o]);
    }
    forMeetingBoxes(lo_, hi_, shiftLo_, shiftHi_, radius_, 0.0, order_, [&](std::uint32_t a, std::uint32_t b) {
      if (std::binary_search(objectPairs_.begin(), objectPairs_.end(), std::make_pair(a, b))) return;
      stale_[a] = stale_[b] = 1;
      any = true;
    });
  }
  return any ? Staleness::kSome : Staleness::kNone;
}

// Builds the stale objects' pairs and keeps the others', the list then in the order of its particles: deterministic.
void ObjectContactSolver::buildList(const std::vector<Solver*>& objects, const ObjectContactParams& params, double h,
                                    bool all, double ahead) {
  ++listBuilds_;
  carryAsleepPairImpulses(all);
  if (all) resetList(objects, params);
  anchorStale(objects, h, ahead);
  findObjectPairs(params, h);
  const std::size_t hashed = hashSelfContact(params);
  const std::size_t kept = keepPairsOfSettledObjects();
  searchObjectPairs();
  if (hashed > 0) searchSelfContact(objects, params, hashed);
  orderNewPairs(kept);
  restoreImpulses(kept, all);
  mergeKeptAndNew(kept);
  std::fill(stale_.begin(), stale_.end(), 0);
  renumberParticles();
}

// A sleeping object's pairs with a stale one keep their impulses for when it wakes, carried by key.
void ObjectContactSolver::carryAsleepPairImpulses(bool all) {
  carried_.clear();
  if (all || asleep_ == nullptr) return;
  for (std::size_t i = 0; i < keys_.size(); ++i) {
    const std::uint32_t o1 = owner_[keys_[i].first], o2 = owner_[keys_[i].second];
    if ((!stale_[o1] && !stale_[o2]) || (!asleep(o1) && !asleep(o2))) continue;
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
  for (auto* v : {&shiftEnd_, &shiftStart_, &shiftMid_, &shiftLo_, &shiftHi_, &meanV_}) v->assign(N, Eigen::Vector3d::Zero());
  fastest_.assign(N, 0.0);
  half_.assign(N, 0.0);
  objectPairs_.clear();  // of other objects: none carries over
  pairShift_.clear();
  pairSlack_.clear();
  radius_.resize(N);
  reach_.resize(N);
  most_.resize(N);
  stale_.assign(N, 1);
  restChecked_.assign(N, 0);
  restVersion_.assign(N, 0);
  reserveDoubling(slotsAsleep_, N);
  keys_.clear();
  const std::size_t total = offset_[N];
  hash_.reserve(total);
  reserveDoubling(hashGlobal_, total);
  reserveDoubling(hashObject_, total);
  reserveDoubling(hashX_, total);
  reserveDoubling(hashBall_, total);
  reserveDoubling(firstCount_, total + 1);
  std::size_t largest = 0;  // the most particles of one object: a sweep's entries
  for (std::size_t o = 0; o < N; ++o) largest = std::max(largest, offset_[o + 1] - offset_[o]);
  reserveDoubling(sweepA_, largest);
  reserveDoubling(sweepB_, largest);
  for (std::size_t o = 0; o < N; ++o) {
    builtRadius_[o] = radius_[o] = objects[o]->contactRadius();
    reach_[o] = radius_[o] * (1.0 + kContactMargin);
  }
}

// Anchors mid-motion with room for a few sub-steps of a particle's motion in its object, so the list outlives the build.
void ObjectContactSolver::anchorStale(const std::vector<Solver*>& objects, double h, double ahead) {
  for (std::size_t o = 0; o < objects.size(); ++o) {
    if (!stale_[o]) {  // the anchors stay: the shift to the middle of the motion checked
      shiftMid_[o] = 0.5 * (shiftEnd_[o] + shiftStart_[o]);
      continue;
    }
    restChecked_[o] = 0;
    const auto& x = objects[o]->positions();
    const auto& v = objects[o]->velocities();
    const std::size_t n = x.size();
    Eigen::Vector3d* a = anchor_.data() + offset_[o];
    double* e = allowance_.data() + offset_[o];
    Eigen::Vector3d sumV = Eigen::Vector3d::Zero();
    for (std::size_t i = 0; i < n; ++i) sumV += v[i];
    meanV_[o] = sumV / double(n);
    shiftMid_[o].setZero();
    double most = 0.0;
    const double rest = kSkin * radius_[o], motion = kSkinMotion * radius_[o];
    for (std::size_t i = 0; i < n; ++i) {
      a[i] = x[i] + (ahead - 0.5 * h) * v[i];
      // a particle moving in its object faster than kSkinMotion r per sub-step has the list built again soon
      e[i] = allowanceOf(rest, h * (v[i] - meanV_[o]).norm(), motion);
      most = std::max(most, e[i]);
    }
    most_[o] = most;
    Eigen::Vector3d lo = a[0], hi = lo;
    for (std::size_t i = 1; i < n; ++i) {
      lo = lo.cwiseMin(a[i]);
      hi = hi.cwiseMax(a[i]);
    }
    lo_[o] = lo.array() - (reach_[o] + most);
    hi_[o] = hi.array() + (reach_[o] + most);
  }
}

// The broad phase, a sweep on the lower x bound: an object alone costs nothing per particle. A pair of
// two objects that stay keeps its shift and allowance; a pair with a stale object starts from here,
// and a stale object's share of its pairs' allowance follows its motion relative to the objects near it.
void ObjectContactSolver::findObjectPairs(const ObjectContactParams& params, double h) {
  const std::size_t N = lo_.size();
  oldPairs_.swap(objectPairs_);
  oldShift_.swap(pairShift_);
  oldSlack_.swap(pairSlack_);
  objectPairs_.clear();
  pairShift_.clear();
  pairSlack_.clear();
  newPairs_.clear();
  if (params.enabled) {
    // padded by a share of the pairs' allowance at its cap, (kPairSkin + kSkinMotion) / 2 of a radius, and kPairPad
    forMeetingBoxes(lo_, hi_, shiftMid_, shiftMid_, radius_, kPairPad + 0.5 * (kPairSkin + kSkinMotion), order_,
                    [&](std::uint32_t a, std::uint32_t b) { newPairs_.emplace_back(a, b); });
    std::sort(newPairs_.begin(), newPairs_.end());
  }
  // a stale object's share: its fastest motion relative to an object near it
  std::fill(fastest_.begin(), fastest_.end(), 0.0);
  for (const ObjectPair& p : newPairs_) {
    const double step = h * (meanV_[p.first] - meanV_[p.second]).norm();
    fastest_[p.first] = std::max(fastest_[p.first], step);
    fastest_[p.second] = std::max(fastest_[p.second], step);
  }
  for (std::size_t o = 0; o < N; ++o)
    if (stale_[o]) half_[o] = 0.5 * allowanceOf(kPairSkin * radius_[o], fastest_[o], kSkinMotion * radius_[o]);
  // the kept pairs of two objects that stay, and the new pairs of a stale object, in order
  std::size_t old = 0, fresh = 0;
  while (old < oldPairs_.size() || fresh < newPairs_.size()) {
    const bool fromOld = fresh == newPairs_.size() || (old < oldPairs_.size() && oldPairs_[old] < newPairs_[fresh]);
    const ObjectPair p = fromOld ? oldPairs_[old] : newPairs_[fresh];
    const bool both = !fromOld && old < oldPairs_.size() && oldPairs_[old] == p;
    if (!stale_[p.first] && !stale_[p.second]) {
      // as it was (two staying objects that near without a pair are found by findStale())
      if (fromOld || both) {
        objectPairs_.push_back(p);
        pairShift_.push_back(oldShift_[old]);
        pairSlack_.push_back(oldSlack_[old]);
      }
    } else if (!fromOld) {
      objectPairs_.push_back(p);
      pairShift_.push_back(shiftMid_[p.first] - shiftMid_[p.second]);
      pairSlack_.push_back(half_[p.first] + half_[p.second]);
    }
    if (fromOld || both) ++old;
    if (!fromOld) ++fresh;
  }
}

// With self-contact, hashes every particle of a stale object (an impact lets inner ones through its surface).
std::size_t ObjectContactSolver::hashSelfContact(const ObjectContactParams& params) {
  if (!params.selfContact) return 0;
  std::size_t n = 0;
  for (std::size_t o = 0; o < stale_.size(); ++o) {
    if (!stale_[o]) continue;
    const Eigen::Vector3d* a = anchor_.data() + offset_[o];
    const double* e = allowance_.data() + offset_[o];
    for (std::size_t i = 0; i < offset_[o + 1] - offset_[o]; ++i) {
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
      hashBall_[n] = reach_[o] + e[i];
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
    const bool sleeping = asleep_ != nullptr && (asleep(o1) || asleep(o2));
    const bool carry = sleeping && carries(keptPairs_[i].lambda, keptPairs_[i].friction);
    keptPairs_[kept] = carry ? keptPairs_[i] : Impulses();
    keys_[kept++] = keys_[i];
  }
  keys_.resize(kept);
  return kept;
}

// The new pairs of two objects, one of them stale: per pair of objects whose bounds meet, only the
// particles whose balls reach into the other's bounds, their anchors where their objects are, swept
// along the longest side of where the bounds overlap (the face where they touch spans it). Its own
// object's particles are never visited.
void ObjectContactSolver::searchObjectPairs() {
  for (std::size_t p = 0; p < objectPairs_.size(); ++p) {
    const std::uint32_t a = objectPairs_[p].first, b = objectPairs_[p].second;
    if (!stale_[a] && !stale_[b]) continue;  // kept
    const Eigen::Vector3d overlap =
        (hi_[a] + shiftMid_[a]).cwiseMin(hi_[b] + shiftMid_[b]) - (lo_[a] + shiftMid_[a]).cwiseMax(lo_[b] + shiftMid_[b]);
    int axis = 0;
    overlap.maxCoeff(&axis);
    const double widestA = selectNear(a, b, axis, sweepA_), widestB = selectNear(b, a, axis, sweepB_);
    if (sweepA_.empty() || sweepB_.empty()) continue;
    const double window = widestA + widestB;
    std::size_t first = 0;  // the first of b's entries not yet behind a's sweep
    for (const SweepEntry& ea : sweepA_) {
      const double key = ea.x[axis];
      while (first < sweepB_.size() && sweepB_[first].x[axis] <= key - window) ++first;
      const double farthest = key + ea.ball + widestB;
      for (std::size_t j = first; j < sweepB_.size() && sweepB_[j].x[axis] < farthest; ++j) {
        const SweepEntry& eb = sweepB_[j];
        const double R = ea.ball + eb.ball;
        if ((ea.x - eb.x).squaredNorm() >= R * R) continue;
        keys_.emplace_back(std::min(ea.g, eb.g), std::max(ea.g, eb.g));
      }
    }
  }
}

// Object o's particles, where o is, whose balls (with o's share of the pairs' allowance) may reach the
// other's, sorted along the axis; returns their widest ball.
double ObjectContactSolver::selectNear(std::uint32_t o, std::uint32_t other, int axis, std::vector<SweepEntry>& out) {
  out.clear();
  const Eigen::Vector3d* a = anchor_.data() + offset_[o];
  const double* e = allowance_.data() + offset_[o];
  const Eigen::Vector3d lo = (lo_[other] + shiftMid_[other]).array() - half_[other];
  const Eigen::Vector3d hi = (hi_[other] + shiftMid_[other]).array() + half_[other];
  double widest = 0.0;
  for (std::size_t i = 0; i < offset_[o + 1] - offset_[o]; ++i) {
    const double ball = reach_[o] + e[i] + half_[o];
    const Eigen::Vector3d x = a[i] + shiftMid_[o];
    if (((x.array() + ball) < lo.array()).any() || ((x.array() - ball) > hi.array()).any()) continue;
    out.push_back({x, ball, static_cast<std::uint32_t>(offset_[o] + i)});
    widest = std::max(widest, ball);
  }
  std::sort(out.begin(), out.end(), [axis](const SweepEntry& l, const SweepEntry& r) {
    return l.x[axis] != r.x[axis] ? l.x[axis] < r.x[axis] : l.g < r.g;
  });
  return widest;
}

// The new pairs of a stale object with itself, each found once and none missed.
void ObjectContactSolver::searchSelfContact(const std::vector<Solver*>& objects, const ObjectContactParams& params,
                                            std::size_t hashed) {
  // a slow particle's partners lie in the 27 cells around it, a fast one (ball > slow) searches
  // ball + widest; a pair is taken by its fast particle, else its first
  double slow = 0.0, widest = 0.0;
  for (std::size_t o = 0; o < stale_.size(); ++o) slow = std::max(slow, reach_[o] + (kSkin + kSkinMotion) * radius_[o]);
  for (std::size_t e = 0; e < hashed; ++e) widest = std::max(widest, hashBall_[e]);
  hash_.build(hashX_, hashed, 2.0 * slow);
  for (std::size_t e1 = 0; e1 < hashed; ++e1) {  // e: an entry of the hash
    const std::uint32_t g1 = hashGlobal_[e1], o1 = hashObject_[e1];
    const bool fast1 = hashBall_[e1] > slow;
    auto consider = [&](std::uint32_t e2) {
      if (hashObject_[e2] != o1 || e2 == e1) return;
      const bool fast2 = hashBall_[e2] > slow;
      if (fast1 != fast2 ? fast2 : e2 < e1) return;  // e2's search takes it
      const std::uint32_t g2 = hashGlobal_[e2];
      const auto& cells = objects[o1]->lattice().cells();
      const Eigen::Vector3i d = cells[g1 - offset_[o1]] - cells[g2 - offset_[o1]];
      if (d.cwiseAbs().maxCoeff() <= params.selfExclusion) return;
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

// The new pairs in the order of their particles, the first then the second (a counting sort by the
// first, each first's few pairs then sorted by the second): the passes meet each particle's contacts
// together, in an order that does not depend on the search's, and a pile's solve converges in fewer
// passes than in the search's order.
void ObjectContactSolver::orderNewPairs(std::size_t kept) {
  const std::size_t total = offset_.back(), fresh = keys_.size() - kept;
  if (fresh < 2) return;
  firstCount_.assign(total + 1, 0);
  for (std::size_t i = kept; i < keys_.size(); ++i) ++firstCount_[keys_[i].first + 1];
  for (std::size_t g = 0; g < total; ++g) firstCount_[g + 1] += firstCount_[g];
  keyScratch_.resize(fresh);
  for (std::size_t i = kept; i < keys_.size(); ++i) keyScratch_[firstCount_[keys_[i].first]++] = keys_[i];
  // firstCount_[g] is now the end of g's pairs
  std::size_t begin = 0;
  for (std::size_t g = 0; g < total && begin < fresh; ++g) {
    const std::size_t end = firstCount_[g];
    for (std::size_t i = begin + 1; i < end; ++i)  // insertion sort: a particle has few new pairs
      for (std::size_t k = i; k > begin && keyScratch_[k].second < keyScratch_[k - 1].second; --k)
        std::swap(keyScratch_[k], keyScratch_[k - 1]);
    begin = end;
  }
  std::copy(keyScratch_.begin(), keyScratch_.end(), keys_.begin() + static_cast<std::ptrdiff_t>(kept));
}

// The kept pairs (in order) and the new ones (ordered) merged, with their impulses: the whole list in
// the order of its particles, whatever builds made it.
void ObjectContactSolver::mergeKeptAndNew(std::size_t kept) {
  if (kept == 0 || kept == keys_.size()) return;
  keyScratch_.resize(keys_.size());
  impulseScratch_.resize(keys_.size());
  std::size_t i = 0, j = kept, n = 0;
  while (i < kept || j < keys_.size()) {
    const bool fromKept = j == keys_.size() || (i < kept && keys_[i] < keys_[j]);
    const std::size_t k = fromKept ? i++ : j++;
    keyScratch_[n] = keys_[k];
    impulseScratch_[n++] = keptPairs_[k];
  }
  keys_.swap(keyScratch_);
  keptPairs_.swap(impulseScratch_);
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
  if (all || asleep_ == nullptr)
    keptCollider_.clear();
  else
    keepAsleepColliderImpulses();  // global numbers: valid over a build of some objects
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
  reserveDoubling(awakeSlots_, keys_.size());
  reserveDoubling(awakeParticles_, count_);
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

// The passes leave two sleeping objects' pairs alone: a pile asleep around a few awake objects costs what they touch.
void ObjectContactSolver::selectAwake() {
  const std::size_t N = builtObjects_.size();
  // chosen after the list's latest build (every build counts in listBuilds_) and for the same sleeping objects
  bool same = awakeBuild_ == listBuilds_;
  for (std::size_t o = 0; same && o < N; ++o) same = slotsAsleep_[o] == char(asleep(static_cast<std::uint32_t>(o)));
  if (same) return;
  awakeBuild_ = listBuilds_;
  slotsAsleep_.resize(N);
  for (std::size_t o = 0; o < N; ++o) slotsAsleep_[o] = asleep(static_cast<std::uint32_t>(o));
  awakeSlots_.clear();
  awakeParticles_.clear();
  std::fill(touched_.begin(), touched_.end(), 0);  // here: marks the particles named
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const std::uint32_t k1 = candidates_[i].first, k2 = candidates_[i].second;
    if (slotsAsleep_[object_[k1]] && slotsAsleep_[object_[k2]]) continue;
    awakeSlots_.push_back(static_cast<std::uint32_t>(i));
    touched_[k1] = touched_[k2] = 1;
  }
  for (std::size_t k = 0; k < count_; ++k)
    if (touched_[k]) awakeParticles_.push_back(static_cast<std::uint32_t>(k));
  std::fill(touched_.begin(), touched_.end(), 0);
}

}  // namespace deformable_flsm
