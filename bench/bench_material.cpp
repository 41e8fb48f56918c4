// Is the material independent of resolution and time step? A cantilever bar L x t x t, clamped
// over its first quarter, sags under a uniform body load to rest; this prints the tip deflection
// across lattice resolutions and time steps, for
//  - classic shape matching: alpha = 1 and a fixed region half-width w = 2 (cells), and
//  - physical parameters: Young's modulus E (Pa) and a region radius (m) (SolverParams docs),
// with Euler-Bernoulli's small-deflection answer delta = q L^4 / (8 E I) for reference.
// A benchmark: it prints figures and never fails.
//
//   bench_material [--quick]

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"

#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

// The material. A step of 1/60 s resolves at most E ~ rho R^2 / h^2 (alpha <= 1), so a bar soft
// enough for 1/60 s sags far beyond Euler-Bernoulli's small-deflection regime under 9.81 m/s^2;
// the load is a lighter body acceleration instead, so that the reference is meaningful.
// Deflections scale linearly with it.
constexpr double kLength = 1.0;          // m
constexpr double kDensity = 1000.0;      // kg/m^3
constexpr double kYoungsModulus = 2e4;   // Pa
constexpr double kLoad = 0.2;            // m/s^2, downwards
constexpr double kSettleTime = 40.0;     // s of simulated time to come to rest
constexpr double kClamp = 0.25;          // clamped fraction of the length
constexpr double kTip = 0.25;            // fraction of the length at the free end whose sag is measured

/// A bar of aspect L : t = `aspect` (t = L / aspect, a whole number of cells at every resolution
/// used) and shape-matching regions of the given radius.
struct Bar {
  const char* name;
  int aspect;
  double regionRadius;  // m
};

struct Result {
  double deflection = 0.0;  // m, mean sag of the tip quarter
  double alpha = 0.0;
  int w = 0;
  bool saturated = false;
};

Result sag(const Bar& bar, int resolution, double subStep, bool physical) {
  const double h = kLength / resolution;
  const int across = resolution / bar.aspect;
  Voxelization vox;
  vox.spacing = h;
  vox.dims = Eigen::Vector3i(resolution, across, across);
  for (int k = 0; k < across; ++k)
    for (int j = 0; j < across; ++j)
      for (int i = 0; i < resolution; ++i) {
        vox.cells.emplace_back(i, j, k);
        vox.fillFraction.push_back(1.0);
      }
  SolverParams p;
  p.density = kDensity;
  p.gravity = Eigen::Vector3d(0.0, 0.0, -kLoad);
  p.regionHalfWidth = physical ? regionHalfWidthForRadius(bar.regionRadius, h) : 2;
  p.youngsModulus = physical ? kYoungsModulus : 0.0;
  p.stiffness = 1.0;
  p.timeStep = subStep;
  p.substeps = 1;
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, p.regionHalfWidth);
  Solver s(lattice, p);
  // clamp and tip are whole cells at every resolution used (multiples of 4 cells along L)
  s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(kClamp * kLength, 1.0, 1.0), true);
  const int steps = static_cast<int>(std::lround(kSettleTime / subStep));
  for (int i = 0; i < steps; ++i) s.step();
  Result r;
  const auto& x0 = lattice->restPositions();
  int count = 0;
  for (std::size_t i = 0; i < x0.size(); ++i)
    if (x0[i].x() > (1.0 - kTip) * kLength) {
      r.deflection += x0[i].z() - s.positions()[i].z();
      ++count;
    }
  r.deflection /= count;
  r.alpha = s.alpha();
  r.w = p.regionHalfWidth;
  r.saturated = s.stiffnessSaturated();
  return r;
}

/// Euler-Bernoulli, uniformly loaded cantilever of free length Lf (Timoshenko & Gere):
/// y(x) = q x^2 (6 Lf^2 - 4 Lf x + x^2) / (24 E I), q = rho g t^2, I = t^4 / 12, averaged over the
/// measured tip interval (Simpson's rule, exact for this quartic).
double eulerBernoulli(const Bar& bar) {
  const double t = kLength / bar.aspect;
  const double Lf = (1.0 - kClamp) * kLength;
  const double q = kDensity * kLoad * t * t;
  const double I = std::pow(t, 4) / 12.0;
  auto y = [&](double x) { return q * x * x * (6.0 * Lf * Lf - 4.0 * Lf * x + x * x) / (24.0 * kYoungsModulus * I); };
  const double a = Lf - kTip * kLength, b = Lf;
  return (y(a) + 4.0 * y(0.5 * (a + b)) + y(b)) / 6.0;
}

void table(const Bar& bar, const char* title, bool physical, const std::vector<int>& resolutions,
           const std::vector<double>& steps) {
  std::printf("\n%s, %s\n%10s %10s %4s %8s %14s %10s %10s\n", bar.name, title, "resolution", "step (s)", "w",
              "alpha", "tip sag (mm)", "/ first", "/ E-B");
  double first = 0.0;
  const double eb = eulerBernoulli(bar);
  double lo = 1e300, hi = 0.0;
  for (int res : resolutions)
    for (double dt : steps) {
      const Result r = sag(bar, res, dt, physical);
      lo = std::min(lo, r.deflection);
      hi = std::max(hi, r.deflection);
      if (first == 0.0) first = r.deflection;
      std::printf("%10d %10s %4d %8.4f %14.3f %10.3f %10.3f%s\n", res,
                  ("1/" + std::to_string(std::lround(1.0 / dt))).c_str(), r.w, r.alpha, 1e3 * r.deflection,
                  r.deflection / first, r.deflection / eb, r.saturated ? "  (alpha capped)" : "");
    }
  std::printf("spread (max - min) / min: %.1f%%\n", 100.0 * (hi - lo) / lo);
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  const std::vector<int> resolutions = quick ? std::vector<int>{8, 16} : std::vector<int>{8, 12, 16, 24, 32};
  const std::vector<double> steps = quick ? std::vector<double>{1.0 / 60, 1.0 / 240}
                                          : std::vector<double>{1.0 / 60, 1.0 / 120, 1.0 / 240, 1.0 / 480};
  // The slender bar is only 2 cells thick at resolution 8, and its region radius is 1.5 cells at
  // resolution 12 (rounded to 2); the thick bar is >= 4 cells thick and its radius a whole number
  // of cells at every resolution listed.
  const Bar slender{"slender bar 1 x 0.25 x 0.25 m, region radius 0.125 m", 4, 0.125};
  const Bar thick{"thick bar 1 x 0.5 x 0.5 m, region radius 0.25 m", 2, 0.25};
  if (argc > 1 && std::strcmp(argv[1], "--resolutions") == 0) {  // the resolution table alone
    for (const Bar* bar : {&slender, &thick})
      table(*bar, "physical: E and region radius, across resolutions at 1/240 s", true, {8, 12, 16, 24, 32}, {1.0 / 240});
    return 0;
  }
  std::printf("cantilever clamped over its first quarter; rho %.0f kg/m^3, load %.2g m/s^2 down, E %.3g Pa\n",
              kDensity, kLoad, kYoungsModulus);
  std::printf("tip sag = mean sag of the last quarter after %.0f s; E-B = Euler-Bernoulli there\n", kSettleTime);
  for (const Bar* bar : {&slender, &thick}) {
    table(*bar, "classic: alpha = 1, w = 2 cells, across resolutions at 1/240 s", false, resolutions, {1.0 / 240});
    table(*bar, "classic: alpha = 1, w = 2 cells, across time steps at resolution 16", false, {16}, steps);
    table(*bar, "physical: E and region radius, across resolutions at 1/240 s", true, resolutions, {1.0 / 240});
    table(*bar, "physical: E and region radius, across time steps at resolution 16", true, {16}, steps);
  }
  return 0;
}
