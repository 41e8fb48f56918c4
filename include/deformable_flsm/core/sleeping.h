/// @file sleeping.h
/// The sleeping of a World's objects (SleepParams): which objects sleep through a step, what wakes
/// them and which fall asleep after it. The World drives it: it adds and removes the objects (in
/// its order), reports the colliders it changes, and calls beforeStep() and afterStep() around
/// each step.
#pragma once

#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/object_contact.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/world.h"

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {

class Sleeping {
 public:
  /// A touching object that moved farther than this fraction of its contact radius in a step (the
  /// RMS of |v| T) wakes a sleeping one: above the jiggle of a soft pile's woken objects, which
  /// would otherwise wake their neighbours in turn.
  static constexpr double kWakeMotion = 0.05;
  /// A change of the other objects' force on a sleeping object by this fraction of its weight
  /// wakes it: a push slower than kWakeMotion, an object lifted off it.
  static constexpr double kWakeLoad = 0.1;

  const SleepParams& params() const { return params_; }
  /// @throws std::invalid_argument when params.validate() fails (the old parameters stay); a
  ///         fraction of 0 wakes every object of `objects`
  void setParams(const SleepParams& params, const std::vector<Solver*>& objects);
  bool enabled() const { return params_.fraction > 0.0; }

  /// `object` appended, awake
  void add(const Solver& object);
  void remove(std::size_t o);
  /// object o (`object`) awake, its rest to be held anew from where it is
  void wake(std::size_t o, const Solver& object);
  void wakeAll(const std::vector<Solver*>& objects);
  /// whether object o sleeps through the next step unless something wakes it
  bool asleep(std::size_t o) const { return objects_[o].asleep; }
  std::size_t count() const;

  /// A collider set, moved or removed, at its pose before or after the change: the objects near
  /// it wake before the next step (nothing is kept while sleeping is off).
  void disturb(const Collider& collider);

  /// Before a step: wakes the objects a command, a change of their state or a collider changed or
  /// moving near them reaches, then fixes which objects sleep through the step.
  void beforeStep(const std::vector<Solver*>& objects, const std::map<std::string, Collider>& colliders,
                  double timeStep);
  /// Per object, whether it sleeps through the current step: asleep when the step began, while
  /// asleep() is the state for the next step (afterStep() may wake it).
  const std::vector<char>& asleepThisStep() const { return asleepThisStep_; }
  /// After the step, given what the objects exerted on each other (`wrenches`, per wrench its
  /// (from, on) objects in `wrenchObjects`, and the contact pass's `pairs`): how far each stepped
  /// object moved, which sleeping objects a touching object's motion or a change of load wakes,
  /// and which objects, at rest for `hold`, fall asleep.
  void afterStep(const std::vector<Solver*>& objects, const std::vector<ObjectPairWrench>& wrenches,
                 const std::vector<std::pair<std::uint32_t, std::uint32_t>>& wrenchObjects,
                 const std::vector<PairImpulse>& pairs, double timeStep);

 private:
  /// Per object, what its rest needs.
  struct Rest {
    bool asleep = false;
    double heldFor = 0.0;                 // s of simulated time within the limit of `anchor`
    std::vector<Eigen::Vector3d> anchor;  // where that time began
    std::uint64_t version = 0;            // Solver::stateVersion() when it fell asleep
    Eigen::Vector3d lo = Eigen::Vector3d::Zero(), hi = Eigen::Vector3d::Zero();  // its particles' bounds
    double step = 0.0;                    // how far it moved in the last step (RMS of |v| T)
    Eigen::Vector3d load = Eigen::Vector3d::Zero();  // the other objects' force on it when it fell asleep
  };
  /// A collider changed, or moving in this step: objects within `margin` (plus two contact radii)
  /// of it at this pose wake.
  struct Disturbance {
    Collider collider;
    double margin = 0.0;
  };
  void bound(std::size_t o, const Solver& object);
  /// how far each stepped object moved, and whether it stayed within its rest's limit
  void measure(const std::vector<Solver*>& objects, double timeStep);
  /// the sleeping objects that a touching object's motion or a change of load wakes
  void wakeTouched(const std::vector<Solver*>& objects, const std::vector<ObjectPairWrench>& wrenches,
                   const std::vector<std::pair<std::uint32_t, std::uint32_t>>& wrenchObjects,
                   const std::vector<PairImpulse>& pairs);

  SleepParams params_;
  std::vector<Rest> objects_;
  std::vector<char> asleepThisStep_;
  std::vector<Eigen::Vector3d> load_;  // per object, the other objects' force on it in the last step
  std::vector<Disturbance> disturbances_;
};

}  // namespace deformable_flsm
