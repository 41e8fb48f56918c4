/// @file window_sums.h
/// One sliding-window pass along an axis of the lattice: FastLSM's building block for region
/// sums (Rivers & James 2007, sec. 4), also used to count region memberships.
#pragma once

#include "deformable_flsm/core/lattice.h"

namespace deformable_flsm {

/// One sliding-window pass along `axis`: out_p = sum of in_q over the particles q of p's run with
/// |q - p| <= w along the axis (w = lattice.regionHalfWidth()). O(1) per particle and channel.
/// @param[in]  in   #P*K particle-major data
/// @param[in]  K    channels per particle (1, 3, 6, 12, 18 or 24)
/// @param[out] out  #P*K window sums (must not alias `in`)
/// @param[in]  threads  OpenMP threads splitting the runs (the result does not depend on it)
void windowPass(const Lattice& lattice, int axis, const double* in, int K, double* out, int threads = 1);

}  // namespace deformable_flsm
