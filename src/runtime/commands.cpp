#include "deformable_flsm/runtime/commands.h"

#include <utility>

namespace deformable_flsm {

void CommandStats::setRejectHook(RejectHook hook) {
  std::lock_guard<std::mutex> lock(mutex_);
  hook_ = std::move(hook);
}

void CommandStats::accept() {
  std::lock_guard<std::mutex> lock(mutex_);
  ++counts_.accepted;
}

void CommandStats::reject(const std::string& reason, const std::string& detail) {
  reject(reason, detail, 1);
}

void CommandStats::reject(const std::string& reason, const std::string& detail, std::uint64_t count) {
  RejectHook hook;
  {
    std::lock_guard<std::mutex> lock(mutex_);
    counts_.rejected += count;
    counts_.rejectedByReason[reason] += count;
    counts_.lastRejection = detail;
    hook = hook_;
  }
  if (hook) hook(reason, detail);  // outside the lock: the hook may log, slowly
}

CommandStats::Counts CommandStats::counts() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return counts_;
}

}  // namespace deformable_flsm
