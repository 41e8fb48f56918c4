// fem_recording: a recording of a poke made by an independent model, for the fit to recover the
// material from (docs/fit.md). The FEM oracle (test/support/fem_oracle.h, linear elastic, one
// hexahedron per lattice cell) presses a block held by its base with a frictionless tool: a flat
// punch (`--punch-cells` wide) or a plate over the whole top (`--squeeze`). The tool is lowered to
// `depth` over `press` seconds, held, then raised over the same time; the force with Gaussian
// noise of `noise` times the largest force, seeded, is written as the fit's CSV (time, the tool's
// position, the force on the tool). `--markers FILE` also writes where points on the block's
// sides (the nodes of its four side faces in the middle third of its height) are, every
// `--marker-every` samples, with Gaussian noise of `--marker-noise` m: a tracked cloud
// (time, marker, x, y, z; the first time is the rest). The base is held up to half a cell, the
// centres of the lattice's bottom layer that a scene pins (with --subdivision 1 only its face:
// nodes lie on the cells' corners); `--subdivision` elements per cell edge (2: minutes).
//
//   fem_recording --mesh block.obj --spacing 0.003846 --youngs 20000 --nu 0.3 [--depth 0.002]
//                 [--punch-cells 5 | --squeeze 1] [--rate 30] [--press 1] [--hold 0.5]
//                 [--noise 0.02] [--seed 1] [--markers FILE --marker-every 3 --marker-noise 1e-5]
//                 [--subdivision 1]
//                 > recording.csv
//
// The tool's frame is its bottom face's centre: it starts on the block's top face, over the
// middle of the block (the scene's collider must be a box of the same footprint, its frame
// offset as in examples/fit/punch_scene.yaml).
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/voxelizer.h"
#include "support/fem_oracle.h"
#include "support/indentation.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <vector>
#include <random>
#include <stdexcept>
#include <string>

using namespace deformable_flsm;

namespace {

/// The command line (see the top comment).
struct Args {
  std::string mesh, markers;
  int squeeze = 0, markerEvery = 3, subdivision = 1;
  double markerNoise = 1e-5;
  double spacing = 0, youngs = 0, nu = -1, depth = 0.002, rate = 30, press = 1.0, hold = 0.5, noise = 0.02;
  int cells = 5;
  unsigned seed = 1;
};

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr, "fem_recording: %s\nusage: fem_recording --mesh FILE --spacing M --youngs PA --nu NU "
                       "[--depth M] [--punch-cells K] [--rate HZ] [--press S] [--hold S] [--noise F] [--seed N]\n",
               why);
  std::exit(2);
}

/// Reads the command line; prints the usage and exits on a wrong one.
Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; i += 2) {
    if (i + 1 >= argc) usage("every option takes a value");
    const std::string key = argv[i];
    const char* v = argv[i + 1];
    if (key == "--mesh") a.mesh = v;
    else if (key == "--spacing") a.spacing = std::atof(v);
    else if (key == "--youngs") a.youngs = std::atof(v);
    else if (key == "--nu") a.nu = std::atof(v);
    else if (key == "--depth") a.depth = std::atof(v);
    else if (key == "--punch-cells") a.cells = std::atoi(v);
    else if (key == "--rate") a.rate = std::atof(v);
    else if (key == "--press") a.press = std::atof(v);
    else if (key == "--hold") a.hold = std::atof(v);
    else if (key == "--noise") a.noise = std::atof(v);
    else if (key == "--seed") a.seed = static_cast<unsigned>(std::atol(v));
    else if (key == "--squeeze") a.squeeze = std::atoi(v);
    else if (key == "--subdivision") a.subdivision = std::atoi(v);
    else if (key == "--markers") a.markers = v;
    else if (key == "--marker-every") a.markerEvery = std::atoi(v);
    else if (key == "--marker-noise") a.markerNoise = std::atof(v);
    else usage(("unknown option " + key).c_str());
  }
  if (a.mesh.empty() || !(a.spacing > 0) || !(a.youngs > 0) || !(a.nu >= 0 && a.nu < 0.5) || !(a.depth > 0) ||
      a.cells < 1 || !(a.rate > 0) || !(a.press > 0) || !(a.hold >= 0) || !(a.noise >= 0) || a.markerEvery < 1 ||
      !(a.markerNoise >= 0) || a.subdivision < 1)
    usage("--mesh, --spacing > 0, --youngs > 0 and 0 <= --nu < 0.5 are needed; the rest positive");
  return a;
}

/// Prints the recording's first line: a comment saying what made it.
void printHeader(const Args& a) {
  if (a.squeeze)
    std::printf("# fem_recording: FEM squeeze (a plate over the top), E %g Pa, nu %g, depth %g m, noise %g, seed %u",
                a.youngs, a.nu, a.depth, a.noise, a.seed);
  else
    std::printf("# fem_recording: FEM punch %d cells, E %g Pa, nu %g, depth %g m, noise %g, seed %u", a.cells,
                a.youngs, a.nu, a.depth, a.noise, a.seed);
  if (a.subdivision > 1) std::printf(", %d elements per cell edge", a.subdivision);
  std::printf("\n");
}

/// The markers: the nodes of the block's side faces in the middle third of its height (`top`).
/// Prints nothing.
std::vector<int> sideNodes(const std::vector<Eigen::Vector3d>& nodes, double top) {
  std::vector<int> marked;
  Eigen::Vector3d lo = nodes.front(), hi = nodes.front();
  for (const Eigen::Vector3d& x : nodes) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
  for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
    const Eigen::Vector3d& x = nodes[i];
    const bool side = std::abs(x.x() - lo.x()) < 1e-9 || std::abs(x.x() - hi.x()) < 1e-9 ||
                      std::abs(x.y() - lo.y()) < 1e-9 || std::abs(x.y() - hi.y()) < 1e-9;
    if (side && x.z() > top / 3 - 1e-9 && x.z() < 2 * top / 3 + 1e-9) marked.push_back(i);
  }
  return marked;
}

/// Prints the fit's CSV (the tool's position and the noisy force at each sample) and writes the
/// markers' CSV to --markers if given. `u`: the displacements at depth `unit`, `perMetre`: the
/// force per metre of depth.
void writeSamples(const Args& a, const std::vector<Eigen::Vector3d>& nodes, const std::vector<int>& marked,
                  const FemSolution& u, double top, double unit, double perMetre, std::mt19937& rng,
                  std::normal_distribution<double>& gauss) {
  const int n = static_cast<int>(std::lround((2 * a.press + a.hold) * a.rate));
  std::FILE* mf = a.markers.empty() ? nullptr : std::fopen(a.markers.c_str(), "w");
  if (!a.markers.empty() && !mf) throw std::runtime_error("cannot write " + a.markers);
  std::normal_distribution<double> jitter(0.0, a.markerNoise);
  if (mf) std::fprintf(mf, "# fem_recording: %zu side nodes, noise %g m\ntime,marker,x,y,z\n", marked.size(), a.markerNoise);
  std::printf("time,x,y,z,fx,fy,fz\n");
  for (int k = 0; k <= n; ++k) {
    const double t = k / a.rate;
    const double d = a.depth * std::min({1.0, t / a.press, std::max(0.0, (2 * a.press + a.hold - t) / a.press)});
    std::printf("%.6f,0,0,%.8f,0,0,%.6e\n", t, top - d, perMetre * d + gauss(rng));
    if (mf && k % a.markerEvery == 0) {
      for (std::size_t m = 0; m < marked.size(); ++m) {
        const Eigen::Vector3d x = nodes[marked[m]] + (d / unit) * u.nodeDisplacements[marked[m]];
        const double e = k == 0 ? 0.0 : 1.0;  // the rest exact
        std::fprintf(mf, "%.6f,%zu,%.8f,%.8f,%.8f\n", t, m, x.x() + e * jitter(rng), x.y() + e * jitter(rng),
                     x.z() + e * jitter(rng));
      }
    }
  }
  if (mf) std::fclose(mf);
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse(argc, argv);
  try {
    VoxelizeOptions o;
    o.spacing = args.spacing;
    const Voxelization vox = voxelize(loadMesh(args.mesh), o);
    const double top = indentation::topOf(vox);
    // linear elastic: the force and the displacements are proportional to the depth
    FemOracle fem(vox, FemMaterial{args.youngs, args.nu, 1000.0}, args.subdivision);
    const double unit = 1e-3;
    double unitForce = 0.0;
    const FemSolution u =
        indentation::femPress(fem, vox, args.squeeze ? 1e3 : 0.5 * args.cells * vox.spacing + 1e-9, unit, unitForce);
    const double perMetre = unitForce / unit;
    std::mt19937 rng(args.seed);
    std::normal_distribution<double> gauss(0.0, args.noise * perMetre * args.depth);
    printHeader(args);
    // the markers: side-face nodes in the middle third of the height
    const std::vector<Eigen::Vector3d>& nodes = fem.nodePositions();
    const std::vector<int> marked = sideNodes(nodes, top);
    writeSamples(args, nodes, marked, u, top, unit, perMetre, rng, gauss);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fem_recording: %s\n", e.what());
    return 1;
  }
  return 0;
}
