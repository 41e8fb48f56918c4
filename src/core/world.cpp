// World: several deformable objects advanced together (see world.h).
//
// How to use it:
//   World world(1.0 / 60.0, 8);                       // every object's timeStep and substeps
//   world.setCollider("ground", ground);              // shared by every object, now and later
//   Solver& a = world.addObject("sponge", lattice, params);  // lattice voxelized at its pose
//   a.pinBox(...); a.grab(...);                       // commands go to the object's Solver
//   world.step();                                     // all objects, one step
//   world.objectWrench("sponge", "apple");            // what the sponge exerted on the apple
//   world.contactWrench("ground");                    // what all objects exerted on the ground
// Each object is a Solver: its state, commands, diagnostics and its own wrench on a collider
// (Solver::contactWrench(), the object contact pass's share against the colliders included)
// are read there. Do not call Solver::step() on an object of a World; the colliders are the
// World's, kept once and read by every object (Solver::shareColliders(): changing them through
// an object throws); an object whose timeStep or substeps is changed to differ from the world's
// makes step() throw.
// Per sub-step: every object's dynamics and collider contact (Solver::advanceSubstep()), then
// the contact between objects and of objects with themselves (ObjectContactSolver), which
// also holds the particles it touches against the colliders in the same solve.
// Objects at rest sleep through steps (SleepParams): Sleeping (sleeping.h) decides which, told of
// every object and collider change here; step() is its stages, each a member function.
#include "deformable_flsm/core/world.h"

#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/mesh_distance_field.h"
#include "deformable_flsm/core/object_contact.h"
#include "deformable_flsm/core/sleeping.h"
#include "deformable_flsm/core/slice_stream_summer.h"
#include "deformable_flsm/core/spatial_hash.h"

#include "number_text.h"

#include <algorithm>
#include <cmath>
#include <map>
#include <stdexcept>

namespace deformable_flsm {

namespace {

/// Objects may start touching (a stack built face to face: particle spheres exactly r1 + r2
/// apart) but not closer than r1 + r2 by more than this fraction of it, which round-off of
/// placing them cannot reach.
constexpr double kStartOverlapTolerance = 1e-6;

bool isRotation(const Eigen::Matrix3d& R) {
  return (R.transpose() * R).isIdentity(1e-6) && R.determinant() > 0.0;
}

bool sameTime(double a, double b) { return std::abs(a - b) <= 1e-12 * std::max(std::abs(a), std::abs(b)); }

}  // namespace

void ObjectContactParams::validate() const {
  if (selfExclusion < 1)
    throw std::invalid_argument("object contact: self_exclusion must be >= 1 lattice cell (got " +
                                std::to_string(selfExclusion) + "): neighbours touch at rest");
  if (!std::isfinite(staticFriction) || staticFriction < 0.0)
    throw std::invalid_argument("object contact: static friction must be finite and >= 0 (got " + numberText(staticFriction) + ")");
  if (!std::isfinite(kineticFriction) || kineticFriction < 0.0 || kineticFriction > staticFriction)
    throw std::invalid_argument("object contact: kinetic friction must be in [0, static friction " +
                                numberText(staticFriction) + "] (got " + numberText(kineticFriction) + ")");
  if (iterations < 1)
    throw std::invalid_argument("object contact: iterations must be >= 1 (got " + std::to_string(iterations) + ")");
}

struct World::Impl {
  std::vector<std::unique_ptr<Solver>> objects;
  std::vector<Solver*> pointers;
  /// the scene's colliders, once: every object reads these (Solver::shareColliders())
  std::shared_ptr<ColliderScene> colliders = std::make_shared<ColliderScene>();
  ObjectContactSolver contact;
  ImplicitCoupling coupling;
  std::vector<char> coupled;  // per object, whether its implicit sub-step is in the coupled solve
  // per object, asleep this step and implicit (a subset of the asleep): held in the coupled solve
  std::vector<char> heldAsleep;
  std::vector<ObjectPairWrench> wrenches;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> wrenchObjects;  // per wrench: from, on
  Sleeping sleeping;
  /// the slice buffers of every object's region sums: the objects step one after another
  std::shared_ptr<SliceStreamScratch> scratch = std::make_shared<SliceStreamScratch>();

  std::size_t indexOf(const std::vector<std::string>& names, const std::string& name) const {
    return static_cast<std::size_t>(std::find(names.begin(), names.end(), name) - names.begin());
  }
};

const char* World::bdf2Refusal(const SolverParams& p, std::size_t objects, const ObjectContactParams& contact) {
  if (contact.couples(objects) && p.integrator == Integrator::Implicit && p.implicitScheme == ImplicitScheme::Bdf2)
    return "the implicit scheme bdf2 steps one object alone: objects in contact with each other or "
           "themselves are solved together with backward_euler";
  return nullptr;
}

World::World(double timeStep, int substeps, const ObjectContactParams& contact)
    : impl_(std::make_unique<Impl>()), contact_(contact), timeStep_(timeStep), substeps_(substeps) {
  if (!std::isfinite(timeStep) || !(timeStep > 0.0))
    throw std::invalid_argument("world: the time step must be positive and finite (got " + numberText(timeStep) + " s)");
  if (substeps < 1) throw std::invalid_argument("world: substeps must be >= 1 (got " + std::to_string(substeps) + ")");
  contact_.validate();
}

World::~World() = default;

Solver& World::addObject(const std::string& name, std::shared_ptr<const Lattice> lattice, const SolverParams& params) {
  if (name.empty()) throw std::invalid_argument("world: an object needs a name");
  if (impl_->indexOf(names_, name) < names_.size())
    throw std::invalid_argument("world: there is already an object named '" + name + "'");
  if (!sameTime(params.timeStep, timeStep_) || params.substeps != substeps_)
    throw std::invalid_argument("world: object '" + name + "' has time step " + numberText(params.timeStep) + " s in " +
                                std::to_string(params.substeps) + " sub-steps, the world " + numberText(timeStep_) +
                                " s in " + std::to_string(substeps_) + ": give it the world's");
  // objects that touch each other are solved as one backward Euler system (step())
  const std::size_t count = impl_->objects.size() + 1;
  const char* why = bdf2Refusal(params, count, contact_);
  for (std::size_t o = 0; o < impl_->objects.size() && why == nullptr; ++o)
    why = bdf2Refusal(impl_->objects[o]->params(), count, contact_);
  if (why != nullptr) throw std::invalid_argument("world: object '" + name + "': " + why);
  auto solver = std::make_unique<Solver>(std::move(lattice), params);
  // refuse a start inside another object: the contact pass would push it out over many sub-steps
  const auto& x = solver->positions();
  const double r = solver->contactRadius();
  Eigen::Vector3d lo = x[0], hi = x[0];
  for (const Eigen::Vector3d& p : x) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  SpatialHash hash;
  bool hashed = false;
  for (std::size_t o = 0; o < impl_->objects.size(); ++o) {
    const Solver& other = *impl_->objects[o];
    const double R = r + other.contactRadius();
    const double limit = R * (1.0 - kStartOverlapTolerance);
    if (!hashed) {
      double reach = 0.0;
      for (const auto& s : impl_->objects) reach = std::max(reach, r + s->contactRadius());
      hash.build(x, x.size(), reach);
      hashed = true;
    }
    for (std::size_t j = 0; j < other.positions().size(); ++j) {
      const Eigen::Vector3d& y = other.positions()[j];
      if ((y.array() < lo.array() - R).any() || (y.array() > hi.array() + R).any()) continue;
      hash.forEachNear(y, [&](std::uint32_t i) {
        const double d = (x[i] - y).norm();
        if (d < limit)
          throw std::invalid_argument("world: object '" + name + "' starts inside object '" + names_[o] +
                                      "': its particle " + std::to_string(i) + " is " + numberText(d) + " m from their particle " +
                                      std::to_string(j) + ", closer than the sum of their contact radii " + numberText(R) +
                                      " m; place it apart");
      });
    }
  }
  solver->shareRegionScratch(impl_->scratch);
  solver->shareColliders(impl_->colliders);
  Solver& added = *solver;
  if (!recordedIds_.empty() && contact_.couples(impl_->objects.size() + 1))
    throw std::invalid_argument("world: object '" + name + "' would touch the others, and contacts on collider '" +
                                *recordedIds_.begin() + "' are recorded: the objects' shared solve does not "
                                "record them (turn object and self contact off, or record nothing)");
  for (const std::string& id : recordedIds_) solver->recordContacts(id, true);
  impl_->objects.push_back(std::move(solver));
  impl_->pointers.push_back(&added);
  names_.push_back(name);
  impl_->contact.invalidate();
  impl_->sleeping.add(added);
  wakeAll();  // what rested may now be pushed
  return added;
}

bool World::removeObject(const std::string& name) {
  const std::size_t o = impl_->indexOf(names_, name);
  if (o >= names_.size()) return false;
  impl_->objects.erase(impl_->objects.begin() + static_cast<std::ptrdiff_t>(o));
  impl_->pointers.erase(impl_->pointers.begin() + static_cast<std::ptrdiff_t>(o));
  names_.erase(names_.begin() + static_cast<std::ptrdiff_t>(o));
  impl_->sleeping.remove(o);
  impl_->contact.invalidate();
  auto& w = impl_->wrenches;
  w.erase(std::remove_if(w.begin(), w.end(),
                         [&](const ObjectPairWrench& p) { return p.from == name || p.on == name; }),
          w.end());
  impl_->wrenchObjects.resize(w.size());
  for (std::size_t i = 0; i < w.size(); ++i)
    impl_->wrenchObjects[i] = {static_cast<std::uint32_t>(impl_->indexOf(names_, w[i].from)),
                               static_cast<std::uint32_t>(impl_->indexOf(names_, w[i].on))};
  wakeAll();  // what it held may fall
  return true;
}

Solver* World::object(const std::string& name) {
  const std::size_t o = impl_->indexOf(names_, name);
  return o < names_.size() ? impl_->objects[o].get() : nullptr;
}

const Solver* World::object(const std::string& name) const {
  const std::size_t o = impl_->indexOf(names_, name);
  return o < names_.size() ? impl_->objects[o].get() : nullptr;
}

void World::setCollider(const std::string& id, const Collider& collider) {
  collider.validate();
  Collider c = collider;
  // one distance field for every object
  if (c.shape.type == ColliderType::Mesh && !c.shape.distanceField)
    c.shape.distanceField = std::make_shared<const MeshDistanceField>(*c.shape.mesh);
  ColliderMap& map = impl_->colliders->map();
  auto old = map.find(id);
  if (old != map.end()) impl_->sleeping.disturb(old->second);
  impl_->sleeping.disturb(c);
  map[id] = std::move(c);
  impl_->colliders->changed();
  for (auto& object : impl_->objects) object->collidersChanged();
}

bool World::moveCollider(const std::string& id, const Eigen::Isometry3d& pose, const Eigen::Vector3d& linearVelocity,
                         const Eigen::Vector3d& angularVelocity) {
  auto it = impl_->colliders->map().find(id);
  if (it == impl_->colliders->map().end()) return false;
  if (!pose.matrix().allFinite() || !linearVelocity.allFinite() || !angularVelocity.allFinite())
    throw std::invalid_argument("world: collider '" + id + "' given a non-finite pose or velocity");
  if (!isRotation(pose.linear()))
    throw std::invalid_argument("world: collider '" + id +
                                "' given a pose whose rotation is not orthonormal with determinant +1");
  const bool jumped = impl_->sleeping.enabled() && !pose.isApprox(it->second.pose, 0.0);
  if (jumped) impl_->sleeping.disturb(it->second);  // where it was
  it->second.pose = pose;
  it->second.linearVelocity = linearVelocity;
  it->second.angularVelocity = angularVelocity;
  if (jumped) impl_->sleeping.disturb(it->second);  // where it is (where it goes: step())
  return true;
}

bool World::removeCollider(const std::string& id) {
  auto it = impl_->colliders->map().find(id);
  if (it == impl_->colliders->map().end()) return false;
  impl_->sleeping.disturb(it->second);
  impl_->colliders->map().erase(it);
  impl_->colliders->changed();
  for (auto& object : impl_->objects) object->collidersChanged();
  return true;
}

ContactWrench World::contactWrench(const std::string& id) const {
  ContactWrench sum;
  for (const auto& object : impl_->objects) {
    const ContactWrench w = object->contactWrench(id);
    sum.force += w.force;
    sum.torque += w.torque;
    sum.contacts += w.contacts;
    sum.buried += w.buried;
  }
  return sum;
}

void World::recordContacts(const std::string& id, bool on) {
  if (on && contact_.couples(impl_->objects.size()))
    throw std::invalid_argument("world: contacts on collider '" + id + "' cannot be recorded where objects "
                                "touch each other or themselves (object or self contact on): their shared "
                                "solve does not record them");
  if (on)
    recordedIds_.insert(id);
  else
    recordedIds_.erase(id);
  for (const auto& object : impl_->objects) object->recordContacts(id, on);
}

void World::setContactParams(const ObjectContactParams& contact) {
  contact.validate();
  for (std::size_t o = 0; o < impl_->objects.size(); ++o)
    if (const char* why = bdf2Refusal(impl_->objects[o]->params(), impl_->objects.size(), contact))
      throw std::invalid_argument("world: object '" + names_[o] + "': " + why);
  contact_ = contact;
  wakeAll();  // friction, margins, self-contact: the rest the objects fell asleep in may be no more
}

const std::vector<ObjectPairWrench>& World::objectWrenches() const { return impl_->wrenches; }

std::size_t World::contactListBuilds() const { return impl_->contact.listBuilds(); }

World::ContactPasses World::contactPasses() const {
  return {impl_->contact.solvePasses(), impl_->contact.solvedSubsteps()};
}

void World::setContactTiming(bool on) { impl_->contact.setTiming(on); }

World::ContactTimes World::contactTimes() const {
  const auto& s = impl_->contact.seconds();
  return {s[ObjectContactSolver::kListSeconds], s[ObjectContactSolver::kPairSeconds],
          s[ObjectContactSolver::kPassSeconds], s[ObjectContactSolver::kRestSeconds]};
}

const SleepParams& World::sleepParams() const { return impl_->sleeping.params(); }

void World::setSleepParams(const SleepParams& sleep) { impl_->sleeping.setParams(sleep, impl_->pointers); }

bool World::asleep(const std::string& name) const {
  const std::size_t o = impl_->indexOf(names_, name);
  return o < names_.size() && impl_->sleeping.asleep(o);
}

std::size_t World::sleepingCount() const { return impl_->sleeping.count(); }

bool World::wake(const std::string& name) {
  const std::size_t o = impl_->indexOf(names_, name);
  if (o >= names_.size()) return false;
  impl_->sleeping.wake(o, *impl_->objects[o]);
  return true;
}

void World::wakeAll() { impl_->sleeping.wakeAll(impl_->pointers); }

ContactWrench World::objectWrench(const std::string& from, const std::string& on) const {
  for (const ObjectPairWrench& w : impl_->wrenches)
    if (w.from == from && w.on == on) return w.wrench;
  return ContactWrench();
}

void World::step() {
  checkObjects();
  impl_->colliders->beginStep();
  chooseSleepers();
  beginObjects();
  const bool couple = planCoupling();
  for (int s = 0; s < substeps_; ++s) substep(s, couple);
  advanceClock();
  endObjects();
  advanceColliders();
  collectWrenches();
  settle();
}

void World::checkObjects() const {
  const std::size_t N = impl_->objects.size();
  for (std::size_t o = 0; o < N; ++o) {
    const SolverParams& p = impl_->objects[o]->params();
    if (!sameTime(p.timeStep, timeStep_) || p.substeps != substeps_)
      throw std::logic_error("world: object '" + names_[o] + "' was set to a time step of " + numberText(p.timeStep) +
                             " s in " + std::to_string(p.substeps) + " sub-steps, the world steps " +
                             numberText(timeStep_) + " s in " + std::to_string(substeps_) + ": give it the world's");
    if (const char* why = bdf2Refusal(p, N, contact_))
      throw std::logic_error("world: object '" + names_[o] + "': " + why);
  }
}

void World::chooseSleepers() { impl_->sleeping.beforeStep(impl_->pointers, impl_->colliders->map(), timeStep_); }

void World::beginObjects() {
  Impl& im = *impl_;
  const std::vector<char>& asleep = im.sleeping.asleepThisStep();
  for (std::size_t o = 0; o < im.objects.size(); ++o)
    if (!asleep[o]) im.pointers[o]->beginStep();
  im.contact.beginStep(im.objects.size(), im.colliders->posed().size());
  im.contact.setAsleep(&asleep);
}

bool World::planCoupling() {
  Impl& im = *impl_;
  const std::size_t N = im.objects.size();
  const std::vector<char>& asleep = im.sleeping.asleepThisStep();
  const bool touching = contact_.couples(N);
  im.coupled.assign(N, 0);
  std::size_t implicitCount = 0;
  for (std::size_t o = 0; o < N; ++o)
    if (touching && !asleep[o] && im.objects[o]->params().integrator == Integrator::Implicit) {
      im.coupled[o] = 1;
      ++implicitCount;
    }
  // the sleeping implicit objects keep their springs to the awake ones, held in place: what rests
  // on them is carried within the solve as while they were awake
  im.heldAsleep.assign(N, 0);
  bool anyHeld = false;
  for (std::size_t o = 0; o < N; ++o)
    if (touching && asleep[o] && im.objects[o]->params().integrator == Integrator::Implicit) {
      im.heldAsleep[o] = 1;
      anyHeld = true;
    }
  return implicitCount >= 2 || (implicitCount == 1 && (contact_.selfContact || anyHeld));
}

void World::substep(int s, bool couple) {
  Impl& im = *impl_;
  const std::size_t N = im.objects.size();
  const std::vector<char>& asleep = im.sleeping.asleepThisStep();
  const double h = timeStep_ / substeps_;
  im.colliders->poseSubstep(s, h);
  if (couple) {
    im.contact.refreshList(im.pointers, contact_, h);  // before any object moves
    for (std::size_t o = 0; o < N; ++o)
      if (!im.coupled[o] && !asleep[o]) im.pointers[o]->advanceSubstep(s);
    static const std::vector<std::pair<std::uint32_t, std::uint32_t>> kNone;
    const auto* candidates = im.contact.currentCandidates(im.pointers, contact_);
    im.coupling.substep(im.pointers, im.coupled, candidates != nullptr ? *candidates : kNone, s, h, &im.heldAsleep);
    im.contact.setCouplingImpulses(&im.coupling.impulses());
  } else {
    for (std::size_t o = 0; o < N; ++o)
      if (!asleep[o]) im.pointers[o]->advanceSubstep(s);
    im.contact.setCouplingImpulses(nullptr);
  }
  if (N < 2 && !contact_.selfContact) return;
  im.contact.substep(im.pointers, im.colliders->posed(), contact_, h, s + 1 == substeps_);
}

void World::advanceClock() {
  const double h = timeStep_ / substeps_;
  for (int s = 0; s < substeps_; ++s) time_ += h;
}

void World::endObjects() {
  Impl& im = *impl_;
  const std::vector<char>& asleep = im.sleeping.asleepThisStep();
  for (std::size_t o = 0; o < im.objects.size(); ++o) {
    if (asleep[o]) {
      im.objects[o]->idleStep();
      continue;
    }
    for (std::size_t c = 0; c < im.colliders->posed().size(); ++c) {
      const ColliderImpulse& ci = im.contact.colliderImpulse(o, c);
      if (!ci.impulse.isZero(0.0)) im.objects[o]->addColliderImpulse(c, ci.impulse, ci.moment);
    }
    im.objects[o]->endStep();
  }
  im.contact.endStep();
}

void World::advanceColliders() { impl_->colliders->endStep(timeStep_); }

void World::collectWrenches() {
  Impl& im = *impl_;
  const std::vector<char>& asleep = im.sleeping.asleepThisStep();
  // two sleeping objects keep what they exerted, moved to the front in place (swaps, no copies)
  std::size_t held = 0;
  for (std::size_t i = 0; i < im.wrenches.size(); ++i)
    if (asleep[im.wrenchObjects[i].first] && asleep[im.wrenchObjects[i].second]) {
      if (i != held) {
        std::swap(im.wrenches[held], im.wrenches[i]);
        std::swap(im.wrenchObjects[held], im.wrenchObjects[i]);
      }
      ++held;
    }
  const auto& pairs = im.contact.pairImpulses();
  im.wrenches.resize(held + 2 * pairs.size());
  im.wrenchObjects.resize(im.wrenches.size());
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    const PairImpulse& p = pairs[i];
    im.wrenchObjects[held + 2 * i] = {p.a, p.b};
    im.wrenchObjects[held + 2 * i + 1] = {p.b, p.a};
    ObjectPairWrench& onB = im.wrenches[held + 2 * i];
    ObjectPairWrench& onA = im.wrenches[held + 2 * i + 1];
    onB.from = names_[p.a];
    onB.on = names_[p.b];
    onB.wrench.force = p.impulse / timeStep_;
    onB.wrench.torque = p.moment / timeStep_;
    onB.wrench.contacts = p.contacts;
    onA.from = names_[p.b];
    onA.on = names_[p.a];
    onA.wrench.force = -onB.wrench.force;
    onA.wrench.torque = -onB.wrench.torque;
    onA.wrench.contacts = p.contacts;
  }
}

void World::settle() {
  impl_->sleeping.afterStep(impl_->pointers, impl_->wrenches, impl_->wrenchObjects, impl_->contact.pairImpulses(),
                            timeStep_);
}

}  // namespace deformable_flsm
