/// @file thread_governor.h
/// Chooses, step by step, between a solver step on several threads and one on a single thread,
/// from their measured wall times. Both give bit-identical results (SliceStreamSummer's sums do
/// not depend on the thread count), so the choice is about speed only.
#pragma once

#include <array>
#include <cstddef>

namespace deformable_flsm {

/// Threads pay only when they get a core each: a sub-step's region pass waits for its slowest
/// thread, so with another process busy on one of two cores a two-thread step can take several
/// times a one-thread step. The governor keeps the mode whose steps are faster and now and then
/// tries the other (a probe): after every probe that loses, the next comes twice as late (from
/// kFirstProbe up to kLastProbe steps), so that a mode that keeps losing costs less and less;
/// a probe that wins switches at once. A step much slower than its mode's recent ones (the
/// machine changed: another job started or stopped) brings the next probe forward.
///
/// Usage, per step: `bool t = g.threaded();` run the step on that many threads, then
/// `g.record(seconds)`. No allocation; not thread-safe (one per solver).
class ThreadGovernor {
 public:
  /// Steps before the first probe, and the longest interval between two probes.
  static constexpr int kFirstProbe = 8;
  static constexpr int kLastProbe = 256;
  /// A probe switches modes only when it is this much faster than its rival's recent median.
  static constexpr double kSwitchMargin = 0.05;
  /// A step this many times its mode's recent median brings the next probe forward.
  static constexpr double kChangeFactor = 2.0;
  /// Recent steps remembered per mode.
  static constexpr std::size_t kRecent = 8;

  /// true: run the next step on several threads; false: on one.
  bool threaded() const { return probing_ ? !threaded_ : threaded_; }
  /// The wall time (s) of the step just run in the mode threaded() gave.
  void record(double seconds);

  /// Steps run threaded and on one thread so far.
  std::size_t threadedSteps() const { return steps_[1]; }
  std::size_t singleSteps() const { return steps_[0]; }

 private:
  struct Recent {
    std::array<double, kRecent> seconds{};
    std::size_t count = 0;  // samples recorded (the ring holds the last kRecent)
    void add(double s) { seconds[count++ % kRecent] = s; }
    /// Median of the remembered samples; 0 when there are none.
    double median() const;
  };

  bool threaded_ = true;  // the mode in use (starts threaded: what was asked for)
  bool probing_ = false;  // the step being run is a probe of the other mode
  int interval_ = kFirstProbe;
  int sinceProbe_ = 0;
  std::array<Recent, 2> recent_;  // [0] one thread, [1] threaded
  std::array<std::size_t, 2> steps_{};
};

}  // namespace deformable_flsm
