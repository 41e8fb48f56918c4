/// @file solver.h
/// The FastLSM dynamics (Rivers & James 2007): shape matching over lattice regions, region
/// damping, external forces, pins and drags, advanced at a fixed time step.
/// Its rooms: solver.cpp (rest state, the step, the region pass, damping),
/// solver_queries.cpp (what an observer reads: nearby particles, energy, momenta, rigid frame),
/// solver_material.cpp (region weights, the Poisson term, the cap on alpha), solver_commands.cpp
/// (pins, drags and their frames, forces, impulses, the spring limit), solver_contact.cpp
/// (colliders and the contact pass), solver_explicit.cpp (the explicit sub-step),
/// solver_implicit.cpp (the implicit and BDF2 sub-steps) and solver_implicit_contact.cpp (the
/// implicit step's contact set).
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/collider_scene.h"
#include "deformable_flsm/core/contact_tally.h"
#include "deformable_flsm/core/fast_summation.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/pcg.h"
#include "deformable_flsm/core/solver_params.h"
#include "deformable_flsm/core/thread_governor.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace deformable_flsm {

/// A drag: particles pulled to targets that move rigidly with a frame, the drag's pose. Each
/// particle keeps the offset it had in that frame when it was grabbed: its target is
/// pose * offsets[i]. grab() puts the frame at the grabbed particles' centroid, unrotated, so
/// that moving the pose's translation pulls the centroid there; attach() takes the frame of a
/// body (a gripper, a robot link) so that the particles follow that body as it moves and turns.
struct Drag {
  /// grabbed particle indices
  std::vector<std::uint32_t> particles;
  /// per particle: where it was in the drag frame when grabbed (m); its target is
  /// pose * offsets[i]
  std::vector<Eigen::Vector3d> offsets;
  /// the drag frame in the simulation frame at the end of the next step()
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  /// the drag frame the last step() ended at; the sub-steps of the next step() move the frame
  /// from here to `pose` (translation linearly, rotation by slerp), so that a frame moving
  /// steadily drags the particles at its own velocity instead of in one jump per step
  Eigen::Isometry3d reached = Eigen::Isometry3d::Identity();
  /// the drag frame at the sub-step being run, on the way from `reached` to `pose` (what the
  /// particles' targets follow within a step)
  Eigen::Isometry3d frame = Eigen::Isometry3d::Identity();
  /// 0 for a hard constraint (the particles follow their targets exactly); otherwise the
  /// stiffness (N/m) of a spring from each particle to its target, scaled by the particle's mass
  /// share
  double stiffness = 0.0;
  /// What the drag exerted on the object over the last step, mean over its sub-steps: force (N)
  /// and torque about the drag frame's origin (N m). A hard drag's is the impulse that held its
  /// particles on their targets against the rest of the step (m (v_target - v_free)); a spring
  /// drag's is its springs' force at the start of each sub-step. At rest: what the hand holds.
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  Eigen::Vector3d torque = Eigen::Vector3d::Zero();
  /// the step's sums behind force and torque (N s, N m s)
  Eigen::Vector3d impulse = Eigen::Vector3d::Zero();
  Eigen::Vector3d moment = Eigen::Vector3d::Zero();

  /// Where the grabbed particles' centroid is pulled to (m, simulation frame): pose applied to
  /// the centroid of the offsets (for grab(), the pose's translation).
  Eigen::Vector3d centroidTarget() const;
};

/// The spring drags on a particle may together be at most kMaxSpringRate M / h^2 stiff: each
/// drag counts its rate k h^2 / M (k its stiffness, M its grabbed mass, h the sub-step), summed
/// over the drags that hold the particle. Symplectic Euler is stable while that and shape
/// matching's share (at most 2, see Solver::alpha()) stay below 4; 1 keeps a margin. Per drag
/// alone, several spring drags on the same particles would add up past it. The implicit
/// integrator has no such limit (its springs are in the system it solves).
constexpr double kMaxSpringRate = 1.0;

/// How stiff a spring drag may be on a set of particles (Solver::springLimit()).
struct SpringLimit {
  /// the stiffest spring allowed (N/m): (kMaxSpringRate - taken) M / h^2, at least 0; infinite
  /// with the implicit integrator
  double stiffness = 0.0;
  /// M, the particles' mass (kg)
  double mass = 0.0;
  /// h, the sub-step (s)
  double substep = 0.0;
  /// the largest sum of rates k h^2 / M the other spring drags put on one of the particles
  double taken = 0.0;
};

/// A force spread over a set of particles in proportion to their masses, so that all of them
/// get the same acceleration F / M (M = their total mass).
struct TimedForce {
  std::vector<std::uint32_t> particles;
  /// total force (N)
  Eigen::Vector3d force = Eigen::Vector3d::Zero();
  /// simulated time left (s)
  double remaining = 0.0;
};

/// The region pass is a RegionKernel (privately): the summer calls back for the particle data, the
/// per-region shape match and damping field, and the per-particle goals, slice by slice.
class Solver : private RegionKernel {
 public:
  /// @throws std::invalid_argument if params.validate() fails or params.regionHalfWidth differs
  ///         from the lattice's.
  Solver(std::shared_ptr<const Lattice> lattice, const SolverParams& params);
  ~Solver();

  const Lattice& lattice() const { return *lattice_; }
  const SolverParams& params() const { return params_; }
  /// Changes stiffness, damping, gravity, time step, substeps and density-free settings at run
  /// time. @throws std::invalid_argument if invalid, or if regionHalfWidth or density change
  /// (they define the lattice: build a new Solver).
  void setParams(const SolverParams& params);
  /// With params.threads > 1 (fast solver), which steps ran on the threads and which on one
  /// thread: each step times itself and a ThreadGovernor picks the faster (results are
  /// identical either way); nullptr with one thread.
  const ThreadGovernor* threadGovernor() const { return singleSummer_ ? &governor_ : nullptr; }
  /// Sweeps its region sums through `scratch` (SliceStreamSummer::shareScratch()) from now on,
  /// also after a setParams() that rebuilds its summers; nullptr: buffers of its own again. For
  /// solvers that never step at once, such as the objects of a World (which gives them one set):
  /// the results are the same to the bit. No effect with SolverKind::Naive.
  void shareRegionScratch(std::shared_ptr<SliceStreamScratch> scratch);
  /// the slice buffers its region sums sweep (nullptr with SolverKind::Naive)
  std::shared_ptr<const SliceStreamScratch> regionScratch() const;

  /// alpha used per sub-step: params().requestedAlpha(spacing), capped. Classic mode: the cap is
  /// params().stiffness. Physical mode: the cap follows the stability of the sub-step, symplectic
  /// Euler on the linearised dynamics, (omega h)^2 < 2 (1 + keep), keep = exp(-ambientDamping h)
  /// - (1 - exp(-damping h)), the velocity a free object's stiffest mode keeps per sub-step
  /// (4 undamped): alpha (s_i + Lambda_i) <= 2 (1 + keep) * 1/2 * params().stiffness for every
  /// particle, s_i the region weight factor and Lambda_i the Poisson term's bound (see
  /// computeRegionWeights()); the stiffest mode then has half its limit.
  double alpha() const { return alpha_; }
  /// true when youngsModulus asks for more than the cap: the material is softer than asked,
  /// by the factor alpha() / params().requestedAlpha(); more sub-steps fix it.
  bool stiffnessSaturated() const;
  /// #P region weights beta_r (1 in classic mode; see computeRegionWeights()).
  const std::vector<double>& regionWeights() const { return regionWeight_; }

  /// Advances the simulation by params().timeStep in params().substeps sub-steps.
  void step();
  /// Simulated time since construction or reset() (s).
  double time() const { return time_; }
  /// Sub-steps taken since construction or reset().
  std::uint64_t substepCount() const { return substeps_; }

  /// Back to rest: positions = rest positions, zero velocities; drags, forces released; pins and
  /// colliders kept (their wrenches cleared).
  void reset();

  /// #P current positions x (m)
  const std::vector<Eigen::Vector3d>& positions() const { return x_; }
  /// #P current velocities v (m/s)
  const std::vector<Eigen::Vector3d>& velocities() const { return v_; }
  /// Overwrites the state (for tests and scenario set-up). Sizes must equal lattice().size().
  void setPositions(const std::vector<Eigen::Vector3d>& x);
  void setVelocities(const std::vector<Eigen::Vector3d>& v);
  /// #P rotations of the regions (region r is centred on particle r) from the last sub-step.
  const std::vector<Eigen::Quaterniond>& regionRotations() const { return rotations_; }
  /// Recomputes goal positions for the current positions without stepping (m).
  void computeGoals(std::vector<Eigen::Vector3d>& goals);

  // --- pins -----------------------------------------------------------------------------
  /// Pins (or unpins) the particles whose rest positions lie in the box [lo, hi] (m). A pinned
  /// particle is held where it is when pinned (at its rest position after reset()).
  /// Returns how many particles the box holds.
  std::size_t pinBox(const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, bool pinned);
  void setPinned(std::uint32_t particle, bool pinned);
  bool isPinned(std::uint32_t particle) const { return pinned_[particle] != 0; }
  std::size_t pinnedCount() const;

  // --- drags ----------------------------------------------------------------------------
  /// Grabs `particles` under `id` (replacing a drag of the same id) and pulls their centroid to
  /// `target`, keeping their arrangement unrotated. stiffness 0 = hard constraint, > 0 = spring
  /// (N/m). @throws std::invalid_argument, std::out_of_range for an empty or bad selection, a
  /// non-finite target, a negative stiffness, or a spring stiffer than springLimit() allows.
  void grab(const std::string& id, const std::vector<std::uint32_t>& particles,
            const Eigen::Vector3d& target, double stiffness);
  /// Attaches `particles` to a moving frame under `id` (replacing a drag of the same id): each
  /// keeps its present position in `frame` (simulation frame <- attached frame), and follows it
  /// when moveDrag() moves and turns the frame. Nothing moves until the frame does.
  /// @throws like grab(), and std::invalid_argument for a non-rigid or non-finite frame.
  void attach(const std::string& id, const std::vector<std::uint32_t>& particles,
              const Eigen::Isometry3d& frame, double stiffness);
  /// Moves the drag frame of drag `id` to `pose` at the end of the next step(). Returns false
  /// if there is no such drag. @throws std::invalid_argument for a non-rigid or non-finite pose.
  bool moveDrag(const std::string& id, const Eigen::Isometry3d& pose);
  /// Moves the origin of drag `id`'s frame to `target` and keeps its rotation (for a grab(): the
  /// grabbed centroid goes to `target`). Returns false if there is no such drag.
  bool moveDrag(const std::string& id, const Eigen::Vector3d& target);
  /// The stiffest spring drag `id` may put on `particles` beside the other spring drags on them
  /// (a drag of the same id is replaced: its own spring does not count), kMaxSpringRate.
  /// @throws std::out_of_range for a particle index out of range
  SpringLimit springLimit(const std::string& id, const std::vector<std::uint32_t>& particles) const;
  /// Releases drag `id`. Returns false if there is no such drag.
  bool release(const std::string& id);
  void releaseAll();
  const std::map<std::string, Drag>& drags() const { return drags_; }

  // --- forces ---------------------------------------------------------------------------
  /// Adds impulse J (N s) spread over `particles` by mass (every particle's velocity changes by
  /// J / M); applied at the start of the next sub-step.
  void applyImpulse(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& impulse);
  /// Applies total force F (N) over `particles` for `duration` seconds of simulated time.
  void applyForce(const std::vector<std::uint32_t>& particles, const Eigen::Vector3d& force,
                  double duration);
  const std::vector<TimedForce>& activeForces() const { return forces_; }

  // --- colliders ------------------------------------------------------------------------
  /// Adds collider `id`, or replaces the collider of that id. Particles collide with it as
  /// spheres of radius contactRadius(), with Coulomb friction (collider.h; the response is
  /// contactVelocityChange() in contact.h). A mesh collider gets its MeshDistanceField here when it has none (this
  /// takes a moment for a large mesh; share one field between colliders of the same mesh).
  /// @throws std::invalid_argument if collider.validate() fails (an open mesh among others).
  void setCollider(const std::string& id, const Collider& collider);
  /// Gives collider `id` its pose at the start of the next step() and its velocity over that
  /// step (the sub-steps move it along). step() leaves each collider at its pose at the end of
  /// the step, so that a collider keeps moving at its velocity until told otherwise.
  /// Returns false if there is no such collider.
  /// @throws std::invalid_argument for a non-finite pose or velocity, or a pose whose rotation
  ///         part is not a rotation.
  bool moveCollider(const std::string& id, const Eigen::Isometry3d& pose,
                    const Eigen::Vector3d& linearVelocity, const Eigen::Vector3d& angularVelocity);
  /// Removes collider `id`. Returns false if there is no such collider.
  bool removeCollider(const std::string& id);
  void removeAllColliders();
  const ColliderMap& colliders() const { return colliders_->map(); }
  /// The object's colliders are `colliders`, a World's for all its objects: from now on the
  /// World changes and moves them (and calls collidersChanged() after adding or removing one),
  /// this object reads them; setCollider(), moveCollider(), removeCollider() and
  /// removeAllColliders() then throw std::logic_error.
  void shareColliders(std::shared_ptr<ColliderScene> colliders);
  /// After the shared colliders were added to, replaced or removed from (between steps).
  void collidersChanged();
  /// What the object exerted on collider `id` during the last step(); zero for an unknown id.
  ContactWrench contactWrench(const std::string& id) const;
  /// Records from the next step on (or stops recording) each particle's force on collider `id`
  /// (its tactile image); kept for a collider of that id added later. Between steps only; a
  /// recorded collider costs a vector per particle and a store per contact.
  void recordContacts(const std::string& id, bool on);
  /// The forces recorded on `id` over the last step, one entry per particle that touched it (in
  /// particle order); they add up to contactWrench(id).force when this object's own contact
  /// pass or implicit solve found every contact (not those another contact solver added with
  /// addColliderImpulse()). Empty for a collider not recorded.
  const std::vector<ParticleContact>& recordedContacts(const std::string& id) const;
  /// Radius of the particles' contact spheres (m): params().contactRadius, or half the lattice
  /// spacing when that is 0. At half the spacing a particle's sphere touches its cell's faces, so
  /// the particles of a full bottom layer stand with their cells' lower faces on the ground: the
  /// rest surface of the voxelized object rests on the collider.
  double contactRadius() const;

  // --- queries --------------------------------------------------------------------------
  /// The `count` particles nearest to `point` in the current configuration, nearest first.
  std::vector<std::uint32_t> nearestParticles(const Eigen::Vector3d& point, std::size_t count) const;
  /// The particles within `radius` of `point` in the current configuration.
  std::vector<std::uint32_t> particlesWithin(const Eigen::Vector3d& point, double radius) const;

  // --- diagnostics ----------------------------------------------------------------------
  double kineticEnergy() const;
  Eigen::Vector3d linearMomentum() const;
  /// about the origin
  Eigen::Vector3d angularMomentum() const;
  /// Largest |x_i - x0_i| (m).
  double maxDisplacement() const;
  /// Best rigid fit of the whole object: the transform T with T x0 ~ x in the least-squares
  /// sense (mass-weighted), i.e. the object's frame relative to its rest pose. Updates the fit's
  /// warm start: like step(), call it from the thread that owns the solver.
  Eigen::Isometry3d rigidFrame() const;
  /// RMS distance (m) between x and the best rigid fit of the rest shape: 0 at the rest shape
  /// up to rigid motion.
  double shapeError() const;
  /// true while a drag, a timed force or an impulse is active: the object is being acted on.
  bool hasPendingCommands() const;
  /// Counts the calls that changed its state or what holds it from outside a step: setParams(),
  /// reset(), setPositions(), setVelocities(), a pin set or freed (not step(), commands or
  /// colliders). A World wakes a sleeping object whose count moved.
  std::uint64_t stateVersion() const { return stateVersion_; }

  // --- the phases of a step, for a coordinator of several objects (World) ----------------
  /// step() is beginStep(), advanceSubstep(s) for s = 0 .. params().substeps - 1, then
  /// endStep(): a coordinator runs several objects' sub-steps interleaved and acts on their
  /// states between them (contact between objects). Results equal step()'s.
  void beginStep();
  /// Sub-step s of the step begun: the drag frames at (s + 1) / substeps of the way, the
  /// integrator's sub-step with the collider contact pass, the pinned and dragged particles.
  void advanceSubstep(int s);
  /// Closes the step: collider wrenches averaged over it, drag frames reached.
  void endStep();
  /// The step of an object that is not moved (a World's sleeping object, at rest): its clock
  /// and its colliders' poses advance by one step, its particles stay where they are with zero
  /// velocity, and its collider wrenches keep the last step's (its weight on what holds it).
  void idleStep();
  /// #P positions and velocities between sub-steps, for a contact solver that corrects them
  /// (a correction dv moves x by h dv: x = x_start + h v holds, as in the collider pass).
  std::vector<Eigen::Vector3d>& substepPositions() { return x_; }
  std::vector<Eigen::Vector3d>& substepVelocities() { return v_; }
  /// Whether particle p's motion is prescribed (pinned or hard-dragged): to contact, a
  /// particle of infinite mass.
  bool isPrescribed(std::uint32_t p) const { return pinned_[p] != 0 || hardDragged_[p] != 0; }
  /// Particle p touches the shared collider of place c (in colliders()' order) in the sub-step
  /// just taken: another contact solver's contact, counted in contactWrench() once with the
  /// object's own.
  /// @throws std::out_of_range for a particle or a place that is not this object's.
  void touchCollider(std::uint32_t p, std::size_t c);
  /// Counts into the wrench of the shared collider of place c an impulse that another contact
  /// solver gave this object's particles during the step begun (before endStep()): `impulse` the
  /// sum of m dv on the particles, `moment` its moment about the collider's origin.
  /// @throws std::out_of_range for a place that is not one of the colliders'.
  void addColliderImpulse(std::size_t c, const Eigen::Vector3d& impulse, const Eigen::Vector3d& moment);

 private:
  double stepSeconds_ = 0.0;  // time spent in this step's sub-steps, for the thread governor

 private:
  /// The goals for the current state, with region damping when withDamping; while an explicit
  /// step integrates (integrating_), its update of every particle (ExplicitStep::update()),
  /// else the goals into *goalsOut_ (computeGoals()).
  void regionPass(bool withDamping);
  /// the end of every sub-step, either integrator: contactPass() and finishSubstep() over the
  /// step h, the timed forces' countdown and the clock by elapsed (h but for BDF2's solve)
  void endSubstep(double h, double elapsed);
  /// the sub-step's update of the pinned and hard-dragged particles
  void finishSubstep(double h);
  /// hardDragged_ from drags_ (solver_commands.cpp)
  void markHardDrags();
  /// Stores a drag under `id`: offsets are the particles' positions in `frame`
  /// (solver_commands.cpp).
  void addDrag(const std::string& id, const std::vector<std::uint32_t>& particles,
               const Eigen::Isometry3d& frame, const Eigen::Isometry3d& pose, double stiffness);
  /// Every drag's frame at fraction `s` of the step from `reached` to `pose` (Drag::frame;
  /// solver_commands.cpp).
  void interpolateDragFrames(double s);
  // RegionKernel
  int gatherChannels() const override;
  int scatterChannels() const override;
  void particleData(std::size_t begin, std::size_t end, double* out) override;
  void regionData(std::size_t begin, std::size_t end, const double* sums, double* out) override;
  void particleResult(std::size_t begin, std::size_t end, const double* sums) override;
  /// forceAccel_ from the timed forces and spring drags for a sub-step (solver_commands.cpp)
  void accumulateForces(double h);
  /// The impulses applied since the last sub-step added to v_ (solver_commands.cpp)
  void applyPendingImpulses();
  // --- contact (solver_contact.cpp) ---
  /// Collider poses at the start of a step, wrench accumulators cleared.
  void beginContactStep();
  /// The contact response of the free particles after the region pass of a sub-step of length h.
  void contactPass(double h);
  /// What a contact pass's chunks share: the sub-step, the contact radius, whether the world holds
  /// the object, the depth below which all of it is inside, the region pass's goals.
  struct ContactPassFrame {
    double h = 0.0, r = 0.0, enclosed = 0.0;
    bool held = false;
    const std::vector<Eigen::Vector3d>* goals = nullptr;
  };
  /// contactPass()'s stages: the bodies near the object (activeBodies_); one chunk of particles
  /// against the bodies near it, its impulses in its ContactPartial; the partials summed on the
  /// bodies.
  void placeContactBodies(double r);
  /// Collider c of the scene as the sub-step sees it (ColliderScene::posed()).
  const PosedCollider& posed(std::size_t c) const { return colliders_->posed()[c]; }
  void contactChunk(std::ptrdiff_t chunk, const ContactPassFrame& pass);
  /// The active bodies near particles [begin, end) (within r of their bounding box), into `near`;
  /// returns their count.
  int bodiesNear(std::size_t begin, std::size_t end, double r, int* near) const;
  void sumContactPartials(std::ptrdiff_t chunks);
  /// Wrenches averaged over the step; colliders left at their end-of-step poses.
  void endContactStep();
  /// contactBodies_ and the reduction buffers after a change of colliders_.
  void rebuildContactBodies();
  /// beta_r, the Poisson stencil and the cap on alpha (solver_material.cpp)
  void computeRegionWeights();
  /// computeRegionWeights()'s stages: beta_r (and the Poisson term's deficits D_ra), the Poisson
  /// stencils, the cap on alpha with a modulus.
  void weighRegions(std::vector<double>& deficit);
  void buildStencils(std::vector<double>& deficit);
  void capPhysicalAlpha(double requested, const std::vector<double>& deficit);
  /// summer_ (and singleSummer_) for params_.kind and threads_.
  void makeSummers();
  /// accumulateForces()'s capacity, reserved when a command arrives (solver_commands.cpp)
  void reserveForcedParticles();

  std::shared_ptr<const Lattice> lattice_;
  SolverParams params_;
  std::unique_ptr<RegionSummer> summer_;
  /// With threads_ > 1: the same sums on one thread, for the steps the governor gives to it.
  std::unique_ptr<RegionSummer> singleSummer_;
  RegionSummer* activeSummer_ = nullptr;  // the summer of the step being run
  std::shared_ptr<SliceStreamScratch> sharedScratch_;  // shareRegionScratch()'s, or null
  ThreadGovernor governor_;

  std::vector<Eigen::Vector3d> x_, v_;
  std::vector<Eigen::Vector3d>* goalsOut_ = nullptr;  // where computeGoals() wants the goals
  std::vector<Eigen::Quaterniond> rotations_;
  std::vector<Eigen::Vector3d> restCentered_;  // q_i = x0_i - rest centre of mass
  Eigen::Vector3d restCom_ = Eigen::Vector3d::Zero();
  std::vector<double> invCount_;               // 1 / n_i
  std::vector<double> regionMass_;             // M_r = sum of m~ over region r
  std::vector<double> regionInvMass_;          // 1 / M_r
  std::vector<Eigen::Vector3d> regionRestCenter_;  // c0_r (rest-centred frame)
  Eigen::Vector3d xref_ = Eigen::Vector3d::Zero();  // the anchor's position, subtracted in sums
  std::uint32_t anchor_ = 0;  // the particle nearest the rest centre of mass
  std::vector<char> pinned_;
  std::vector<std::uint32_t> pinnedList_;  // the indices where pinned_ is set
  bool pinnedListStale_ = false;           // pinned_ changed since pinnedList_ was listed
  std::vector<char> hardDragged_;          // 1 where a hard drag (stiffness 0) holds the particle
  std::vector<Eigen::Vector3d> pinPosition_;
  mutable Eigen::Quaterniond frameRotation_ = Eigen::Quaterniond::Identity();  // rigidFrame warm start
  std::vector<Eigen::Vector3d> impulseDv_;  // velocity change pending from impulses
  /// Counts impulse J on particle p (at x_[p]) into drag d's sums.
  static void countDragImpulse(Drag& d, const Eigen::Vector3d& x, const Eigen::Vector3d& J) {
    d.impulse += J;
    d.moment += (x - d.frame.translation()).cross(J);
  }
  bool impulsePending_ = false;
  std::map<std::string, Drag> drags_;
  /// the colliders: the object's own, or its World's (shareColliders()); posed over a step only
  /// by their keeper (the World, or the lone object)
  std::shared_ptr<ColliderScene> colliders_ = std::make_shared<ColliderScene>();
  bool ownsColliders_ = true;
  /// throws std::logic_error when the colliders are a World's
  void checkOwnsColliders(const char* what) const;
  /// What the object gave collider c (posed(c)) over the step, in the order of colliders_.
  struct ContactBody {
    const Collider* collider = nullptr;  // to keep a staying collider's wrench over a change of the set
    Eigen::Vector3d impulse = Eigen::Vector3d::Zero();  // sum of m dv on the particles this step
    Eigen::Vector3d moment = Eigen::Vector3d::Zero();   // sum of (contact point - origin) x m dv
    std::size_t buried = 0;  // the most particles buried deeper than r at a sub-step's start, this step
    ContactWrench wrench;                                // over the last step
    /// recordContacts(): per particle its impulse on the body this step (m dv, summed) and its
    /// last contact point; the step's contacts as a list
    bool recording = false;
    std::vector<Eigen::Vector3d> particleImpulse, particlePoint;
    std::vector<ParticleContact> recorded;
  };
  /// the colliders whose contacts are recorded (recordContacts()), by id
  std::set<std::string> recordedIds_;
  /// Counts particle i's impulse J on body a, meeting it at `point`, when a records.
  static void record(ContactBody& body, std::size_t i, const Eigen::Vector3d& J, const Eigen::Vector3d& point) {
    if (!body.recording) return;
    body.particleImpulse[i] += J;
    body.particlePoint[i] = point;
  }
  /// One chunk's share of a body's impulse (chunks of fixed size: thread-count-independent sums).
  struct ContactPartial {
    Eigen::Vector3d impulse = Eigen::Vector3d::Zero();
    Eigen::Vector3d moment = Eigen::Vector3d::Zero();
    std::size_t buried = 0;
  };
  std::vector<ContactBody> contactBodies_;
  std::vector<int> activeBodies_;               // bodies near the object in this sub-step
  ContactTally tally_;  // the colliders each particle touched in the sub-step, for the wrenches' contacts
  /// Starts a sub-step's contacts; a lone object poses its colliders for sub-step s.
  void beginContactSubstep(int s);
  std::vector<ContactPartial> contactPartials_;  // chunk-major, #chunks x #bodies
  std::vector<int> chunkBodies_;                // per chunk, the active bodies near it (#chunks x #bodies)
  std::vector<TimedForce> forces_;
  std::vector<Eigen::Vector3d> forceAccel_;  // per-particle acceleration from forces and springs
  std::vector<std::uint32_t> forcedParticles_;  // where forceAccel_ is non-zero
  bool passDamping_ = false;  // the current region pass computes the damping field too
  std::size_t pinnedCount_ = 0;
  /// The object's rigid motion v_obj(x) = velocity + spin x (x - xref_), what relative ambient
  /// damping leaves alone: rigidMotion() gives the one that keeps its momenta now (xref_ updated).
  struct RigidMotion {
    Eigen::Vector3d velocity = Eigen::Vector3d::Zero(), spin = Eigen::Vector3d::Zero();
  };
  RigidMotion rigidMotion();
  /// pinned, dragged or attached, or with colliders to rest on: ambient damping drags to rest
  bool heldByWorld() const;
  std::vector<double> regionWeight_;     // beta_r
  bool volumetric_ = false;  // physical mode with nu > 0: the Poisson term is on
  /// The Poisson term on the lattice stencil of each particle (see computeVolumetricForces())
  struct VolumetricStencil {
    std::uint32_t plus[3], minus[3];  // the particles whose difference is column a of F_i
    double invDistance[3];            // 1 / their rest distance along a; 0 where there is none
    double mass;                      // the lightest member's mass (kg): V_i = mass / rho
    double weight;                    // lambda_eff V_i (N m)
    double deficit[3];                // k D_ia: the normal-strain stiffness region i lacks (N m)
  };
  std::vector<VolumetricStencil> stencil_;
  std::vector<std::array<Eigen::Vector3d, 3>> stencilForce_;  // G_ia = lambda V e_i F_ia / d_ia
  std::vector<Eigen::Vector3d> volumetricAccel_;
  /// volumetricAccel_ from the Poisson term (solver_material.cpp)
  void computeVolumetricForces();
  std::vector<double> invWeightSum_;     // 1 / sum_{r contains i} beta_r
  std::vector<double> stiffnessFactor_;  // s_i = sum_{r contains i} beta_r / n_i
  int threads_ = 1;
  double alphaCap_ = 1.0;
  double alpha_ = 1.0;
  double time_ = 0.0;
  std::uint64_t substeps_ = 0;
  std::uint64_t stateVersion_ = 0;

 public:
  // --- implicit integrator (solver_implicit.cpp) ------------------------------------------
  /// The conjugate-gradient solve of the last implicit sub-step (zeros before the first);
  /// iterations summed over its contact passes.
  const PcgResult& lastImplicitSolve() const;

  // --- one member of a coupled implicit solve (ImplicitCoupling; solver_implicit.cpp): with the
  // implicit integrator only ------------------------------------------------------------------
  // Several objects' sub-steps as one system: each object's system begun here, solved there
  // through implicitProduct(), implicitPrecondition() and updateContactSet(), ended here.
  /// Sub-step s of length h begun as a member: the drags' frames at its end and the object's
  /// system (ImplicitStep::begin()), which the accessors below show.
  void beginCoupledSubstep(int s, double h);
  /// The system A v = b of the sub-step begun: v_{n+1} (the unknown, which the coupled solve
  /// sets), b, each row's constraint and normal, the inverse of the Jacobi diagonal (the const
  /// ones empty, and the norms 0, for an explicit object).
  std::vector<Eigen::Vector3d>& implicitVelocity();
  const std::vector<Eigen::Vector3d>& implicitRhs() const;
  const std::vector<PcgConstraint>& implicitConstraints() const;
  const std::vector<Eigen::Vector3d>& implicitNormals() const;
  const std::vector<Eigen::Vector3d>& implicitInvDiagonal() const;
  /// The squared P-norms of h f(x_n) and of M g h over the free particles, and their count: what
  /// a solve's floor is made of.
  double implicitRhsNorm2() const;
  double implicitGravityNorm2() const;
  std::size_t implicitFreeCount() const;
  /// y = A p, A the implicit step's matrix M + h C + h^2 K (rows of fixed entries meaningless).
  void implicitProduct(const std::vector<Eigen::Vector3d>& p, std::vector<Eigen::Vector3d>& y);
  /// z = P^-1 r: the object's two-level preconditioner with `invDiagonal` as its Jacobi part
  /// (implicitInvDiagonal(), or a coupled solve's with its springs added).
  void implicitPrecondition(const std::vector<Eigen::Vector3d>& invDiagonal, const std::vector<Eigen::Vector3d>& r,
                            std::vector<Eigen::Vector3d>& z);
  /// The contact active set after a solve: lets go of pulling contacts, turns sticking ones out
  /// of the friction cone into sliding ones, adds particles the solution carries into a
  /// collider; returns whether it changed (never without colliders). Sets guessChanged when it
  /// prescribed a velocity (the next solve then needs its residual computed again).
  /// The solve's residual is pcg.residual()[offset + i].
  bool updateContactSet(double h, bool& guessChanged, Pcg& pcg, std::size_t offset);
  /// The member's sub-step of length h ended after the coupled solve (`result`, its residual at
  /// residual[offset + i]): `couplingImpulse` (per particle) the impulse the other objects gave
  /// each particle in the solve, which the momentum correction counts as external.
  void endCoupledSubstep(double h, const PcgResult& result, const std::vector<Eigen::Vector3d>& residual,
                         std::size_t offset, const std::vector<Eigen::Vector3d>& couplingImpulse);
  /// Counts `seconds` of a coupled solve as this object's step time, for its thread governor.
  void addCoupledSolveTime(double seconds);

 private:
  /// The integrators' sub-steps with their own state: their interface (integrator_step.h), the
  /// implicit step (backward Euler and BDF2, implicit_step.h), the explicit one (explicit_step.h).
  class IntegratorStep;
  class ImplicitStep;
  class ExplicitStep;
  std::unique_ptr<ImplicitStep> implicit_;  // made with the implicit integrator, kept after a switch
  /// The implicit step when it is the integrator (one kept from before a switch to the explicit
  /// step is not), else null: what the implicit-system accessors read.
  const ImplicitStep* implicitSystem() const;
  std::unique_ptr<ExplicitStep> explicit_;  // made with the explicit integrator
  IntegratorStep* integrator_ = nullptr;    // the step of params_.integrator
  ExplicitStep* integrating_ = nullptr;     // the explicit step whose sub-step runs: its region pass integrates
  /// After computeRegionWeights(): integrator_ made for params_.integrator; with the implicit
  /// one, alpha as requested (no cap) and the step's buffers sized; called from the constructor
  /// and setParams(), never in a step.
  void configureIntegrator();
};

}  // namespace deformable_flsm
