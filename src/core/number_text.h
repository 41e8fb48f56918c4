// A number in the core's error messages, as a stream prints it (shortest of 6 significant digits).
#pragma once

#include <sstream>
#include <string>

namespace deformable_flsm {

inline std::string numberText(double v) {
  std::ostringstream s;
  s << v;
  return s.str();
}

}  // namespace deformable_flsm
