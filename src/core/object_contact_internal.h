// What the candidate list (object_contact_list.cpp) and the passes (object_contact.cpp) share.
#pragma once

#include <cstddef>

namespace deformable_flsm {
namespace object_contact {

/// Pairs are found closer than (r1 + r2)(1 + kContactMargin), and colliders within
/// r kContactMargin: a pair just apart at the end of the sub-step is in the solve, so that the
/// corrections of its neighbours cannot push it into each other unseen.
constexpr double kContactMargin = 0.25;

/// Grows a buffer's capacity to twice n when n exceeds it: a list whose size grows slowly (the
/// pairs of objects pressed together) allocates a few times only.
template <class V>
void reserveDoubling(V& v, std::size_t n) {
  if (n > v.capacity()) v.reserve(2 * n);
}

}  // namespace object_contact
}  // namespace deformable_flsm
