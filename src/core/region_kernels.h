/// @file region_kernels.h
/// The region pass's per-region work (private to the core): the rotation batch and the region
/// batch that feeds it, compiled as whole translation units for each SIMD level
/// (region_kernels.cpp). simd_dispatch.h's entries compile a kernel inlined into a function for
/// a wider level, which leaves the rotation batch and the region batch 1.5-1.7x slower than a
/// build for that level (docs/performance.md); a whole unit built with `-march=x86-64-v3` or
/// `-v4` matches it. The units see raw arrays only (no Eigen, no standard containers), so that
/// no inline function or template compiled for a wide level can stand in for the build's own
/// (CMakeLists.txt checks their objects for weak symbols and static initialisers); what they
/// cannot do in lanes goes to the fallbacks below, at the build's own level.
#pragma once

#include <cstddef>

namespace deformable_flsm {
namespace detail {

/// Newton converges quadratically: after a step of length |theta| the error left is about
/// c |theta|^2, with c of order one for a well-conditioned H. Stopping once c |theta|^2 is below
/// the tolerance (c taken as this margin) saves the iteration that would only confirm it.
constexpr double kQuadraticMargin = 100.0;
/// Relative tolerance for "H is positive semi-definite" (scaled by |A|): Newton's fixed point
/// must be a maximum of tr(R^T A), not a saddle; round-off of order 1e-12 |A| is not a saddle.
constexpr double kSaddleTolerance = 1e-9;

/// extractRotationBatch()'s work: `count` <= kRotationBatch row-major matrices at a + 9 i,
/// their unit quaternions at q + 4 i as (x, y, z, w) (Eigen::Quaterniond's coefficients), the
/// rotations into r + 9 i; Newton's angle tolerance `angleTolerance` (PolarOptions).
using RotationBatchKernel = void (*)(int count, const double* a, double* q, double* r, double angleTolerance);

/// What Solver::regionData() hands the region batch: regions [begin, end) of the pass, their
/// sums at sums + (r - begin) in, their results into out + (r - begin) outK (the region's
/// transform in channels 0..11, the damping field's u and w in 12..17 when `damping`).
struct RegionBatchArgs {
  std::size_t begin = 0, end = 0;
  int in = 0, outK = 0;
  bool damping = false;
  const double* sums = nullptr;
  const double* mass = nullptr;        ///< M_r, by region index
  const double* invMass = nullptr;     ///< 1 / M_r
  const double* weight = nullptr;      ///< the region's weight beta_r
  const double* restCenter = nullptr;  ///< c0_r, 3 doubles a region
  double* quat = nullptr;              ///< the region's rotation, 4 doubles (x, y, z, w) a region
  double* out = nullptr;
  double angleTolerance = 0.0;         ///< the rotations' Newton tolerance (PolarOptions)
  double inertiaRankTolerance = 0.0;   ///< kInertiaRankTolerance
};
using RegionBatchKernel = void (*)(const RegionBatchArgs& args);

/// a * a - c as the unit computes it: fused at a level with FMA (simd.h's probe, for the tests).
using ProbeKernel = double (*)(double a, double c);

/// The kernels at one level.
struct RegionKernels {
  RotationBatchKernel rotationBatch;
  RegionBatchKernel regionBatch;
  ProbeKernel fusedMultiplyAddProbe;
};

/// The kernels at simdLevel() (simd.h).
RegionKernels regionKernels();

/// The general rotation routine for a lane the batch hands over (polar.cpp, the build's level):
/// extractRotation() of row-major a from the warm start q (x, y, z, w), the rotation into r.
void extractRotationGeneral(const double* a, double* q, double* r);
/// omega = I^+ L for a lane whose inertia the lanes could not invert (solver.cpp): row-major I.
void solveInertiaGeneral(const double* I, const double* L, double* w);

// Each level's kernels (region_kernels.cpp): the build's own, and where simd_dispatch.h has
// entries for wider levels, x86-64-v3's and v4's.
void rotationBatchOwn(int count, const double* a, double* q, double* r, double angleTolerance);
void regionBatchOwn(const RegionBatchArgs& args);
double fusedMultiplyAddProbeOwn(double a, double c);
void rotationBatchV3(int count, const double* a, double* q, double* r, double angleTolerance);
void regionBatchV3(const RegionBatchArgs& args);
double fusedMultiplyAddProbeV3(double a, double c);
void rotationBatchV4(int count, const double* a, double* q, double* r, double angleTolerance);
void regionBatchV4(const RegionBatchArgs& args);
double fusedMultiplyAddProbeV4(double a, double c);

}  // namespace detail
}  // namespace deformable_flsm
