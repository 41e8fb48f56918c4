/// @file fast_summation.h
/// Region sums: FastLSM's separable sliding-window summation and the direct (naive) summation,
/// in one include (see the headers below for each part).
#pragma once

#include "deformable_flsm/core/naive_summer.h"
#include "deformable_flsm/core/region_summer.h"
#include "deformable_flsm/core/slice_stream_summer.h"
#include "deformable_flsm/core/window_sums.h"
