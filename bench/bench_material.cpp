// Does the material mean what its parameters say? The dynamic solver, settled under a static load
// with damping, against the FEM oracle (linear hexahedra on the same voxels, see fem_oracle.h) and
// the analytic answers, for the load cases of linear elasticity a user would check:
//  - a cantilever (L/t = 8) under its own weight, 2 to 8 cells across, w = 1 to 3, 4 and 16
//    sub-steps per 1/60 s step: tip deflection;
//  - a column on a clamped base under its own weight: top displacement;
//  - a stubby cantilever (L/t = 2): tip deflection;
//  - a free bar pulled at both ends (uniaxial stress): axial strain against sigma / E and lateral
//    strain against -nu eps.
// Then the local cases (support/indentation.h), what a finger meets:
//  - a frictionless flat punch 5 cells wide pressed 2 mm into a 5 cm cube of 13 cells held by
//    its base: force against the oracle's on the same 5 x 5 cells;
//  - a frictionless sphere of radius 2 cm pressed 2 mm into a block 21 x 21 x 12 cells of 2.5 mm:
//    force against the axisymmetric FEM of the block (axisymmetric_press.h) and Hertz on a layer
//    bonded to its base (Dimitriadis et al. 2002),
// at 20 kPa, w = 1 to 3, the explicit step at 120 sub-steps of 1/30 s (not capped) and the
// implicit step at 4 (--local-only prints only these). --sphere-sweep prints the sphere against
// the FEM by its contact radius in cells (R 2 and 1 cm, 1 to 4 mm, two spacings) and nothing else.
// Loads are small (deflections ~1 % of the length), where linear elasticity is the reference.
// A benchmark: it prints figures and never fails.
//
// With --from-section each case runs with the regions regionHalfWidthForSection() chooses for the
// asked w on the case's measured thinnest section (core/section.h; the node's
// ~region_from_section); the column "w" is then the one used.
//
// --substeps N runs every case at N sub-steps only (default 4 and 16; 4 with --quick); --across N
// runs only the cantilevers N cells across (2, 4 or 8; 8 takes minutes and a gigabyte for its
// oracle).
//
// --integrator implicit prints, beside each explicit row, the same case with the implicit step
// (SolverParams::Integrator::Implicit) at one sub-step (or --substeps N); --modulus E gives every
// case the Young's modulus E (Pa) instead of the one that keeps the explicit step under its cap.
//
//   bench_material [--quick] [--nu NU] [--substeps N] [--across N] [--from-section]
//                  [--integrator explicit|implicit] [--modulus E] [--local-only] [--sphere-sweep]

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/section.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"
#include "support/fem_oracle.h"
#include "support/indentation.h"
#include "support/params.h"

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

constexpr double kDensity = 1000.0;  // kg/m^3
constexpr double kStep = 1.0 / 60.0;  // s per step
constexpr double kBig = 1e3;          // a box bound beyond the objects (m)
/// Simulated time to settle, in units of the case's 1 / omega_1 (--settle)
double gSettle = 10.0;
/// ... and at least this many steps: a stiff case's 10 / omega_1 is a step or two, too few for
/// the implicit step's conjugate gradients (stopped at a relative tolerance) to reach the static
/// answer, or for the explicit step's capped damping to remove the motion.
constexpr int kMinSettleSteps = 300;
/// --from-section: regions narrowed to the case's thinnest section
bool gFromSection = false;
/// --modulus: every case's Young's modulus (Pa); 0 for modulusFor()
double gModulus = 0.0;
/// The oracle splits each cell so that a bent section has at least this many elements across
/// (fully integrated hexahedra are within ~3 % of beam theory there, test_fem_oracle).
constexpr int kOracleElementsAcross = 8;

Voxelization box(int nx, int ny, int nz, double h, const Eigen::Vector3d& origin) {
  return boxVoxels(Eigen::Vector3i(nx, ny, nz), h, origin);
}

struct Setting {
  int w = 1;
  int substeps = 4;
  double nu = 0.0;
  Integrator integrator = Integrator::Explicit;
};

/// Young's modulus for a lattice of spacing h: alpha = 0.3 at w = 1, 4 sub-steps, nu = 0 (Pa), under
/// the cap for nu up to 0.3 (the cap softens a material by alpha / requested, and that is not
/// what this table is about).
double modulusFor(double h) {
  return gModulus > 0.0 ? gModulus : 0.3 * kDensity * h * h * 2.0 / (3.0 * std::pow(kStep / 4, 2));
}

/// The region half-width a case runs with: the asked one, or with --from-section the widest
/// regions no wider than the voxels' thinnest section.
int regionHalfWidthFor(const Setting& s, const Voxelization& vox) {
  return gFromSection ? regionHalfWidthForSection(measureSectionThickness(vox).thinnest, s.w) : s.w;
}

SolverParams paramsFor(const Setting& s, int w, double E, const Eigen::Vector3d& load, double settleRate) {
  SolverParams p = test::physicalParams(E, s.nu, w, kStep, s.substeps, s.integrator);
  p.density = kDensity;
  p.gravity = load;
  p.ambientDamping = settleRate;
  return p;
}

/// The implicit step's CG iterations per step over the last settle(): mean and largest.
double gMeanIterations = 0.0;
int gMaxIterations = 0;

/// Runs the solver for `seconds` of simulated time (at least kMinSettleSteps steps); returns the
/// largest particle speed at the end.
double settle(Solver& s, double seconds) {
  long total = 0;
  gMaxIterations = 0;
  const int steps = std::max(kMinSettleSteps, static_cast<int>(std::ceil(seconds / kStep)));
  for (int i = 0; i < steps; ++i) {
    s.step();
    total += s.lastImplicitSolve().iterations;
    gMaxIterations = std::max(gMaxIterations, s.lastImplicitSolve().iterations);
  }
  gMeanIterations = steps > 0 ? double(total) / steps : 0.0;
  double v = 0.0;
  for (const auto& vi : s.velocities()) v = std::max(v, vi.norm());
  return v;
}

struct Row {
  int w = 0;  // the region half-width used
  double lattice = 0.0, oracle = 0.0, alpha = 0.0, residualSpeed = 0.0;
  double settledScale = 0.0;  // what residualSpeed is compared with; 0: lattice (the lateral strain takes the axial)
  bool saturated = false;
  double meanIterations = 0.0;  // the implicit step's CG iterations per step, mean and largest
  int maxIterations = 0;
};

void print(const char* name, int across, const Setting& s, const Row& r, double scale) {
  char iterations[64] = "";
  if (s.integrator == Integrator::Implicit)
    std::snprintf(iterations, sizeof iterations, "  implicit, CG %.1f / %d", r.meanIterations, r.maxIterations);
  std::printf("%-12s %3d %2d %3d %5.2f %7.3f %12.4f %12.4f %8.3f%s%s%s\n", name, across, r.w, s.substeps, s.nu, r.alpha,
              scale * r.lattice, scale * r.oracle, r.lattice / r.oracle, iterations,
              r.saturated ? "  (alpha capped)" : "",
              std::abs(r.residualSpeed / (r.settledScale != 0.0 ? r.settledScale : r.lattice)) > 0.01 ? "  (not settled)"
                                                                                                       : "");
  if (std::getenv("FLSM_BENCH_RESIDUAL")) std::printf("   residual %.3g\n", r.residualSpeed / r.lattice);
}

/// Cantilever of section t x t (`across` cells), free length L, clamped over two cells; body load
/// small enough for a ~1 % tip deflection. Mean z displacement of the last cell layer.
Row cantilever(double t, double L, int across, const Setting& s) {
  const double h = t / across;
  const int along = static_cast<int>(std::lround(L / h));
  const Voxelization vox = box(along + 2, across, across, h, Eigen::Vector3d(-2 * h, 0, 0));
  const double E = modulusFor(h);
  const double g = 0.01 * L * E * t * t / (1.5 * kDensity * std::pow(L, 4));
  const double omega = analytic::cantileverFirstBendingFrequency(L, t, E, kDensity);
  const int w = regionHalfWidthFor(s, vox);
  const SolverParams p = paramsFor(s, w, E, Eigen::Vector3d(0, 0, -g), 2.0 * omega);
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, w);
  Solver solver(lattice, p);
  solver.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(0.0, kBig, kBig), true);
  Row r;
  r.residualSpeed = settle(solver, gSettle / omega) / omega;
  r.meanIterations = gMeanIterations;
  r.maxIterations = gMaxIterations;
  FemOracle fem(vox, FemMaterial{E, s.nu, kDensity}, std::max(2, kOracleElementsAcross / across));
  // supported where the lattice is: at the pinned particles (cell centres)
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(-0.5 * h + 1e-9, kBig, kBig));
  const FemSolution u = fem.solveStatic(p.gravity);
  int count = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i)
    if (lattice->restPositions()[i].x() > L - h) {
      r.lattice -= solver.positions()[i].z() - lattice->restPositions()[i].z();
      r.oracle -= u.cellDisplacements[i].z();
      ++count;
    }
  r.lattice /= count;
  r.oracle /= count;
  r.w = w;
  r.alpha = solver.alpha();
  r.saturated = solver.stiffnessSaturated();
  return r;
}

/// Column of `across` x `across` cells and height 4 t on a clamped base layer; top layer's mean
/// downward displacement under a small weight.
Row column(double t, int across, const Setting& s) {
  const double h = t / across;
  const int up = 4 * across;
  const Voxelization vox = box(across, across, up + 1, h, Eigen::Vector3d(0, 0, -h));
  const double E = modulusFor(h);
  const double H = up * h;
  const double g = 0.002 * 2.0 * E / (kDensity * H);  // top moves ~0.2 % of H
  const double omega = 0.5 * M_PI * std::sqrt(E / kDensity) / H;
  const int w = regionHalfWidthFor(s, vox);
  const SolverParams p = paramsFor(s, w, E, Eigen::Vector3d(0, 0, -g), 2.0 * omega);
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, w);
  Solver solver(lattice, p);
  solver.pinBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(kBig, kBig, 0.0), true);
  Row r;
  r.residualSpeed = settle(solver, gSettle / omega) / omega;
  r.meanIterations = gMeanIterations;
  r.maxIterations = gMaxIterations;
  FemOracle fem(vox, FemMaterial{E, s.nu, kDensity}, std::max(2, 4 / across));
  fem.fixNodesInBox(Eigen::Vector3d::Constant(-kBig), Eigen::Vector3d(kBig, kBig, -0.5 * h + 1e-9));
  const FemSolution u = fem.solveStatic(p.gravity);
  int count = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i)
    if (lattice->restPositions()[i].z() > H - h) {
      r.lattice -= solver.positions()[i].z() - lattice->restPositions()[i].z();
      r.oracle -= u.cellDisplacements[i].z();
      ++count;
    }
  r.lattice /= count;
  r.oracle /= count;
  r.w = w;
  r.alpha = solver.alpha();
  r.saturated = solver.stiffnessSaturated();
  return r;
}

/// Free bar 4t x t x t pulled by opposite forces on its end layers (uniaxial stress sigma):
/// axial and lateral strain of its middle half, against sigma / E and -nu sigma / E.
std::pair<Row, Row> stretch(double t, int across, const Setting& s) {
  const double h = t / across;
  const int along = 4 * across;
  const Voxelization vox = box(along, across, across, h, Eigen::Vector3d::Zero());
  const double E = modulusFor(h);
  const double eps = 0.002;
  const double F = eps * E * t * t;
  const double omega = M_PI * std::sqrt(E / kDensity) / (along * h);
  const int w = regionHalfWidthFor(s, vox);
  const SolverParams p = paramsFor(s, w, E, Eigen::Vector3d::Zero(), 2.0 * omega);
  auto lattice = std::make_shared<const Lattice>(vox, kDensity, w);
  Solver solver(lattice, p);
  std::vector<std::uint32_t> left, right;
  const auto& x0 = lattice->restPositions();
  for (std::uint32_t i = 0; i < lattice->size(); ++i) {
    if (x0[i].x() < h) left.push_back(i);
    if (x0[i].x() > (along - 1) * h) right.push_back(i);
  }
  solver.applyForce(left, Eigen::Vector3d(-F, 0, 0), 1e9);
  solver.applyForce(right, Eigen::Vector3d(F, 0, 0), 1e9);
  Row axial, lateral;
  axial.residualSpeed = lateral.residualSpeed = settle(solver, 1.2 * gSettle / omega) / omega / (4 * t);
  axial.meanIterations = lateral.meanIterations = gMeanIterations;
  axial.maxIterations = lateral.maxIterations = gMaxIterations;
  // middle half: mean x of the layers at 1/4 and 3/4 length; width from the side layers there
  const int i1 = along / 4, i2 = 3 * along / 4;
  double a1 = 0, a2 = 0, lo = 0, hi = 0;
  int n1 = 0, n2 = 0, nlo = 0, nhi = 0;
  for (std::size_t i = 0; i < lattice->size(); ++i) {
    const Eigen::Vector3i& c = lattice->cells()[i];
    const Eigen::Vector3d& x = solver.positions()[i];
    if (c.x() == i1) a1 += x.x(), ++n1;
    if (c.x() == i2) a2 += x.x(), ++n2;
    if (c.x() >= i1 && c.x() <= i2) {
      if (c.y() == 0) lo += x.y(), ++nlo;
      if (c.y() == across - 1) hi += x.y(), ++nhi;
    }
  }
  const double restLength = (i2 - i1) * h, restWidth = (across - 1) * h;
  axial.lattice = (a2 / n2 - a1 / n1) / restLength - 1.0;
  axial.oracle = F / (t * t * E);
  lateral.lattice = (hi / nhi - lo / nlo) / restWidth - 1.0;
  lateral.oracle = analytic::uniaxialLateralStrain(axial.oracle, s.nu);
  lateral.settledScale = axial.lattice;  // at nu = 0 the lateral strain is round-off
  axial.w = lateral.w = w;
  axial.alpha = lateral.alpha = solver.alpha();
  axial.saturated = lateral.saturated = solver.stiffnessSaturated();
  return {axial, lateral};
}

}  // namespace

namespace {

/// The local cases (see the top of this file), one row per w and integrator.
void printLocalCases(const std::vector<double>& nus) {
  namespace ind = indentation;
  constexpr double kLocalModulus = 20000.0;
  std::printf("\nlocal cases: E %.0f Pa, frictionless indenters lowered over 0.5 s, held 1.5 s (force, N)\n",
              kLocalModulus);
  std::printf("%-12s %3s %2s %3s %5s %9s %12s %12s %8s\n", "case", "n", "w", "sub", "nu", "step", "lattice",
              "oracle", "ratio");
  const Voxelization cube = box(13, 13, 13, 0.05 / 13, Eigen::Vector3d(-0.025, -0.025, 0.0));
  const Voxelization slab = box(21, 21, 12, 0.0025, Eigen::Vector3d(-0.02625, -0.02625, 0.0));
  const double depth = 0.002, R = 0.02;
  for (double nu : nus) {
    const double punchOracle = ind::femPunch(cube, 5, depth, FemMaterial{kLocalModulus, nu, kDensity});
    const double hertz = analytic::hertzSphereOnBondedLayerForce(R, depth, 11.5 * 0.0025, kLocalModulus, nu);
    const double sphereOracle = ind::sphereOracle(slab, R, depth, FemMaterial{kLocalModulus, nu, kDensity});
    for (int w = 1; w <= 3; ++w)
      for (Integrator integrator : {Integrator::Explicit, Integrator::Implicit}) {
        ind::Press how;
        how.integrator = integrator;
        how.substeps = integrator == Integrator::Explicit ? 120 : 4;
        how.w = w;
        how.nu = nu;
        how.youngsModulus = kLocalModulus;
        const ind::PressResult punch = ind::press(cube, ind::punch(5, cube.spacing), ind::kPunchBottom, depth, how);
        const ind::PressResult sphere = ind::press(slab, ind::sphere(R), R, depth, how);
        std::printf("%-12s %3d %2d %3d %5.2f %9s %12.4f %12.4f %8.3f%s\n", "punch 5x5", 13, w, how.substeps, nu,
                    toString(integrator), punch.force, punchOracle, punch.force / punchOracle,
                    punch.saturated ? " capped" : "");
        std::printf("%-12s %3d %2d %3d %5.2f %9s %12.4f %12.4f %8.3f (of Hertz on the layer %.3f)%s\n", "sphere 2 mm",
                    21, w, how.substeps, nu, toString(integrator), sphere.force, sphereOracle,
                    sphere.force / sphereOracle, sphere.force / hertz, sphere.saturated ? " capped" : "");
      }
  }
}

/// The sphere against the axisymmetric FEM by its contact radius in cells (--sphere-sweep): R 2
/// and 1 cm pressed 1 to 4 mm into the same 5.25 x 5.25 x 3 cm block at two spacings, w = 1, the
/// implicit step at 4 sub-steps.
void printSphereSweep(const std::vector<double>& nus) {
  namespace ind = indentation;
  constexpr double kLocalModulus = 20000.0;
  std::printf("\nsphere by contact radius: E %.0f Pa, w = 1, implicit, 4 sub-steps (force, N)\n", kLocalModulus);
  std::printf("%6s %7s %5s %6s %11s %9s %10s %10s %8s\n", "R mm", "dx mm", "nu", "d mm", "a / dx", "contacts",
              "lattice", "FEM", "ratio");
  for (double R : {0.02, 0.01})
    for (double dx : {0.0025, 0.001875}) {
      const int n = static_cast<int>(std::lround(0.0525 / dx)) | 1, nz = static_cast<int>(std::lround(0.03 / dx));
      const Voxelization slab = box(n, n, nz, dx, Eigen::Vector3d(-0.5 * n * dx, -0.5 * n * dx, 0.0));
      for (double nu : nus)
        for (double depth = 0.001; depth < 0.00401; depth += 0.0005) {
          ind::Press how;
          how.nu = nu;
          how.youngsModulus = kLocalModulus;
          const ind::PressResult p = ind::press(slab, ind::sphere(R), R, depth, how);
          const double fem = ind::sphereOracle(slab, R, depth, FemMaterial{kLocalModulus, nu, kDensity});
          std::printf("%6.0f %7.3f %5.2f %6.2f %11.2f %9zu %10.4f %10.4f %8.3f\n", 1e3 * R, 1e3 * dx, nu, 1e3 * depth,
                      std::sqrt(R * depth) / dx, p.contacts, p.force, fem, p.force / fem);
        }
    }
}

}  // namespace

int main(int argc, char** argv) {
  bool quick = false, implicit = false, localOnly = false, sphereSweep = false;
  int onlySubsteps = 0, onlyAcross = 0;
  std::vector<double> nus = {0.0, 0.3};
  for (int a = 1; a < argc; ++a) {
    if (std::strcmp(argv[a], "--quick") == 0) quick = true;
    if (std::strcmp(argv[a], "--nu") == 0 && a + 1 < argc) nus = {std::atof(argv[++a])};
    if (std::strcmp(argv[a], "--settle") == 0 && a + 1 < argc) gSettle = std::atof(argv[++a]);
    if (std::strcmp(argv[a], "--from-section") == 0) gFromSection = true;
    if (std::strcmp(argv[a], "--substeps") == 0 && a + 1 < argc) onlySubsteps = std::atoi(argv[++a]);
    if (std::strcmp(argv[a], "--across") == 0 && a + 1 < argc) onlyAcross = std::atoi(argv[++a]);
    if (std::strcmp(argv[a], "--integrator") == 0 && a + 1 < argc) implicit = parseIntegrator(argv[++a]) == Integrator::Implicit;
    if (std::strcmp(argv[a], "--modulus") == 0 && a + 1 < argc) gModulus = std::atof(argv[++a]);
    if (std::strcmp(argv[a], "--local-only") == 0) localOnly = true;
    if (std::strcmp(argv[a], "--sphere-sweep") == 0) sphereSweep = true;
  }
  if (sphereSweep) {
    printSphereSweep(nus);
    return 0;
  }
  if (localOnly) {
    printLocalCases(nus);
    return 0;
  }
  // each setting, and with --integrator implicit the same at implicitSubsteps with the implicit step
  const int implicitSubsteps = onlySubsteps > 0 ? onlySubsteps : 1;
  int firstSubsteps = 0;  // set below: the implicit rows go beside the first explicit ones
  auto settings = [&](int w, int sub, double nu) {
    std::vector<Setting> out{Setting{w, sub, nu, Integrator::Explicit}};
    if (implicit && sub == firstSubsteps) out.push_back(Setting{w, implicitSubsteps, nu, Integrator::Implicit});
    return out;
  };
  const std::vector<int> substeps = onlySubsteps > 0 ? std::vector<int>{onlySubsteps}
                                    : quick          ? std::vector<int>{4}
                                                     : std::vector<int>{4, 16};
  firstSubsteps = substeps.front();
  if (gModulus > 0.0) std::printf("E = %g Pa for every case\n", gModulus);
  std::printf("lattice = the settled solver, oracle = FEM on the same voxels (cantilever, column) or the\n"
              "analytic uniaxial-stress strains (stretch); E chosen per lattice (alpha 0.3 at w 1, 4 sub-steps)\n%s\n",
              gFromSection ? "regions narrowed to each case's thinnest section (--from-section): w asked 1 to 3, "
                             "the column w is the one used\n"
                           : "");
  std::printf("%-12s %3s %2s %3s %5s %7s %12s %12s %8s\n", "case", "n", "w", "sub", "nu", "alpha", "lattice",
              "oracle", "ratio");
  for (double nu : nus) {
    const std::vector<int> sections = onlyAcross > 0 ? std::vector<int>{onlyAcross}
                                      : quick          ? std::vector<int>{2, 4}
                                                       : std::vector<int>{2, 4, 8};
    for (int across : sections)
      for (int w = 1; w <= 3; ++w)
        for (int sub : substeps) {
          // minutes of settling; 4 sub-steps show the trend
          if (across == 8 && sub == 16 && onlySubsteps == 0) continue;
          for (const Setting& s : settings(w, sub, nu))
            print("cantilever", across, s, cantilever(0.1, 0.8, across, s), 1e3);
        }
    if (onlyAcross > 0) continue;
    for (int w = 1; w <= 3; ++w)
      for (int sub : substeps) {
        for (const Setting& s : settings(w, sub, nu)) {
          print("stubby", 4, s, cantilever(0.2, 0.4, 4, s), 1e3);
          print("column", 4, s, column(0.1, 4, s), 1e3);
          const auto [axial, lateral] = stretch(0.1, 4, s);
          print("axial", 4, s, axial, 1e3);
          print("lateral", 4, s, lateral, 1e3);
          std::printf("%-12s %40s lateral/axial %.3f (nu %.2f)\n", "", "", lateral.lattice / axial.lattice, nu);
        }
      }
  }
  if (onlyAcross == 0) printLocalCases(nus);
  return 0;
}
