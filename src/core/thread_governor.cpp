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

void ThreadGovernor::record(double seconds) {
  const bool mode = threaded();
  ++steps_[mode ? 1 : 0];
  if (probing_) {
    probing_ = false;
    sinceProbe_ = 0;
    const double rival = recent_[threaded_ ? 1 : 0].median();
    recent_[mode ? 1 : 0].add(seconds);
    if (rival <= 0.0 || seconds < (1.0 - kSwitchMargin) * rival) {
      threaded_ = mode;  // the probe won: switch, and check the old mode again soon
      interval_ = kFirstProbe;
    } else {
      interval_ = std::min(2 * interval_, kLastProbe);
    }
    return;
  }
  Recent& mine = recent_[mode ? 1 : 0];
  const double usual = mine.median();
  mine.add(seconds);
  if (mine.count > kRecent / 2 && seconds > kChangeFactor * usual) interval_ = kFirstProbe;
  if (++sinceProbe_ >= interval_) probing_ = true;
}

}  // namespace deformable_flsm
