// The solver's contact with rigid colliders: the collider set, and the contact pass of a sub-step
// (see contactPass()). The geometry and the per-particle response are in contact.h.
#include "deformable_flsm/core/contact.h"
#include "deformable_flsm/core/mesh_distance_field.h"
#include "deformable_flsm/core/solver.h"
#include "integrator_step.h"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <stdexcept>

namespace deformable_flsm {

namespace {

/// Particles per chunk of the contact pass. Each chunk sums its own impulses, and the chunks are
/// added in order: the wrenches do not depend on how many threads share the chunks.
constexpr std::size_t kContactChunk = 1024;

/// A buried particle's normal "turned" within a sub-step when the cosine between its normals at
/// the start and at the end is below this (more than 60 degrees: across a medial axis the normal
/// flips, or jumps from one face to the next, 90 degrees on a box; a path along a surface turns
/// it by its length over the curvature radius, a small angle for any particle that is near the
/// surface rather than near the centre).
constexpr double kTurnedNormal = 0.5;

bool isRotation(const Eigen::Matrix3d& R) {
  return (R.transpose() * R).isIdentity(1e-6) && R.determinant() > 0.0;
}

}  // namespace

double Solver::contactRadius() const {
  return params_.contactRadius > 0.0 ? params_.contactRadius : 0.5 * lattice_->spacing();
}

void Solver::shareColliders(std::shared_ptr<ColliderScene> colliders) {
  colliders_ = std::move(colliders);
  ownsColliders_ = false;
  rebuildContactBodies();
}

void Solver::collidersChanged() { rebuildContactBodies(); }

void Solver::checkOwnsColliders(const char* what) const {
  if (!ownsColliders_)
    throw std::logic_error(std::string("solver: ") + what + ": this object's colliders are its World's (World::" + what +
                           ")");
}

void Solver::setCollider(const std::string& id, const Collider& collider) {
  checkOwnsColliders("setCollider");
  collider.validate();
  Collider c = collider;
  if (c.shape.type == ColliderType::Mesh && !c.shape.distanceField)
    c.shape.distanceField = std::make_shared<const MeshDistanceField>(*c.shape.mesh);
  colliders_->map()[id] = std::move(c);
  colliders_->changed();
  rebuildContactBodies();
}

bool Solver::moveCollider(const std::string& id, const Eigen::Isometry3d& pose,
                          const Eigen::Vector3d& linearVelocity, const Eigen::Vector3d& angularVelocity) {
  checkOwnsColliders("moveCollider");
  auto it = colliders_->map().find(id);
  if (it == colliders_->map().end()) return false;
  if (!pose.matrix().allFinite() || !linearVelocity.allFinite() || !angularVelocity.allFinite())
    throw std::invalid_argument("solver: collider '" + id + "' given a non-finite pose or velocity");
  if (!isRotation(pose.linear()))
    throw std::invalid_argument("solver: collider '" + id +
                                "' given a pose whose rotation is not orthonormal with determinant +1");
  it->second.pose = pose;
  it->second.linearVelocity = linearVelocity;
  it->second.angularVelocity = angularVelocity;
  return true;
}

bool Solver::removeCollider(const std::string& id) {
  checkOwnsColliders("removeCollider");
  const bool found = colliders_->map().erase(id) > 0;
  colliders_->changed();
  rebuildContactBodies();
  return found;
}

void Solver::removeAllColliders() {
  checkOwnsColliders("removeAllColliders");
  colliders_->map().clear();
  colliders_->changed();
  rebuildContactBodies();
}

ContactWrench Solver::contactWrench(const std::string& id) const {
  for (std::size_t c = 0; c < contactBodies_.size(); ++c)
    if (*posed(c).id == id) return contactBodies_[c].wrench;
  return ContactWrench();
}

void Solver::recordContacts(const std::string& id, bool on) {
  if (on)
    recordedIds_.insert(id);
  else
    recordedIds_.erase(id);
  rebuildContactBodies();
}

const std::vector<ParticleContact>& Solver::recordedContacts(const std::string& id) const {
  static const std::vector<ParticleContact> kNone;
  for (std::size_t c = 0; c < contactBodies_.size(); ++c)
    if (*posed(c).id == id) return contactBodies_[c].recorded;
  return kNone;
}

// Every change of the collider set comes here, outside step(): the buffers the contact pass
// writes are sized now, so that the pass allocates nothing.
void Solver::rebuildContactBodies() {
  std::vector<ContactBody> bodies;
  bodies.reserve(colliders_->posed().size());
  for (const PosedCollider& entry : colliders_->posed()) {
    ContactBody body;
    body.collider = entry.collider;
    // a collider that stays (another was added or removed) keeps its last wrench
    for (const ContactBody& old : contactBodies_)
      if (old.collider == body.collider) body.wrench = old.wrench;
    if (recordedIds_.count(*entry.id) > 0) {
      // sized now: recording allocates nothing in a step
      body.recording = true;
      body.particleImpulse.assign(x_.size(), Eigen::Vector3d::Zero());
      body.particlePoint.assign(x_.size(), Eigen::Vector3d::Zero());
      body.recorded.reserve(x_.size());
      // and, as its wrench, a collider that stays keeps its last record (a sleeping object's)
      for (const ContactBody& old : contactBodies_)
        if (old.collider == body.collider && old.recording) body.recorded = old.recorded;
    }
    bodies.push_back(std::move(body));
  }
  contactBodies_ = std::move(bodies);
  activeBodies_.clear();
  activeBodies_.reserve(contactBodies_.size());
  const std::size_t chunks = (x_.size() + kContactChunk - 1) / kContactChunk;
  contactPartials_.assign(chunks * contactBodies_.size(), ContactPartial());
  chunkBodies_.assign(chunks * contactBodies_.size(), 0);
  tally_.resize(x_.size(), contactBodies_.size());
}

void Solver::beginContactStep() {
  if (ownsColliders_) colliders_->beginStep();
  for (ContactBody& body : contactBodies_) {
    body.impulse.setZero();
    body.moment.setZero();
    body.buried = 0;
    if (body.recording) std::fill(body.particleImpulse.begin(), body.particleImpulse.end(), Eigen::Vector3d::Zero());
  }
}

// Contact of the particle spheres (radius r = contactRadius()) with the colliders, after the
// region pass has moved every free particle to x* = x + h v:
//  1. broad phase: colliders whose bounds (inflated by r) miss the object's bounds are skipped,
//     then those that miss a chunk's bounds (a slab of the lattice), then, per particle, those
//     whose inflated bounds miss the particle;
//  2. velocity-level response (contactVelocityChange()): a particle whose sphere ends inside a
//     collider, at the collider's pose at the end of the sub-step, gets the velocity that undoes
//     the penetration its motion relative to the collider made in this sub-step (measured from
//     its start x = x* - h v against the collider's pose at the start of the sub-step), with
//     Coulomb friction relative to the collider's surface velocity; x* moves with it
//     (x* = x + h v holds). Colliders are visited in id order, each seeing the corrections of
//     the ones before;
//  3. safety projection: a sphere still inside a collider (a curved surface, pushed into one
//     collider by another, or inside since before the sub-step: a collider set, moved or reset
//     onto it) is moved out along the normal, position only, by at most its radius r per
//     sub-step. No velocity comes from this part: a penetration the particle did not move into
//     is no motion of the particle, and where colliders overlap so that no place is outside
//     both, velocity made of it would grow every sub-step (see contactVelocityChange()). The
//     bound keeps the depenetration at most r / h (as physics engines bound theirs): a collider
//     set around the object, as large as it may be (a sphere of 1e9 m), pushes it out over
//     sub-steps instead of throwing its particles to a surface however far, whence shape
//     matching would pull them back at that distance over h.
// A particle buried deeper than its radius r since before the sub-step (startDepth < -r) is in a
// state no motion into the collider made (a collider set, moved or reset onto it). Two cases of
// it get a rule of their own; otherwise it is treated as above (its approach stopped, pushed out
// by up to r), which is what pushes an object out of an indenter moved into it by more than r in
// one command and lets it rest there.
//   - Its normal turned within the sub-step (startNormal . normal < kTurnedNormal: the particle
//     crossed the collider's medial axis, a sphere's centre, a capsule's axis, a box's
//     diagonal planes): no velocity response. "Stop the approach along the normal" means
//     nothing where the normal is not one direction over the particle's path: it is a one-sided
//     filter on the velocity that removes a different component every sub-step, and with shape
//     matching's overshoot (alpha > 1 moves a particle past its goal) it does not only take
//     energy out: a particle crossing a buried collider's centre, between pinned or
//     hard-dragged neighbours, swings a little farther every few sub-steps until the state blows
//     up. Such a particle has no surface near to rest on; what it needs is to be moved out.
//     Where the normal stays put (an indenter pressed in, the particle under its surface), the
//     approach is well defined and stopping it is what keeps shape matching from pulling the
//     particle back in as fast as the push-out moves it out.
//   - The object cannot leave: a pinned or hard-dragged particle holds it, and the particle's
//     centre is deeper than the object's size L (Lattice::objectSize()) in the collider. A
//     signed distance changes by at most the distance moved, and every particle is within L of
//     this one, so the whole object is inside the collider, pins included. Then: no velocity
//     response, and the push-out takes the particle no farther than r beyond its goal g (this
//     sub-step's shape-matching goal) along the normal. Unbounded, an object held inside a
//     collider it cannot leave (a sphere of 1e9 m) is pushed out by r every sub-step as long as
//     the collider stays, its free part stretched away from what holds it without bound, and
//     shape matching's pull-back (alpha |g - x| / h) grows with the stretch; released, the
//     stretch snaps back at that speed. Bounded by the goal, the push-out deforms the material
//     by at most about the particle's own size per sub-step beyond what its regions follow: the
//     particles leave as far as the held body lets its goals go, and no farther by tearing.
//     Stopping only the inward motion of such a particle would be a ratchet: shape matching's
//     pull back towards the held part is stopped, its overshoot outwards let through, so the
//     free part is pumped away from the pins against the material (with hard drags yanking it,
//     until the state blows up, even where the normal stays put). Where the pins and the
//     collider disagree, the pins win and the particles stay buried, as a pinned particle
//     inside a collider does. Shallower, part of the object is outside: pushing the buried
//     part out deforms the object by at most about L, as an indenter pressed into a pinned
//     object does, and it is pushed out as a free object is. A free object is pushed out at r
//     per sub-step as a body: its goals move with it, and nothing stretches.
// A particle that touches a surface (shallower than r at the start) is pushed out by up to r
// whatever its goal: a squeeze between two colliders deforms it, and it must not sink in.
// The impulses m dv, and their moments about each collider's origin taken at the contact point
// x* - r n, are summed per chunk, then over the chunks in order.
// Pinned and hard-dragged particles are left alone: their motion is prescribed.
void Solver::beginContactSubstep(int s) {
  tally_.beginSubstep();
  if (ownsColliders_) colliders_->poseSubstep(s, params_.substepLength());
}

void Solver::contactPass(double h) {
  if (contactBodies_.empty()) return;
  const double r = contactRadius();
  placeContactBodies(r);
  if (activeBodies_.empty()) return;
  ContactPassFrame pass;
  pass.h = h;
  pass.r = r;
  // the goals of this sub-step's region pass (the implicit step's linearisation point)
  pass.goals = &integrator_->goals();
  // held: a pinned or hard-dragged particle keeps the object from leaving a collider as a body;
  // it cannot leave one whose surface is farther than its size from a particle (above)
  pass.held = pinnedCount_ > 0;
  for (const auto& entry : drags_) pass.held = pass.held || entry.second.stiffness <= 0.0;
  pass.enclosed = -lattice_->objectSize() - r;  // a depth phi - r below which all the object is inside
  const std::size_t n = x_.size();
  const std::ptrdiff_t chunks = static_cast<std::ptrdiff_t>((n + kContactChunk - 1) / kContactChunk);
  // the thread count the governor gave this step (the sums do not depend on it)
  const int threads = singleSummer_ && activeSummer_ == singleSummer_.get() ? 1 : threads_;
#pragma omp parallel for num_threads(threads) schedule(static) if (threads > 1)
  for (std::ptrdiff_t chunk = 0; chunk < chunks; ++chunk) contactChunk(chunk, pass);
  sumContactPartials(chunks);
}

void Solver::placeContactBodies(double r) {
  Eigen::Vector3d lo = x_[0], hi = x_[0];
  for (const Eigen::Vector3d& x : x_) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
  }
  activeBodies_.clear();
  for (std::size_t b = 0; b < contactBodies_.size(); ++b)
    if (boxNearCollider(posed(b).collider->shape, posed(b).now, lo, hi, r)) activeBodies_.push_back(static_cast<int>(b));
}

void Solver::contactChunk(std::ptrdiff_t chunk, const ContactPassFrame& pass) {
  const std::size_t n = x_.size();
  const std::size_t bodies = contactBodies_.size();
  const auto& m = lattice_->masses();
  const double h = pass.h, r = pass.r, enclosed = pass.enclosed;
  const bool held = pass.held;
  const std::vector<Eigen::Vector3d>& goals = *pass.goals;
  ContactPartial* partial = contactPartials_.data() + static_cast<std::size_t>(chunk) * bodies;
  for (int a : activeBodies_) partial[a] = ContactPartial();
  const std::size_t begin = static_cast<std::size_t>(chunk) * kContactChunk;
  const std::size_t end = std::min(n, begin + kContactChunk);
  int* near = chunkBodies_.data() + static_cast<std::size_t>(chunk) * bodies;
  const int nearCount = bodiesNear(begin, end, r, near);
  if (nearCount == 0) return;
  for (std::size_t i = begin; i < end; ++i) {
    if (pinned_[i] != 0 || hardDragged_[i] != 0) continue;
    Eigen::Vector3d x = x_[i], v = v_[i];
    const Eigen::Vector3d start = x - h * v;  // where the sub-step began: x* = x + h v
    bool touched = false, buried = false;
    for (int k = 0; k < nearCount; ++k) {
      const int a = near[k];
      const PosedCollider& body = posed(static_cast<std::size_t>(a));
      if (!body.near(x, r)) continue;
      const Collider& c = *body.collider;
      Eigen::Vector3d normal;
      const double depth = body.gap(x, r, normal);
      if (!(depth < 0.0)) continue;
      Eigen::Vector3d startNormal;
      const double startDepth = body.startGap(start, r, startNormal);
      // buried deeper than its radius since before the sub-step (above)
      if (startDepth < -r) {
        buried = true;
        ++partial[a].buried;
        if ((held && depth < enclosed) || startNormal.dot(normal) < kTurnedNormal) {  // no velocity response (above)
          touched = true;
          continue;
        }
      }
      const Eigen::Vector3d origin = body.now.translation();
      const Eigen::Vector3d vc = body.surfaceVelocity(x);
      const Eigen::Vector3d dv = contactVelocityChange(depth, startDepth, normal, v, vc, h, c.staticFriction,
                                                       c.kineticFriction);
      v += dv;
      x += h * dv;
      const Eigen::Vector3d J = m[i] * dv;
      ContactPartial& p = partial[a];
      p.impulse += J;
      p.moment += (x - r * normal - origin).cross(J);
      // (particle i is this chunk's alone: no other thread writes its entries)
      record(contactBodies_[a], i, J, x - r * normal);
      tally_.touch(i, static_cast<std::size_t>(a));
      touched = true;
    }
    if (!touched) continue;
    const Eigen::Vector3d& goal = goals[i];
    for (int k = 0; k < nearCount; ++k) {
      const PosedCollider& body = posed(static_cast<std::size_t>(near[k]));
      if (!body.near(x, r)) continue;
      Eigen::Vector3d normal;
      const double depth = body.gap(x, r, normal);
      if (!(depth < 0.0)) continue;
      // at most r per sub-step; a buried particle of a held object all inside the collider no
      // farther than r beyond its goal
      const double most =
          buried && held && depth < enclosed ? std::min(r, std::max(0.0, r - normal.dot(x - goal))) : r;
      x += std::min(-depth, most) * normal;
    }
    x_[i] = x;
    v_[i] = v;
  }
}

int Solver::bodiesNear(std::size_t begin, std::size_t end, double r, int* near) const {
  // The chunk's own broad phase: particles are sorted by (k, j, i), so a chunk is a slab of the
  // lattice, and most colliders (the ground, under the bottom slabs) miss most slabs.
  Eigen::Vector3d lo = x_[begin], hi = x_[begin];
  for (std::size_t i = begin + 1; i < end; ++i) {
    lo = lo.cwiseMin(x_[i]);
    hi = hi.cwiseMax(x_[i]);
  }
  int count = 0;
  for (int a : activeBodies_) {
    const PosedCollider& body = posed(static_cast<std::size_t>(a));
    if (boxNearCollider(body.collider->shape, body.now, lo, hi, r)) near[count++] = a;
  }
  return count;
}

void Solver::sumContactPartials(std::ptrdiff_t chunks) {
  const std::size_t bodies = contactBodies_.size();
  for (int a : activeBodies_) {
    ContactBody& body = contactBodies_[a];
    std::size_t buried = 0;  // this pass's
    for (std::ptrdiff_t chunk = 0; chunk < chunks; ++chunk) {
      const ContactPartial& partial = contactPartials_[static_cast<std::size_t>(chunk) * bodies + static_cast<std::size_t>(a)];
      body.impulse += partial.impulse;
      body.moment += partial.moment;
      buried += partial.buried;
    }
    body.buried = std::max(body.buried, buried);
  }
}

void Solver::touchCollider(std::uint32_t p, std::size_t c) {
  if (p >= x_.size() || c >= contactBodies_.size())
    throw std::out_of_range("solver: touchCollider(" + std::to_string(p) + ", " + std::to_string(c) +
                            "): no such particle or collider");
  tally_.touch(p, c);
}

void Solver::addColliderImpulse(std::size_t c, const Eigen::Vector3d& impulse, const Eigen::Vector3d& moment) {
  ContactBody& body = contactBodies_.at(c);
  body.impulse += impulse;
  body.moment += moment;
}

// The object's impulse on a collider is minus the particles' m dv; averaged over the step.
void Solver::endContactStep() {
  const double T = params_.timeStep;
  for (ContactBody& body : contactBodies_) body.wrench.contacts = 0;
  // the particles in contact at the end of the last sub-step, each once per collider
  tally_.count([this](std::size_t c) { ++contactBodies_[c].wrench.contacts; });
  for (ContactBody& body : contactBodies_) {
    body.wrench.force = -body.impulse / T;
    body.wrench.torque = -body.moment / T;
    body.wrench.buried = body.buried;
    if (body.recording) {
      body.recorded.clear();
      for (std::size_t i = 0; i < body.particleImpulse.size(); ++i)
        if (!body.particleImpulse[i].isZero(0.0))
          body.recorded.push_back({static_cast<std::uint32_t>(i), body.particlePoint[i], -body.particleImpulse[i] / T});
    }
  }
  if (ownsColliders_) colliders_->endStep(T);  // a World's are moved by the World, once
}

}  // namespace deformable_flsm
