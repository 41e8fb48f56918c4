/// @file bench_solver_implicit.h
/// bench_solver's tables of the implicit step (included by bench_solver.cpp only): the implicit
/// step against the explicit step on a drop, the node's demo with the implicit step, and the
/// bunny's sway after a poke at each scheme and step.
#pragma once

#include "deformable_flsm/core/lattice.h"
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/resolution.h"
#include "deformable_flsm/core/solver.h"
#include "support/params.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <complex>
#include <cstdio>
#include <ctime>
#include <memory>
#include <vector>

namespace deformable_flsm {
namespace bench {

/// The voxelization whose particle count is nearest to `target`.
inline Voxelization voxelizeNear(const TriMesh& mesh, std::size_t target) {
  return nearestResolution(mesh, target).voxels;
}

/// The fewest sub-steps of a 1/60 s step at which the explicit step takes the material uncapped
/// (at most kMaxSubsteps); `p` otherwise as given.
inline int substepsNeeded(const std::shared_ptr<const Lattice>& lattice, SolverParams p) {
  constexpr int kMaxSubsteps = 1000;
  p.integrator = Integrator::Explicit;
  int lo = 1, hi = kMaxSubsteps;  // hi: uncapped
  while (lo < hi) {
    const int mid = (lo + hi) / 2;
    p.substeps = mid;
    if (Solver(lattice, p).stiffnessSaturated())
      lo = mid + 1;
    else
      hi = mid;
  }
  return lo;
}

/// A drop: the object 2 cm above a ground plane, stepped for `seconds`; wall time per particle per
/// step (ns) and the implicit step's CG iterations per step (mean, largest).
struct DropRun {
  double ns = 0.0, cpuNs = 0.0, meanIterations = 0.0;
  int maxIterations = 0;
};

/// A ground plane 2 cm below the solver's lowest contact sphere, set as collider "ground".
inline void setGroundBelow(Solver& s) {
  double lowest = s.positions()[0].z();
  for (const auto& x : s.positions()) lowest = std::min(lowest, x.z());
  Collider ground;
  ground.shape.type = ColliderType::HalfSpace;
  ground.pose.translation() = Eigen::Vector3d(0, 0, lowest - s.contactRadius() - 0.02);
  s.setCollider("ground", ground);
}

inline DropRun drop(const std::shared_ptr<const Lattice>& lattice, const SolverParams& p, double seconds) {
  Solver s(lattice, p);
  setGroundBelow(s);
  const int steps = static_cast<int>(std::lround(seconds / p.timeStep));
  DropRun out;
  long total = 0;
  const auto t0 = std::chrono::steady_clock::now();
  const std::clock_t c0 = std::clock();
  for (int i = 0; i < steps; ++i) {
    s.step();
    total += s.lastImplicitSolve().iterations;
    out.maxIterations = std::max(out.maxIterations, s.lastImplicitSolve().iterations);
  }
  const double ns = std::chrono::duration<double, std::nano>(std::chrono::steady_clock::now() - t0).count();
  out.ns = ns / (double(steps) * double(lattice->size()));
  out.cpuNs = 1e9 * double(std::clock() - c0) / CLOCKS_PER_SEC / (double(steps) * double(lattice->size()));
  out.meanIterations = double(total) / steps;
  return out;
}

/// The implicit step against the explicit step at the sub-steps it needs, per modulus, on the
/// bunny at `particles` and a quarter of it (w, the moduli; `implicitAlone`: no explicit runs).
inline void implicitTable(const TriMesh& mesh, std::size_t particles, int w, const std::vector<double>& moduli,
                          bool implicitAlone) {
  std::printf("\nimplicit (1 sub-step) against explicit (the sub-steps it needs for the material), nu 0.3, w %d,\n"
              "single thread, a drop of 2 cm onto a plane and 2 s of settling; ns per particle per 1/60 s step,\n"
              "wall clock and CPU time (the process's: on a loaded machine the wall clock counts the waits too)\n"
              "%10s %10s %8s %14s %14s %8s %12s %12s %8s %8s %7s\n",
              w, "particles", "E (Pa)", "exp sub", "explicit ns/p", "implicit ns/p", "exp/imp",
              "exp cpu ns/p", "imp cpu ns/p", "cpu e/i", "CG mean", "CG max");
  for (std::size_t target : {particles / 4, particles}) {
    const Voxelization vox = voxelizeNear(mesh, target);
    auto lattice = std::make_shared<const Lattice>(vox, 1000.0, w);
    for (double E : moduli) {
      const SolverParams p = test::physicalParams(E, 0.3, w, 1.0 / 60.0, 1, Integrator::Implicit);
      const DropRun imp = drop(lattice, p, 2.0);
      SolverParams e = p;
      e.integrator = Integrator::Explicit;
      e.substeps = substepsNeeded(lattice, p);
      const DropRun exp = implicitAlone ? DropRun() : drop(lattice, e, 2.0);
      std::printf("%10zu %10.3g %8d %14.1f %14.1f %8.2f %12.1f %12.1f %8.2f %8.1f %7d\n", lattice->size(), E, e.substeps,
                  exp.ns, imp.ns, exp.ns / imp.ns, exp.cpuNs, imp.cpuNs, exp.cpuNs / imp.cpuNs, imp.meanIterations,
                  imp.maxIterations);
    }
  }
}

/// The bunny's material in the demo and sway tables: E, nu 0, the node's region damping 10 and
/// ambient damping 0.5, steps of h in `substeps`.
inline SolverParams bunnyParams(int w, double E, Integrator integrator, double h, int substeps) {
  SolverParams p = test::physicalParams(E, 0.0, w, h, substeps, integrator);
  p.damping = 10.0;
  p.ambientDamping = 0.5;
  return p;
}

/// The node's demo on the ground (flsm_demo): the bunny upright, dropped 2 cm onto a ground plane
/// and left 2.5 s; the 6 particles nearest its top dragged (hard) round the demo's circle for 5 s,
/// the target moved at 20 Hz; released and left 2.5 s; poked sideways (an impulse of 0.6 object
/// sizes per second on the particles within a quarter of its size of the centre) and left 2.5 s;
/// pushed for 0.5 s and left 2 s more, in steps of h seconds (one sub-step each). Per phase: CPU
/// time per step (this thread's) and CG iterations per step (mean, largest).
inline void demoRow(const TriMesh& upright, std::size_t particles, int w, double E, double h) {
  const Voxelization vox = voxelizeNear(upright, particles);
  auto lattice = std::make_shared<const Lattice>(vox, 1000.0, w);
  Solver s(lattice, bunnyParams(w, E, Integrator::Implicit, h, 1));
  setGroundBelow(s);
  std::uint32_t top = 0;
  for (std::uint32_t k = 0; k < s.positions().size(); ++k)
    if (s.positions()[k].z() > s.positions()[top].z()) top = k;
  const auto threadCpu = [] {
    timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
  };
  std::printf("%10zu %3d %9.3g", lattice->size(), w, E);
  const auto stepsIn = [h](double seconds) { return std::max(1, static_cast<int>(std::lround(seconds / h))); };
  const auto phase = [&](double seconds, const auto& before) {
    const int steps = stepsIn(seconds);
    long total = 0;
    int most = 0;
    const double t0 = threadCpu();
    for (int i = 0; i < steps; ++i) {
      before(i);
      s.step();
      total += s.lastImplicitSolve().iterations;
      most = std::max(most, s.lastImplicitSolve().iterations);
    }
    std::printf(" %8.2f %5.1f %4d", 1e3 * (threadCpu() - t0) / steps, double(total) / steps, most);
  };
  const auto nothing = [](int) {};
  phase(2.5, nothing);
  Eigen::Vector3d lo = s.positions()[0], hi = lo, centre = Eigen::Vector3d::Zero();
  for (const auto& x : s.positions()) {
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
    centre += x;
  }
  centre /= double(s.positions().size());
  const double size = (hi - lo).norm();
  const Eigen::Vector3d start = s.positions()[top];
  s.grab("ear", s.nearestParticles(start, 6), start, 0.0);
  const double radius = 0.12 * size;
  const int dragSteps = stepsIn(5.0), every = stepsIn(0.05);  // the target moved at 20 Hz
  phase(5.0, [&](int i) {
    if (i % every != 0) return;
    const double phi = 2.0 * M_PI * i / dragSteps;
    s.moveDrag("ear", start + Eigen::Vector3d(radius * std::sin(phi), 0.5 * radius * (1.0 - std::cos(phi)),
                                              0.5 * radius * std::sin(phi)));
  });
  s.release("ear");
  phase(2.5, nothing);
  const std::vector<std::uint32_t> body = s.particlesWithin(centre, 0.25 * size);
  const double sphereMass = 1000.0 * 4.0 / 3.0 * M_PI * std::pow(0.25 * size, 3);
  s.applyImpulse(body, Eigen::Vector3d(0.6 * size * sphereMass, 0, 0));
  phase(2.5, nothing);
  s.applyForce(body, Eigen::Vector3d(0, -4.0 * size * sphereMass, 0), 0.5);
  phase(2.5, nothing);
  std::printf("\n");
}

/// The bunny file is Y-up: turned about x so that it stands, as the node's default mesh_rpy does.
inline TriMesh standing(const TriMesh& mesh) {
  TriMesh upright = mesh;
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.5 * M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (auto& v : upright.vertices) v = R * v;
  return upright;
}

inline void demoTable(const TriMesh& mesh, std::size_t particles, double h) {
  const TriMesh upright = standing(mesh);
  std::printf("\nimplicit, the node's demo on the ground (nu 0, region damping 10, ambient damping 0.5, one sub-step\n"
              "of 1/%.4g s, single thread): dropped and settled, dragged round the demo's circle, released, poked,\n"
              "pushed; per phase CPU ms per step, CG iterations per step (mean, largest)\n"
              "%10s %3s %9s %19s %19s %19s %19s %19s\n", 1.0 / h, "particles", "w", "E (Pa)", "drop: ms  CG  max",
              "drag: ms  CG  max", "released", "poked", "pushed");
  for (std::size_t n : {particles / 4, particles})
    for (int w : {1, 2})
      for (double E : {30e3, 1e6}) demoRow(upright, n, w, E, h);
}

/// The amplitude a linear mode of angular frequency omega keeps per period under backward Euler
/// ((1 + (omega h)^2)^(-pi / (omega h))) or BDF2 (its characteristic root r of
/// (3/2 - i omega h) r^2 - 2 r + 1/2 = 0: |r|^(2 pi / arg r)), at omega h = z.
inline double schemeKeeps(ImplicitScheme scheme, double z) {
  if (scheme == ImplicitScheme::BackwardEuler) return std::pow(1.0 + z * z, -M_PI / z);
  const std::complex<double> a(1.5, -z), sq = std::sqrt(std::complex<double>(4.0, 0.0) - 2.0 * a);
  const std::complex<double> r1 = (2.0 + sq) / (2.0 * a), r2 = (2.0 - sq) / (2.0 * a);
  const std::complex<double> r = std::abs(r1) > std::abs(r2) ? r1 : r2;
  return std::pow(std::abs(r), 2.0 * M_PI / std::abs(std::arg(r)));
}

/// The bunny's sway after a poke, with every damping off (region, ambient; no gravity, no ground:
/// the material and the integrator alone): the 6 particles nearest its top, their mean
/// displacement along the poke in the object's frame (Solver::rigidFrame()) after each step, for
/// 1.5 s, fitted by least squares with a damped sinusoid A exp(-s t) cos(omega t + phi) + c (a
/// search over omega and s, the rest linear): the period 2 pi / omega and the amplitude kept per
/// period exp(-2 pi s / omega). Prints the row and returns the kept amplitude.
inline double swayRow(const TriMesh& upright, std::size_t particles, int w, double E, Integrator integrator,
               ImplicitScheme scheme, double h, int substeps, double reference) {
  const Voxelization vox = voxelizeNear(upright, particles);
  auto lattice = std::make_shared<const Lattice>(vox, 1000.0, w);
  SolverParams p = bunnyParams(w, E, integrator, h, substeps);
  p.damping = 0.0;
  p.ambientDamping = 0.0;
  p.gravity.setZero();
  p.implicitScheme = scheme;
  Solver s(lattice, p);
  Eigen::Vector3d lo = s.positions()[0], hi = lo, centre = Eigen::Vector3d::Zero();
  std::uint32_t top = 0;
  for (std::uint32_t k = 0; k < s.positions().size(); ++k) {
    const Eigen::Vector3d& x = s.positions()[k];
    lo = lo.cwiseMin(x);
    hi = hi.cwiseMax(x);
    centre += x;
    if (x.z() > s.positions()[top].z()) top = k;
  }
  centre /= double(s.positions().size());
  const double size = (hi - lo).norm();
  const std::vector<std::uint32_t> ear = s.nearestParticles(s.positions()[top], 6);
  const std::vector<std::uint32_t> body = s.particlesWithin(centre, 0.25 * size);
  const double sphereMass = 1000.0 * 4.0 / 3.0 * M_PI * std::pow(0.25 * size, 3);
  s.applyImpulse(body, Eigen::Vector3d(0.6 * size * sphereMass, 0, 0));
  const auto& x0 = lattice->restPositions();
  const auto sway = [&] {
    const Eigen::Isometry3d toRest = s.rigidFrame().inverse();
    double d = 0.0;
    for (std::uint32_t k : ear) d += (toRest * s.positions()[k] - x0[k]).x();
    return d / double(ear.size());
  };
  const int steps = static_cast<int>(std::lround(1.5 / h));
  std::vector<double> t(steps), d(steps);
  timespec t0, t1;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t0);
  for (int i = 0; i < steps; ++i) {
    s.step();
    t[i] = h * (i + 1);
    d[i] = sway();
  }
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t1);
  const double cpu = double(t1.tv_sec - t0.tv_sec) + 1e-9 * double(t1.tv_nsec - t0.tv_nsec);
  // the fit: for each (omega, s) the best A cos, B sin and c by linear least squares
  double best = std::numeric_limits<double>::infinity(), omega = 0.0, decay = 0.0;
  for (double om = 5.0; om <= 60.0; om += 0.05) {
    for (double sg = 0.0; sg <= 15.0; sg += 0.02) {
      Eigen::Matrix3d AtA = Eigen::Matrix3d::Zero();
      Eigen::Vector3d Atb = Eigen::Vector3d::Zero();
      for (int i = 0; i < steps; ++i) {
        const double e = std::exp(-sg * t[i]);
        const Eigen::Vector3d row(e * std::cos(om * t[i]), e * std::sin(om * t[i]), 1.0);
        AtA += row * row.transpose();
        Atb += row * d[i];
      }
      const Eigen::Vector3d c = AtA.ldlt().solve(Atb);
      double r = 0.0;
      for (int i = 0; i < steps; ++i) {
        const double e = std::exp(-sg * t[i]);
        const double f = c.x() * e * std::cos(om * t[i]) + c.y() * e * std::sin(om * t[i]) + c.z();
        r += (f - d[i]) * (f - d[i]);
      }
      if (r < best) {
        best = r;
        omega = om;
        decay = sg;
      }
    }
  }
  const double period = 2.0 * M_PI / omega;
  const double kept = std::exp(-decay * period);
  const double omegaH = omega * h / substeps;
  const bool implicit = integrator == Integrator::Implicit;
  std::printf("%10zu %3d %9.3g %15s %7.4f %9d %9.3f %9.3f %11.3f %12.3f %11.2f\n", lattice->size(), w, E,
              !implicit ? "explicit" : scheme == ImplicitScheme::Bdf2 ? "implicit bdf2" : "implicit BE", h, substeps,
              period, kept, implicit ? schemeKeeps(scheme, omegaH) : 1.0, reference > 0.0 ? kept / reference : 1.0,
              cpu / 1.5);
  return kept;
}

/// The sway of the implicit step at 1/240, 1/60 and 1/30 s against the explicit step at 80
/// sub-steps of 1/60 s (its own loss per period, to other modes, is the reference).
inline void swayTable(const TriMesh& mesh, std::size_t particles) {
  const TriMesh upright = standing(mesh);
  std::printf("\nthe bunny's sway after a poke, every damping off (nu 0, w = 2, 30 kPa): period (s), amplitude kept\n"
              "per period, what the scheme keeps of a linear mode at that period, kept over the explicit step's,\n"
              "CPU s per simulated s (one thread)\n"
              "%10s %3s %9s %15s %7s %9s %9s %9s %11s %12s %11s\n", "particles", "w", "E (Pa)", "step", "h (s)",
              "substeps", "period", "kept", "scheme's", "over explicit", "CPU s/s");
  constexpr auto BE = ImplicitScheme::BackwardEuler;
  constexpr auto BDF2 = ImplicitScheme::Bdf2;
  const double reference = swayRow(upright, particles, 2, 30e3, Integrator::Explicit, BE, 1.0 / 60.0, 80, 0.0);
  for (ImplicitScheme scheme : {BE, BDF2}) {
    swayRow(upright, particles, 2, 30e3, Integrator::Implicit, scheme, 1.0 / 60.0, 4, reference);
    swayRow(upright, particles, 2, 30e3, Integrator::Implicit, scheme, 1.0 / 60.0, 1, reference);
    swayRow(upright, particles, 2, 30e3, Integrator::Implicit, scheme, 1.0 / 30.0, 1, reference);
  }
}

}  // namespace bench
}  // namespace deformable_flsm
