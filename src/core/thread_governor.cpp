#include "deformable_flsm/core/thread_governor.h"

#include <algorithm>

namespace deformable_flsm {

double ThreadGovernor::Recent::median() const {
  const std::size_t n = std::min(count, kRecent);
  if (n == 0) return 0.0;
  std::array<double, kRecent> sorted = seconds;
  std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.begin() + n);
  return sorted[n / 2];
}

bool ThreadGovernor::better(bool m) const {
  const Recent& mine = recent_[m ? 1 : 0];
  const Recent& rival = recent_[m ? 0 : 1];
  if (mine.count < kMinSamples || rival.count < kMinSamples) return false;
  const double margin = m ? kToThreadsMargin : kToSingleMargin;
  return mine.median() < (1.0 - margin) * rival.median();
}

void ThreadGovernor::record(double seconds) {
  const bool mode = threaded();
  ++steps_[mode ? 1 : 0];
  Recent& mine = recent_[mode ? 1 : 0];
  const double usual = mine.median();
  mine.add(seconds);
  if (opening_) {
    // Alternate until both modes have kMinSamples times, then run the faster one.
    if (recent_[0].count >= kMinSamples && recent_[1].count >= kMinSamples) {
      opening_ = false;
      probing_ = false;
      threaded_ = better(true);
      return;
    }
    probing_ = !probing_;
    return;
  }
  if (probing_) {
    probing_ = false;
    sinceProbe_ = 0;
    if (better(mode)) {
      threaded_ = mode;  // the probed mode wins: switch, and check the old one again soon
      interval_ = kFirstProbe;
    } else if (mine.count >= kMinSamples) {
      interval_ = std::min(2 * interval_, kLastProbe);
    }
    return;
  }
  // Another job started and took a core from the threads: look at one thread soon. (Slower
  // one-thread steps mean a busier machine, where threads would fare worse still.)
  if (threaded_ && mine.count > kRecent / 2 && seconds > kChangeFactor * usual) interval_ = kFirstProbe;
  if (better(!threaded_)) {  // this mode's recent steps fell behind the other's figure
    threaded_ = !threaded_;
    interval_ = kFirstProbe;
    sinceProbe_ = 0;
    return;
  }
  if (++sinceProbe_ >= interval_) probing_ = true;
}

}  // namespace deformable_flsm
