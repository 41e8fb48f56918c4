/// @file world.h
/// A scene of several deformable objects advanced by one step: each object is a Solver with its
/// own lattice (mesh, pose, scale, resolution) and SolverParams (material, regions); the rigid
/// colliders are shared; object-object contact and self-contact with Coulomb friction run in
/// every sub-step beside the colliders' contact pass, found through a spatial hash so that their
/// cost grows with the particles near each other, not with the square of the object count.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/solver_params.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <memory>
#include <set>
#include <string>
#include <vector>

namespace deformable_flsm {

/// How objects touch each other and themselves.
struct ObjectContactParams {
  /// contact between different objects
  bool enabled = true;
  /// contact of an object with itself: particles farther apart than `selfExclusion` lattice
  /// cells in the rest lattice collide as spheres (an object bent onto itself)
  bool selfContact = false;
  /// rest-lattice neighbourhood (cells, Chebyshev distance) left out of self-contact
  int selfExclusion = 2;
  /// Coulomb friction between objects (the lower of the two objects' if they differ is not
  /// modelled: one pair of coefficients for every object pair)
  double staticFriction = 0.6;
  double kineticFriction = 0.5;
  /// Gauss-Seidel passes over the contacts per sub-step at most (>= 1; fewer once a pass changes
  /// nothing): more make the impulses through a stack of objects converge within a sub-step
  int iterations = 16;

  /// @throws std::invalid_argument saying which field is wrong
  void validate() const;
  /// whether `objects` objects may touch each other or themselves: implicit ones are then
  /// solved as one backward Euler system (World::step())
  bool couples(std::size_t objects) const { return (objects >= 2 && enabled) || selfContact; }
};

/// When the objects of a World sleep: an object at rest is not stepped (its particles stay, its
/// wrenches on the colliders and on the other sleeping objects it touches keep the last step's)
/// until something moves near it. Rest in the node's loop's sense (LoopSettings: equilibrium,
/// not slowness), over the object's particles as an RMS where the loop takes the largest
/// particle's. An object falls asleep once its particles' mass-weighted RMS displacement from
/// where they were `hold` seconds of simulated time earlier stays below `fraction` of its size
/// (Lattice::objectSize()), with no drag, force or impulse on it and no collider moving near it.
/// It wakes when a command or a state change reaches it (Solver::hasPendingCommands(),
/// Solver::stateVersion()), when a collider of the World is set, moved or removed near it (or
/// moves near it within a step), when
/// an object is added or removed or the contact parameters change, when a touching object
/// moved farther than five hundredths of its contact radius in the last step (the RMS of its
/// particles' |v| T: a push, not the jiggle of a soft pile), and when the other
/// objects' force on it changed by a tenth of its weight since it fell asleep. A sleeping object
/// is immovable to the others: they rest on it as on a collider (an implicit object keeps its
/// contact springs to a sleeping implicit one in its solve, the sleeping particles held still),
/// and one that moves or pushes wakes it for the next step. A non-finite state never rests.
struct SleepParams {
  /// 0: never sleep
  double fraction = 0.0;
  /// s of simulated time (> 0)
  double hold = 1.0;
  /// @throws std::invalid_argument saying which field is wrong
  void validate() const;
};

/// What one object exerted on another over the last step.
struct ObjectPairWrench {
  std::string from;  ///< the object that pushed
  std::string on;    ///< the object it pushed
  /// force on `on` (N, simulation frame), torque about the simulation frame's origin (N m),
  /// particle pairs in contact at the end of the last sub-step
  ContactWrench wrench;
};

class World {
 public:
  /// @param timeStep  the step every object is advanced by (s); an object's
  ///                  SolverParams::timeStep must equal it
  /// @param substeps  sub-steps per step, shared by every object (object-object contact runs
  ///                  after each); an object's SolverParams::substeps must equal it
  /// @throws std::invalid_argument for a non-positive or non-finite time step, sub-steps < 1 or
  ///         contact parameters that fail ObjectContactParams::validate()
  World(double timeStep, int substeps, const ObjectContactParams& contact = ObjectContactParams());
  ~World();
  World(const World&) = delete;
  World& operator=(const World&) = delete;

  /// Why an object of params `p` cannot be stepped among `objects` objects with these contact
  /// settings, or nullptr: an implicit object with ImplicitScheme::Bdf2 steps alone, and objects
  /// that may touch each other (or one itself) are solved as one backward Euler system.
  static const char* bdf2Refusal(const SolverParams& p, std::size_t objects, const ObjectContactParams& contact);

  // --- objects ------------------------------------------------------------------------
  /// Adds object `name` (its lattice already placed where it starts: voxelize the mesh at its
  /// pose and scale). It reads the world's colliders (one map for every object,
  /// Solver::shareColliders()). The objects' region sums share one set of slice buffers
  /// (Solver::shareRegionScratch()): step them through step() only, never two of them at once
  /// from different threads.
  /// @throws std::invalid_argument for an empty or duplicate name, params whose time step or
  ///         sub-steps differ from the world's, or an object that starts inside another
  ///         (particles closer than the sum of their contact radii), naming both objects
  Solver& addObject(const std::string& name, std::shared_ptr<const Lattice> lattice,
                    const SolverParams& params);
  /// Removes object `name`; false when there is none. Between steps only.
  bool removeObject(const std::string& name);
  /// nullptr when there is no such object
  Solver* object(const std::string& name);
  const Solver* object(const std::string& name) const;
  /// the objects' names in the order they were added
  const std::vector<std::string>& objectNames() const { return names_; }
  std::size_t objectCount() const { return names_.size(); }

  // --- colliders, shared by every object (the same semantics as Solver's) ---------------
  void setCollider(const std::string& id, const Collider& collider);
  bool moveCollider(const std::string& id, const Eigen::Isometry3d& pose,
                    const Eigen::Vector3d& linearVelocity, const Eigen::Vector3d& angularVelocity);
  bool removeCollider(const std::string& id);
  /// what all objects together exerted on collider `id` over the last step
  ContactWrench contactWrench(const std::string& id) const;
  /// Records each particle's force on collider `id` in every object, and in objects added later
  /// (Solver::recordContacts(); read with object(name)->recordedContacts(id)). Where objects
  /// touch (ObjectContactParams::couples()), the collider contacts of particles near other
  /// objects go through the objects' shared solve and would be missing from the record:
  /// @throws std::invalid_argument then.
  void recordContacts(const std::string& id, bool on);
  /// the colliders whose contacts are recorded
  const std::set<std::string>& recordedColliders() const { return recordedIds_; }

  // --- object-object contact ----------------------------------------------------------
  const ObjectContactParams& contactParams() const { return contact_; }
  /// Wakes every sleeping object.
  /// @throws std::invalid_argument when contact.validate() fails (the old parameters stay)
  void setContactParams(const ObjectContactParams& contact);
  /// Every ordered pair (from, on) of different objects that touched in the last step, with
  /// what `from` exerted on `on` (the reverse pair carries the opposite force).
  const std::vector<ObjectPairWrench>& objectWrenches() const;
  /// what object `from` exerted on object `on` over the last step; zero when they did not touch
  ContactWrench objectWrench(const std::string& from, const std::string& on) const;
  /// How many times the object contact's candidate list was built (wholly or for some objects)
  /// since the world was made: a figure for benchmarks.
  std::size_t contactListBuilds() const;
  /// The object contact's Gauss-Seidel passes per sub-step with contacts, on average since the
  /// world was made (at most ObjectContactParams::iterations; fewer once a pass changes nothing):
  /// a figure for benchmarks. `since` = {passes, sub-steps} of an earlier contactPasses() call
  /// gives the average since then.
  struct ContactPasses {
    std::size_t passes = 0, substeps = 0;
    double perSubstep() const { return substeps > 0 ? double(passes) / double(substeps) : 0.0; }
    ContactPasses since(const ContactPasses& before) const {
      return {passes - before.passes, substeps - before.substeps};
    }
  };
  ContactPasses contactPasses() const;
  /// The CPU time of the object contact's parts since the world was made, while
  /// setContactTiming(true) was in force (off by default: it costs a few system calls per
  /// sub-step): `list` the candidate list's checks and builds, `pairs` finding the contacts
  /// among the candidates, `passes` the Gauss-Seidel passes, `rest` the others (gathering,
  /// warm start, collider contacts, keeping the impulses, push-out, scattering, the sums, the
  /// implicit step's spring impulses taken in). A figure for benchmarks.
  struct ContactTimes {
    double list = 0.0, pairs = 0.0, passes = 0.0, rest = 0.0;
    ContactTimes since(const ContactTimes& before) const {
      return {list - before.list, pairs - before.pairs, passes - before.passes, rest - before.rest};
    }
  };
  void setContactTiming(bool on);
  ContactTimes contactTimes() const;

  // --- sleeping objects (SleepParams) ---------------------------------------------------
  const SleepParams& sleepParams() const;
  /// @throws std::invalid_argument when sleep.validate() fails (the old parameters stay); a
  ///         fraction of 0 wakes every object
  void setSleepParams(const SleepParams& sleep);
  /// whether object `name` is asleep: it sleeps through the next step unless something wakes it
  /// (false for an unknown name)
  bool asleep(const std::string& name) const;
  /// how many objects slept through the last step
  std::size_t sleepingCount() const;
  /// Wakes object `name` (false when there is none) or every object.
  bool wake(const std::string& name);
  void wakeAll();

  // --- the step -----------------------------------------------------------------------
  /// Advances every object by one time step: per sub-step each object's dynamics and collider
  /// contact, then object-object and self-contact. Allocates nothing once the contacts' buffers
  /// have grown to the scene's size.
  /// @throws std::logic_error when an object's timeStep or substeps was changed (through its
  ///         Solver::setParams()) to differ from the world's, naming it; nothing is stepped
  void step();
  double time() const { return time_; }
  double timeStep() const { return timeStep_; }
  int substeps() const { return substeps_; }

 private:
  struct Impl;
  // the stages of step(), in their order
  /// an object given a time step or scheme the world cannot step is refused before anything moves
  void checkObjects() const;
  /// which objects sleep through the step: those at rest that nothing has reached (Sleeping)
  void chooseSleepers();
  /// the awake objects begin their step; the contact pass learns which objects sleep through it
  void beginObjects();
  /// which implicit objects may touch and so are solved as one system (true when any are)
  bool planCoupling();
  /// sub-step s: the awake objects' dynamics (the coupled ones in one solve), then object contact
  void substep(int s, bool couple);
  /// the world's clock as each object's: the sum of the sub-steps
  void advanceClock();
  /// the awake objects end their step with the contact pass's share against the colliders
  void endObjects();
  /// the colliders at the poses their velocities carried them to over the step
  void advanceColliders();
  /// the pair impulses as wrenches both ways, read by objectWrench(); sleeping pairs keep theirs
  void collectWrenches();
  /// which sleeping objects a touching object or a change of load wakes, which fall asleep (Sleeping)
  void settle();

  std::unique_ptr<Impl> impl_;
  std::vector<std::string> names_;
  ObjectContactParams contact_;
  std::set<std::string> recordedIds_;  ///< recordContacts()
  double timeStep_ = 0.0;
  int substeps_ = 1;
  double time_ = 0.0;
};

}  // namespace deformable_flsm
