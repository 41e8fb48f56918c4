// Is the material independent of resolution and time step? A cantilever bar L x L/4 x L/4,
// clamped over its first eighth, sags under a uniform body load to rest; this prints the tip
// deflection across lattice resolutions and time steps, for
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

// The bar and its material. A step of 1/60 s resolves at most E ~ rho R^2 / h^2 (alpha <= 1),
// so a bar that is soft enough for 1/60 s sags far beyond Euler-Bernoulli's small-deflection
// regime under 9.81 m/s^2; the load is a lighter body acceleration instead, so that the
// reference is meaningful. Deflections scale linearly with it.
constexpr double kLength = 1.0;          // m
constexpr double kThickness = 0.25;      // m
constexpr double kDensity = 1000.0;      // kg/m^3
constexpr double kYoungsModulus = 2e4;   // Pa
constexpr double kRegionRadius = 0.125;  // m
constexpr double kLoad = 0.2;            // m/s^2, downwards
constexpr double kSettleTime = 40.0;     // s of simulated time to come to rest

struct Result {
  double deflection = 0.0;  // m, mean sag of the last eighth
  double alpha = 0.0;
  int w = 0;
  bool saturated = false;
};

Result sag(int resolution, double subStep, bool physical) {
  const double h = kLength / resolution;
  const int across = resolution / 4;
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
  p.regionHalfWidth = physical ? regionHalfWidthForRadius(kRegionRadius, h) : 2;
  p.youngsModulus = physical ? kYoungsModulus : 0.0;
  p.stiffness = 1.0;
  p.timeStep = subStep;
  p.substeps = 1;
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, p.regionHalfWidth);
  Solver s(lattice, p);
  s.pinBox(Eigen::Vector3d::Constant(-1.0), Eigen::Vector3d(kLength / 8.0, 1.0, 1.0), true);
  const int steps = static_cast<int>(std::lround(kSettleTime / subStep));
  for (int i = 0; i < steps; ++i) s.step();
  Result r;
  const auto& x0 = lattice->restPositions();
  int count = 0;
  for (std::size_t i = 0; i < x0.size(); ++i)
    if (x0[i].x() > kLength * 7.0 / 8.0) {
      r.deflection += x0[i].z() - s.positions()[i].z();
      ++count;
    }
  r.deflection /= count;
  r.alpha = s.alpha();
  r.w = p.regionHalfWidth;
  r.saturated = s.stiffnessSaturated();
  return r;
}

void table(const char* title, bool physical, const std::vector<int>& resolutions, const std::vector<double>& steps) {
  std::printf("\n%s\n%10s %10s %4s %8s %14s %10s\n", title, "resolution", "step (s)", "w", "alpha",
              "tip sag (mm)", "/ first");
  double first = 0.0;
  for (int res : resolutions)
    for (double dt : steps) {
      const Result r = sag(res, dt, physical);
      if (first == 0.0) first = r.deflection;
      std::printf("%10d %10s %4d %8.4f %14.3f %10.3f%s\n", res, ("1/" + std::to_string(std::lround(1.0 / dt))).c_str(),
                  r.w, r.alpha, 1e3 * r.deflection, r.deflection / first, r.saturated ? "  (alpha capped)" : "");
    }
}

}  // namespace

int main(int argc, char** argv) {
  const bool quick = argc > 1 && std::strcmp(argv[1], "--quick") == 0;
  const std::vector<int> resolutions = quick ? std::vector<int>{8, 16} : std::vector<int>{8, 12, 16, 24, 32};
  const std::vector<double> steps = quick ? std::vector<double>{1.0 / 60, 1.0 / 240}
                                          : std::vector<double>{1.0 / 60, 1.0 / 120, 1.0 / 240, 1.0 / 480};
  // Euler-Bernoulli, uniformly loaded cantilever of free length Lf: delta = q Lf^4 / (8 E I),
  // q = rho g t^2, I = t^4 / 12 (the sag is averaged over the last eighth: roughly its middle).
  const double free = kLength * 7.0 / 8.0;
  const double q = kDensity * kLoad * kThickness * kThickness;
  const double I = std::pow(kThickness, 4) / 12.0;
  const double at = free * 15.0 / 16.0 / free;  // x / Lf at the middle of the last eighth
  const double tip = q * std::pow(free, 4) / (8.0 * kYoungsModulus * I);
  const double eb = tip * at * at * (6.0 - 4.0 * at + at * at) / 3.0;
  std::printf("cantilever %.2g x %.2g x %.2g m, rho %.0f kg/m^3, load %.2g m/s^2, E %.3g Pa, region radius %.3g m\n",
              kLength, kThickness, kThickness, kDensity, kLoad, kYoungsModulus, kRegionRadius);
  std::printf("Euler-Bernoulli sag of the last eighth for this E: %.3f mm\n", 1e3 * eb);
  table("classic: alpha = 1, w = 2 cells -- across resolutions at 1/240 s", false, resolutions, {1.0 / 240});
  table("classic: alpha = 1, w = 2 cells -- across time steps at resolution 16", false, {16}, steps);
  table("physical: E and region radius -- across resolutions at 1/240 s", true, resolutions, {1.0 / 240});
  table("physical: E and region radius -- across time steps at resolution 16", true, {16}, steps);
  return 0;
}
