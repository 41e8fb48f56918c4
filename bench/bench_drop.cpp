// A block dropped tilted onto the ground, once per tilt: the largest kinetic energy over the run
// (looked at every step) against the energy of the fall, and the energy left at the end. A check
// of what a step's contact does with an impact; docs/method.md ("The implicit step", limits)
// gives the figures of the 10 MPa block at one sub-step of 1/30 s, the defaults here.
//
//   bench_drop [--modulus PA] [--nu NU] [--step S] [--substeps N] [--integrator implicit|explicit]
//              [--cells N] [--spacing M] [--height M] [--seconds S] [--tilts A,B,...]
//
// The block: N^3 cells of `spacing`, density 1000, regions of half-width 1, its lowest corner
// `height` above the ground after turning it by the tilt about (1, 1, 0); ground friction 0.6.
#include "deformable_flsm/core/collider.h"
#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/solver.h"
#include "deformable_flsm/core/voxelizer.h"
#include "support/params.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

using namespace deformable_flsm;

namespace {

struct Args {
  double modulus = 10e6, nu = 0.3, step = 1.0 / 30.0, spacing = 0.01, height = 0.06, seconds = 5.0;
  int substeps = 1, cells = 10;
  Integrator integrator = Integrator::Implicit;
  std::vector<double> tilts = {0.3, 0.4, 0.45, 0.5, 0.8};
};

[[noreturn]] void usage(const char* problem) {
  std::fprintf(stderr, "bench_drop: %s\n(see the comment at the top of bench/bench_drop.cpp)\n", problem);
  std::exit(2);
}

Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; i += 2) {
    const std::string k = argv[i];
    if (i + 1 >= argc) usage(("no value after " + k).c_str());
    const std::string v = argv[i + 1];
    if (k == "--modulus") a.modulus = std::atof(v.c_str());
    else if (k == "--nu") a.nu = std::atof(v.c_str());
    else if (k == "--step") a.step = std::atof(v.c_str());
    else if (k == "--substeps") a.substeps = std::atoi(v.c_str());
    else if (k == "--cells") a.cells = std::atoi(v.c_str());
    else if (k == "--spacing") a.spacing = std::atof(v.c_str());
    else if (k == "--height") a.height = std::atof(v.c_str());
    else if (k == "--seconds") a.seconds = std::atof(v.c_str());
    else if (k == "--integrator") {
      if (v == "implicit") a.integrator = Integrator::Implicit;
      else if (v == "explicit") a.integrator = Integrator::Explicit;
      else usage("--integrator is implicit or explicit");
    } else if (k == "--tilts") {
      a.tilts.clear();
      std::stringstream list(v);
      for (std::string t; std::getline(list, t, ',');) a.tilts.push_back(std::atof(t.c_str()));
    } else {
      usage(("unknown option " + k).c_str());
    }
  }
  if (a.cells < 2 || a.substeps < 1 || !(a.step > 0.0) || !(a.spacing > 0.0) || a.tilts.empty())
    usage("--cells >= 2, --substeps >= 1, --step and --spacing > 0, one tilt or more");
  return a;
}

std::shared_ptr<const Lattice> block(const Args& a) {
  return std::make_shared<const Lattice>(boxVoxels(Eigen::Vector3i::Constant(a.cells), a.spacing), 1000.0, 1);
}

}  // namespace

int main(int argc, char** argv) {
  const Args a = parse(argc, argv);
  const SolverParams p = test::physicalParams(a.modulus, a.nu, 1, a.step, a.substeps, a.integrator);
  const auto lattice = block(a);
  const int steps = static_cast<int>(std::lround(a.seconds / a.step));
  std::printf("block of %d^3 cells of %.3g m (%.3g kg), E %.3g Pa, nu %.2f, %s, %d sub-step(s) of %.4g s, "
              "dropped %.3g m\n",
              a.cells, a.spacing, lattice->totalMass(), a.modulus, a.nu,
              a.integrator == Integrator::Implicit ? "implicit" : "explicit", a.substeps, a.step / a.substeps,
              a.height);
  std::printf("%10s %12s %14s %10s %14s %12s\n", "tilt_rad", "fall_J", "peak_KE_J", "at_step", "final_KE_J",
              "peak/fall");
  for (double tilt : a.tilts) {
    Solver s(lattice, p);
    const Eigen::Matrix3d R = Eigen::AngleAxisd(tilt, Eigen::Vector3d(1, 1, 0).normalized()).toRotationMatrix();
    std::vector<Eigen::Vector3d> x = s.positions();
    for (auto& xi : x) xi = R * xi;
    double lowest = x.front().z();
    for (const auto& xi : x) lowest = std::min(lowest, xi.z());
    s.setPositions(x);
    Collider ground;
    ground.shape.type = ColliderType::HalfSpace;
    ground.pose.translation() = Eigen::Vector3d(0, 0, lowest - s.contactRadius() - a.height);
    s.setCollider("ground", ground);
    const double fall = lattice->totalMass() * 9.81 * a.height;
    double peak = 0.0;
    int at = 0;
    for (int i = 0; i < steps; ++i) {
      s.step();
      const double ke = s.kineticEnergy();
      if (ke > peak) {
        peak = ke;
        at = i;
      }
    }
    std::printf("%10.3f %12.4g %14.4g %10d %14.3g %12.3g\n", tilt, fall, peak, at, s.kineticEnergy(), peak / fall);
  }
  return 0;
}
