/// @file sleep_fixtures.h
/// What the tests of sleeping objects in a World share (test_sleeping_world,
/// test_sleeping_piles): the node's rest criterion with a hold of one's own.
#pragma once

#include "deformable_flsm/core/world.h"

namespace deformable_flsm {
namespace sleep_fixtures {

inline SleepParams sleepAfter(double hold) {
  SleepParams s;
  s.fraction = 2e-5;  // the node's rest (LoopSettings::restFraction)
  s.hold = hold;
  return s;
}

}  // namespace sleep_fixtures
}  // namespace deformable_flsm
