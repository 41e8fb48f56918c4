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
/// times a one-thread step. The governor keeps the last kRecent step times of each mode and runs
/// the mode whose median is lower. It opens by alternating the modes, one thread first, until
/// each has kMinSamples times (six steps), then takes the faster; from there on the other mode is
/// tried now and then (a probe) to keep its figure fresh: kFirstProbe steps apart, then twice as
/// far apart after every probe that does not change the choice (up to kLastProbe steps), so that
/// a mode that keeps losing costs less and less. Moving to the threads asks for a clear win
/// (kToThreadsMargin: a lucky step of a busy machine must not bring back a run of slow ones);
/// moving to one thread a small one (kToSingleMargin). A step much slower than its mode's recent
/// ones on the threads (another job started) brings the next probe of one thread forward.
///
/// Usage, per step: `bool t = g.threaded();` run the step on that many threads, then
/// `g.record(seconds)`. No allocation; not thread-safe (one per solver).
class ThreadGovernor {
 public:
  /// Steps between probes at first, and the longest interval between two probes.
  static constexpr int kFirstProbe = 8;
  static constexpr int kLastProbe = 256;
  /// The threads are chosen when their median step is this fraction shorter than one thread's;
  /// one thread when its median is this fraction shorter than the threads'.
  static constexpr double kToThreadsMargin = 0.2;
  static constexpr double kToSingleMargin = 0.05;
  /// A step this many times its mode's recent median brings the next probe forward.
  static constexpr double kChangeFactor = 2.0;
  /// Recent steps remembered per mode, and how many a mode needs before it can be chosen.
  static constexpr std::size_t kRecent = 8;
  static constexpr std::size_t kMinSamples = 3;

  /// true: run the next step on several threads; false: on one.
  bool threaded() const { return probing_ ? !threaded_ : threaded_; }
  /// The wall time (s) of the step just run in the mode threaded() gave.
  void record(double seconds);

  /// Steps run threaded and on one thread so far.
  std::size_t threadedSteps() const { return steps_[1]; }
  std::size_t singleSteps() const { return steps_[0]; }
  /// Median of the recent step times (s) of a mode; 0 before its first step.
  double recentSeconds(bool threaded) const { return recent_[threaded ? 1 : 0].median(); }

 private:
  struct Recent {
    std::array<double, kRecent> seconds{};
    std::size_t count = 0;  // samples recorded (the ring holds the last kRecent)
    void add(double s) { seconds[count++ % kRecent] = s; }
    /// Median of the remembered samples; 0 when there are none.
    double median() const;
  };

  /// true when mode `m`'s recent steps beat the other mode's by the margin moving to m asks.
  bool better(bool m) const;

  // The mode in use. One thread until the opening has shown the threads faster: the safe choice
  // (a step on a busy machine's threads can take several times as long; one on a quiet
  // machine's single thread at most as many times as there are threads).
  bool threaded_ = false;
  bool opening_ = true;   // the first steps, alternating the modes
  bool probing_ = false;  // the step being run is a probe of the other mode (or, in the
                          // opening, the threaded one of a pair)
  int interval_ = kFirstProbe;
  int sinceProbe_ = 0;
  std::array<Recent, 2> recent_;  // [0] one thread, [1] threaded
  std::array<std::size_t, 2> steps_{};
};

}  // namespace deformable_flsm
