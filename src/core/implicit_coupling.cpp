// Several objects' implicit sub-step as one system (see implicit_coupling.h).
//
// Why one system: with each object solved alone and the contact between objects after the solves
// (a splitting), a contact stops the touching layer of particles only; the rest of an object
// resting on another goes on falling for the sub-step and is stopped by its own stiffness in the
// next one. At one sub-step of 1/60 s a stack of soft cubes crushed to half its height and
// toppled that way; holding each object against the other's velocity in turn (Dirichlet-Neumann)
// was exact at 2 and more sub-steps but unstable at one, and for stiff objects at any count up to
// 8 (docs/method.md). In one solve the contact decelerates both objects through their stiffness
// within the sub-step, as a collider contact does one object's.
//
// The contact is a one-sided spring per touching particle pair, about as stiff as the material
// about it (coupling_spring::kStiffness), at rest at a skin (kSkin of r_1 + r_2) outside the spheres'
// touching distance, so that the weight it
// carries leaves the spheres apart by a little less than the skin and the object contact pass
// after the solve finds nothing to push; that pass still keeps every pair apart (the springs'
// deflection under a larger load, pairs the solve did not see) and applies the friction between
// the objects, bounded by the springs' normal impulse as well as its own. Backward Euler makes
// the spring's stiffness free of a time-step bound.
#include "deformable_flsm/core/implicit_coupling.h"

#include "deformable_flsm/core/solver.h"
#include "implicit_solve.h"

#include <algorithm>
#include <chrono>
#include <cmath>

namespace deformable_flsm {

using namespace implicit_solve;
namespace spring = coupling_spring;

namespace {

/// CG's tolerance and floor for the coupled solve, against each object's own 1e-2 and 1e-3: a
/// pile's slow modes (objects rocking on each other's springs) are where CG leaves its error. At
/// 1e-2 a stack of three 10 MPa cubes began to rock after 3 s and its top slid a centimetre by
/// 4 s (at 1e-3 it stood for the 20 s watched); at 1e-3 a bin of twenty 30 kPa objects kept one
/// particle rocking at 1.3 cm/s, at 1e-4 it came to rest (2.2 mm/s, test_world_scenes' bound 4.5) for
/// 37 % more CPU. The floor was measured with them (1e-3 and 1e-4 of a particle's gravity impulse
/// left the bin rocking at 1.2 and 0.14 cm/s with the tolerance at 1e-3).
constexpr double kCouplingCgTolerance = 1e-4;
constexpr double kCouplingCgFloor = 3e-5;

}  // namespace

void ImplicitCoupling::gather(const std::vector<Solver*>& objects) {
  for (std::size_t m = 0; m < members_.size(); ++m) {
    Solver& s = *objects[members_[m]];
    const std::size_t b = start_[m], n = s.positions().size();
    const std::vector<Eigen::Vector3d>& velocity = s.implicitVelocity();
    const std::vector<Eigen::Vector3d>& rhs = s.implicitRhs();
    const std::vector<PcgConstraint>& constraint = s.implicitConstraints();
    const std::vector<Eigen::Vector3d>& normal = s.implicitNormals();
    for (std::size_t i = 0; i < n; ++i) {
      velocity_[b + i] = velocity[i];
      rhs_[b + i] = rhs[i];
      constraint_[b + i] = constraint[i];
      normal_[b + i] = normal[i];
    }
  }
  std::fill(springDiagonal_.begin(), springDiagonal_.end(), Eigen::Vector3d::Zero());
  for (const Spring& sp : springs_) {
    if (!sp.active) continue;
    const Eigen::Vector3d f = (-sp.k * sp.gap / h_) * sp.n;
    rhs_[sp.row1] += f;
    rhs_[sp.row2] -= f;
    const Eigen::Vector3d d = sp.k * sp.n.cwiseAbs2();
    springDiagonal_[sp.row1] += d;
    springDiagonal_[sp.row2] += d;
  }
  for (const Spring& sp : held_) {
    if (!sp.active) continue;
    rhs_[sp.row1] += (-sp.k * sp.gap / h_) * sp.n;
    springDiagonal_[sp.row1] += sp.k * sp.n.cwiseAbs2();
  }
  for (std::size_t m = 0; m < members_.size(); ++m) {
    const std::vector<Eigen::Vector3d>& invDiagonal = objects[members_[m]]->implicitInvDiagonal();
    const std::size_t b = start_[m], n = invDiagonal.size();
    for (std::size_t i = 0; i < n; ++i)
      inv_[m][i] = (invDiagonal[i].cwiseInverse() + springDiagonal_[b + i]).cwiseInverse();
  }
}

template <class Apply>
void ImplicitCoupling::perMember(const std::vector<Solver*>& objects, const std::vector<Eigen::Vector3d>& in,
                                 std::vector<Eigen::Vector3d>& out, Apply&& apply) {
  for (std::size_t m = 0; m < members_.size(); ++m) {
    const std::size_t b = start_[m], n = in_[m].size();
    std::copy(in.begin() + static_cast<std::ptrdiff_t>(b), in.begin() + static_cast<std::ptrdiff_t>(b + n), in_[m].begin());
    apply(*objects[members_[m]], m);
    std::copy(out_[m].begin(), out_[m].end(), out.begin() + static_cast<std::ptrdiff_t>(b));
  }
}

void ImplicitCoupling::product(const std::vector<Solver*>& objects, const std::vector<Eigen::Vector3d>& p,
                               std::vector<Eigen::Vector3d>& y) {
  perMember(objects, p, y, [this](Solver& s, std::size_t m) { s.implicitProduct(in_[m], out_[m]); });
  for (const Spring& sp : springs_) {
    if (!sp.active) continue;
    const Eigen::Vector3d f = (sp.k * sp.n.dot(p[sp.row1] - p[sp.row2])) * sp.n;
    y[sp.row1] += f;
    y[sp.row2] -= f;
  }
  for (const Spring& sp : held_)
    if (sp.active) y[sp.row1] += (sp.k * sp.n.dot(p[sp.row1])) * sp.n;
}

void ImplicitCoupling::precondition(const std::vector<Solver*>& objects, const std::vector<Eigen::Vector3d>& r,
                                    std::vector<Eigen::Vector3d>& z) {
  perMember(objects, r, z, [this](Solver& s, std::size_t m) { s.implicitPrecondition(inv_[m], in_[m], out_[m]); });
}

// A candidate pair of a coupled object's particle and a sleeping object's: a spring as while both
// were awake (the sleeping particle's diagonal from its last sub-step, so that the equilibrium
// the pile fell asleep in stays one), the sleeping particle held still.
void ImplicitCoupling::holdSpring(const std::vector<Solver*>& objects, const std::vector<char>& asleep, Spring sp,
                                  std::size_t slot, double h) {
  const auto isAsleep = [&](std::uint32_t o) { return o < asleep.size() && asleep[o] != 0; };
  if (place_[sp.o1] < 0 && place_[sp.o2] >= 0 && isAsleep(sp.o1)) {  // the coupled particle first
    std::swap(sp.o1, sp.o2);
    std::swap(sp.i1, sp.i2);
  }
  if (place_[sp.o1] < 0 || !isAsleep(sp.o2)) return;
  const Solver& a = *objects[sp.o1];
  const Solver& b = *objects[sp.o2];
  if (a.isPrescribed(sp.i1)) return;
  if (!spring::geometry(a.positions()[sp.i1], a.contactRadius(), b.positions()[sp.i2], b.contactRadius(), sp.n,
                        sp.gap))
    return;
  const double predicted = spring::gapAfter(sp.gap, sp.n, a.velocities()[sp.i1], h);
  const std::vector<Eigen::Vector3d>& invB = b.implicitInvDiagonal();
  const double d1 = 3.0 / a.implicitInvDiagonal()[sp.i1].sum();
  const double d2 = sp.i2 < invB.size() ? 3.0 / invB[sp.i2].sum() : d1;
  sp.k = spring::stiffness(d1, a.lattice().masses()[sp.i1], false, d2, b.lattice().masses()[sp.i2],
                           b.isPrescribed(sp.i2));
  sp.row1 = static_cast<std::uint32_t>(start_[static_cast<std::size_t>(place_[sp.o1])] + sp.i1);
  sp.row2 = 0;
  sp.slot = static_cast<std::uint32_t>(slot);
  sp.active = spring::activeAfter(false, predicted);
  held_.push_back(sp);
}

void ImplicitCoupling::recordImpulse(const Spring& sp, double lambda) {
  CouplingImpulse ci;
  ci.g1 = static_cast<std::uint32_t>(globalStart_[sp.o1] + sp.i1);
  ci.g2 = static_cast<std::uint32_t>(globalStart_[sp.o2] + sp.i2);
  ci.slot = sp.slot;
  ci.n = sp.n;
  ci.lambda = lambda;
  impulses_.push_back(ci);
}

bool ImplicitCoupling::updateSprings(double h) {
  bool changed = false;
  for (Spring& sp : springs_) {
    // the gap the solution ends the sub-step at, less the skin
    const bool active = spring::activeAfter(sp.active, spring::gapAfter(sp.gap, sp.n, velocity_[sp.row1] - velocity_[sp.row2], h));
    changed = changed || active != sp.active;
    sp.active = active;
  }
  for (Spring& sp : held_) {
    const bool active = spring::activeAfter(sp.active, spring::gapAfter(sp.gap, sp.n, velocity_[sp.row1], h));
    changed = changed || active != sp.active;
    sp.active = active;
  }
  return changed;
}

void ImplicitCoupling::substep(const std::vector<Solver*>& objects, const std::vector<char>& coupled,
                               const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairCandidates, int s,
                               double h, const std::vector<char>* asleep) {
  h_ = h;
  placeMembers(objects, coupled);
  const auto t0 = std::chrono::steady_clock::now();
  const double floor = beginMembers(objects, s, h);
  buildSprings(objects, pairCandidates, h, asleep);
  const PcgResult result = solve(objects, h, floor);
  sumSpringImpulses(h);
  for (std::size_t m = 0; m < members_.size(); ++m)
    objects[members_[m]]->endCoupledSubstep(h, result, pcg_.residual(), start_[m], impulseOn_[m]);
  // each member's thread governor gets its share of the solve's time (as advanceSubstep() times
  // an object's own sub-step)
  const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  for (std::uint32_t o : members_) {
    Solver& sv = *objects[o];
    sv.addCoupledSolveTime(seconds * static_cast<double>(sv.positions().size()) /
                           static_cast<double>(std::max<std::size_t>(size_, 1)));
  }
}

void ImplicitCoupling::placeMembers(const std::vector<Solver*>& objects, const std::vector<char>& coupled) {
  // the coupled objects and their places in the solve's vectors
  members_.clear();
  start_.clear();
  globalStart_.assign(objects.size() + 1, 0);
  std::vector<std::int64_t>& place = place_;
  place.assign(objects.size(), -1);
  size_ = 0;
  for (std::size_t o = 0; o < objects.size(); ++o) {
    globalStart_[o + 1] = globalStart_[o] + objects[o]->positions().size();
    if (!coupled[o]) continue;
    place[o] = static_cast<std::int64_t>(members_.size());
    members_.push_back(static_cast<std::uint32_t>(o));
    start_.push_back(size_);
    size_ += objects[o]->positions().size();
  }
  if (velocity_.size() != size_) {
    pcg_.resize(size_);
    velocity_.resize(size_);
    rhs_.resize(size_);
    normal_.resize(size_);
    springDiagonal_.resize(size_);
    constraint_.resize(size_);
  }
  // the members' segments: never fewer slots, each with room for the largest object, so that
  // a slot that holds another object after one fell asleep or woke allocates nothing
  if (in_.size() < members_.size()) {
    in_.resize(members_.size());
    out_.resize(members_.size());
    inv_.resize(members_.size());
    impulseOn_.resize(members_.size());
  }
  std::size_t largest = 0;
  for (const Solver* object : objects) largest = std::max(largest, object->positions().size());
  for (std::size_t m = 0; m < members_.size(); ++m) {
    const std::size_t n = objects[members_[m]]->positions().size();
    for (auto* segment : {&in_[m], &out_[m], &inv_[m], &impulseOn_[m]}) {
      if (segment->capacity() < largest) segment->reserve(largest);
      segment->resize(n);
    }
  }
}

double ImplicitCoupling::beginMembers(const std::vector<Solver*>& objects, int s, double h) {
  // every object's system at the start of the sub-step
  double rhsNorm2 = 0.0, gravityNorm2 = 0.0;
  std::size_t free = 0;
  for (std::uint32_t o : members_) {
    Solver& sv = *objects[o];
    sv.beginCoupledSubstep(s, h);
    rhsNorm2 += sv.implicitRhsNorm2();
    gravityNorm2 += sv.implicitGravityNorm2();
    free += sv.implicitFreeCount();
  }
  return kCouplingCgFloor * std::max({std::sqrt(rhsNorm2), std::sqrt(gravityNorm2), 1e-300}) /
         std::sqrt(static_cast<double>(std::max<std::size_t>(free, 1)));
}

void ImplicitCoupling::buildSprings(const std::vector<Solver*>& objects,
                                    const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairCandidates,
                                    double h, const std::vector<char>* asleep) {
  const std::vector<std::int64_t>& place = place_;
  // a spring per candidate pair of coupled objects, active where predicted within the skin (and
  // one per pair of a coupled and a sleeping object: holdSpring())
  springs_.clear();
  held_.clear();
  const auto locate = [&](std::uint32_t g, std::uint32_t& o, std::uint32_t& i) {
    o = static_cast<std::uint32_t>(std::upper_bound(globalStart_.begin(), globalStart_.end(), g) - globalStart_.begin() - 1);
    i = static_cast<std::uint32_t>(g - globalStart_[o]);
  };
  for (std::size_t c = 0; c < pairCandidates.size(); ++c) {
    Spring sp;
    locate(pairCandidates[c].first, sp.o1, sp.i1);
    locate(pairCandidates[c].second, sp.o2, sp.i2);
    if (place[sp.o1] < 0 || place[sp.o2] < 0) {
      if (asleep != nullptr) holdSpring(objects, *asleep, sp, c, h);
      continue;
    }
    const Solver& a = *objects[sp.o1];
    const Solver& b = *objects[sp.o2];
    const bool fixed1 = a.isPrescribed(sp.i1), fixed2 = b.isPrescribed(sp.i2);
    if (fixed1 && fixed2) continue;
    if (!spring::geometry(a.positions()[sp.i1], a.contactRadius(), b.positions()[sp.i2], b.contactRadius(), sp.n,
                          sp.gap))
      continue;
    const double predicted = spring::gapAfter(sp.gap, sp.n, a.velocities()[sp.i1] - b.velocities()[sp.i2], h);
    // the particles' own diagonals (mass, damping, the material's stiffness bound)
    const double d1 = 3.0 / a.implicitInvDiagonal()[sp.i1].sum(), d2 = 3.0 / b.implicitInvDiagonal()[sp.i2].sum();
    sp.k = spring::stiffness(d1, a.lattice().masses()[sp.i1], fixed1, d2, b.lattice().masses()[sp.i2], fixed2);
    sp.row1 = static_cast<std::uint32_t>(start_[static_cast<std::size_t>(place[sp.o1])] + sp.i1);
    sp.row2 = static_cast<std::uint32_t>(start_[static_cast<std::size_t>(place[sp.o2])] + sp.i2);
    sp.slot = static_cast<std::uint32_t>(c);
    sp.active = spring::activeAfter(false, predicted);
    springs_.push_back(sp);
  }
}

PcgResult ImplicitCoupling::solve(const std::vector<Solver*>& objects, double h, double floor) {
  // one solve, with the objects' collider contacts and the springs in one active set
  const auto apply = [&](const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y) {
    product(objects, p, y);
  };
  const auto precond = [&](const std::vector<Eigen::Vector3d>& r, std::vector<Eigen::Vector3d>& z) {
    precondition(objects, r, z);
  };
  const auto scatter = [&] {
    for (std::size_t m = 0; m < members_.size(); ++m) {
      std::vector<Eigen::Vector3d>& v = objects[members_[m]]->implicitVelocity();
      std::copy(velocity_.begin() + static_cast<std::ptrdiff_t>(start_[m]),
                velocity_.begin() + static_cast<std::ptrdiff_t>(start_[m] + v.size()), v.begin());
    }
  };
  const auto update = [&](bool& guessChanged) {
    bool changed = false;
    for (std::size_t m = 0; m < members_.size(); ++m)
      if (objects[members_[m]]->updateContactSet(h, guessChanged, pcg_, start_[m])) changed = true;
    if (updateSprings(h)) {
      changed = true;
      guessChanged = true;  // the matrix changed: the residual from a product
    }
    return changed;
  };
  // the solves after the first, as an object's own: to kCgContactTolerance of the first one's
  // initial residual (at kCouplingCgTolerance instead, the bin of twenty kept a particle rocking
  // at 3.2 cm/s; a pass right after a spring joined may then end at once, the spring's force
  // left in the residual, and its impulse below is taken from the gap all the same)
  return solveWithContactSet(
      pcg_, [&] { gather(objects); }, apply, precond, constraint_, normal_, rhs_, velocity_, floor,
      kCouplingCgTolerance, scatter, update);
}

void ImplicitCoupling::sumSpringImpulses(double h) {
  // the springs' impulses, on the objects' momentum and for the contact pass
  impulses_.clear();
  for (std::size_t m = 0; m < members_.size(); ++m)
    std::fill(impulseOn_[m].begin(), impulseOn_[m].end(), Eigen::Vector3d::Zero());
  for (const Spring& sp : springs_) {
    if (!sp.active) continue;
    // h times the force the solve applied on particle 1 (negative: a spring the last pass left
    // pulling), into the momentum correction and the wrench as it acted
    const double lambda = spring::impulse(sp.k, spring::gapAfter(sp.gap, sp.n, velocity_[sp.row1] - velocity_[sp.row2], h), h);
    if (lambda == 0.0) continue;
    const Eigen::Vector3d J = lambda * sp.n;
    impulseOn_[static_cast<std::size_t>(place_[sp.o1])][sp.i1] += J;
    impulseOn_[static_cast<std::size_t>(place_[sp.o2])][sp.i2] -= J;
    recordImpulse(sp, lambda);
  }
  for (const Spring& sp : held_) {
    if (!sp.active) continue;
    const double lambda = spring::impulse(sp.k, spring::gapAfter(sp.gap, sp.n, velocity_[sp.row1], h), h);
    if (lambda == 0.0) continue;
    impulseOn_[static_cast<std::size_t>(place_[sp.o1])][sp.i1] += lambda * sp.n;  // the sleeping object takes none
    recordImpulse(sp, lambda);
  }
}

}  // namespace deformable_flsm
