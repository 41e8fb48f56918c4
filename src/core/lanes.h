/// @file lanes.h
/// SIMD lanes for the core's per-region batches (private to the core): GCC/Clang vector types,
/// one region per lane, lowered to whatever width the target has (AVX-512: one register).
#pragma once

#include <cstdint>

namespace deformable_flsm {

/// Regions per batch (polar.h's kRotationBatch).
constexpr int kLanes = 8;
typedef double Lanes __attribute__((vector_size(kLanes * sizeof(double))));
/// A comparison's result per lane: -1 (all bits set) where true, 0 where false.
typedef std::int64_t LaneMask __attribute__((vector_size(kLanes * sizeof(std::int64_t))));

/// solveSymmetricPositive3() in every lane: H x = b for the symmetric H with the given upper
/// triangle. `positive` holds the lanes where every pivot of H's LDL^T factorisation exceeds
/// minPivot; x is the solution there and finite (a division by 1) in the other lanes. (Results
/// by reference: a vector returned by value changes the ABI between SIMD widths.)
inline void solveSymmetricPositive3(const Lanes& h00, const Lanes& h11, const Lanes& h22, const Lanes& h01,
                                    const Lanes& h02, const Lanes& h12, const Lanes b[3], const Lanes& minPivot,
                                    Lanes x[3], LaneMask& positive) {
  // adjugate (symmetric) and determinant by the first row's cofactors
  const Lanes d2 = h00 * h11 - h01 * h01;
  const Lanes c00 = h11 * h22 - h12 * h12;
  const Lanes c01 = h02 * h12 - h01 * h22;
  const Lanes c02 = h01 * h12 - h02 * h11;
  const Lanes d3 = h00 * c00 + h01 * c01 + h02 * c02;
  const Lanes c11 = h00 * h22 - h02 * h02;
  const Lanes c12 = h01 * h02 - h00 * h12;
  positive = (h00 > minPivot) & (d2 > minPivot * h00) & (d3 > minPivot * d2);
  const Lanes one = Lanes{} + 1.0;
  const Lanes inv = one / (positive ? d3 : one);
  x[0] = (c00 * b[0] + c01 * b[1] + c02 * b[2]) * inv;
  x[1] = (c01 * b[0] + c11 * b[1] + c12 * b[2]) * inv;
  x[2] = (c02 * b[0] + c12 * b[1] + d2 * b[2]) * inv;
}

}  // namespace deformable_flsm
