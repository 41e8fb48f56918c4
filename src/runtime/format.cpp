/// @file format.cpp
#include "deformable_flsm/runtime/format.h"

#include <cstdio>
#include <vector>

namespace deformable_flsm {

std::string vformatted(const char* format, va_list args) {
  va_list again;
  va_copy(again, args);
  const int n = std::vsnprintf(nullptr, 0, format, args);
  std::string out;
  if (n > 0) {
    std::vector<char> buffer(static_cast<std::size_t>(n) + 1);
    std::vsnprintf(buffer.data(), buffer.size(), format, again);
    out.assign(buffer.data(), static_cast<std::size_t>(n));
  }
  va_end(again);
  return out;
}

std::string formatted(const char* format, ...) {
  va_list args;
  va_start(args, format);
  std::string out = vformatted(format, args);
  va_end(args);
  return out;
}

}  // namespace deformable_flsm
