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

[[noreturn]] void usage(const char* why) {
  std::fprintf(stderr, "fem_recording: %s\nusage: fem_recording --mesh FILE --spacing M --youngs PA --nu NU "
                       "[--depth M] [--punch-cells K] [--rate HZ] [--press S] [--hold S] [--noise F] [--seed N]\n",
               why);
  std::exit(2);
}

}  // namespace

int main(int argc, char** argv) {
  std::string mesh, markers;
  int squeeze = 0, markerEvery = 3, subdivision = 1;
  double markerNoise = 1e-5;
  double spacing = 0, youngs = 0, nu = -1, depth = 0.002, rate = 30, press = 1.0, hold = 0.5, noise = 0.02;
  int cells = 5;
  unsigned seed = 1;
  for (int i = 1; i < argc; i += 2) {
    if (i + 1 >= argc) usage("every option takes a value");
    const std::string key = argv[i];
    const char* v = argv[i + 1];
    if (key == "--mesh") mesh = v;
    else if (key == "--spacing") spacing = std::atof(v);
    else if (key == "--youngs") youngs = std::atof(v);
    else if (key == "--nu") nu = std::atof(v);
    else if (key == "--depth") depth = std::atof(v);
    else if (key == "--punch-cells") cells = std::atoi(v);
    else if (key == "--rate") rate = std::atof(v);
    else if (key == "--press") press = std::atof(v);
    else if (key == "--hold") hold = std::atof(v);
    else if (key == "--noise") noise = std::atof(v);
    else if (key == "--seed") seed = static_cast<unsigned>(std::atol(v));
    else if (key == "--squeeze") squeeze = std::atoi(v);
    else if (key == "--subdivision") subdivision = std::atoi(v);
    else if (key == "--markers") markers = v;
    else if (key == "--marker-every") markerEvery = std::atoi(v);
    else if (key == "--marker-noise") markerNoise = std::atof(v);
    else usage(("unknown option " + key).c_str());
  }
  if (mesh.empty() || !(spacing > 0) || !(youngs > 0) || !(nu >= 0 && nu < 0.5) || !(depth > 0) || cells < 1 ||
      !(rate > 0) || !(press > 0) || !(hold >= 0) || !(noise >= 0) || markerEvery < 1 || !(markerNoise >= 0) ||
      subdivision < 1)
    usage("--mesh, --spacing > 0, --youngs > 0 and 0 <= --nu < 0.5 are needed; the rest positive");
  try {
    VoxelizeOptions o;
    o.spacing = spacing;
    const Voxelization vox = voxelize(loadMesh(mesh), o);
    const double top = indentation::topOf(vox);
    // linear elastic: the force and the displacements are proportional to the depth
    FemOracle fem(vox, FemMaterial{youngs, nu, 1000.0}, subdivision);
    const double unit = 1e-3;
    double unitForce = 0.0;
    const FemSolution u =
        indentation::femPress(fem, vox, squeeze ? 1e3 : 0.5 * cells * vox.spacing + 1e-9, unit, unitForce);
    const double perMetre = unitForce / unit;
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss(0.0, noise * perMetre * depth);
    const int n = static_cast<int>(std::lround((2 * press + hold) * rate));
    if (squeeze)
      std::printf("# fem_recording: FEM squeeze (a plate over the top), E %g Pa, nu %g, depth %g m, noise %g, seed %u",
                  youngs, nu, depth, noise, seed);
    else
      std::printf("# fem_recording: FEM punch %d cells, E %g Pa, nu %g, depth %g m, noise %g, seed %u", cells,
                  youngs, nu, depth, noise, seed);
    if (subdivision > 1) std::printf(", %d elements per cell edge", subdivision);
    std::printf("\n");
    // the markers: side-face nodes in the middle third of the height
    std::vector<int> marked;
    const std::vector<Eigen::Vector3d>& nodes = fem.nodePositions();
    Eigen::Vector3d lo = nodes.front(), hi = nodes.front();
    for (const Eigen::Vector3d& x : nodes) lo = lo.cwiseMin(x), hi = hi.cwiseMax(x);
    for (int i = 0; i < static_cast<int>(nodes.size()); ++i) {
      const Eigen::Vector3d& x = nodes[i];
      const bool side = std::abs(x.x() - lo.x()) < 1e-9 || std::abs(x.x() - hi.x()) < 1e-9 ||
                        std::abs(x.y() - lo.y()) < 1e-9 || std::abs(x.y() - hi.y()) < 1e-9;
      if (side && x.z() > top / 3 - 1e-9 && x.z() < 2 * top / 3 + 1e-9) marked.push_back(i);
    }
    std::FILE* mf = markers.empty() ? nullptr : std::fopen(markers.c_str(), "w");
    if (!markers.empty() && !mf) throw std::runtime_error("cannot write " + markers);
    std::normal_distribution<double> jitter(0.0, markerNoise);
    if (mf) std::fprintf(mf, "# fem_recording: %zu side nodes, noise %g m\ntime,marker,x,y,z\n", marked.size(), markerNoise);
    std::printf("time,x,y,z,fx,fy,fz\n");
    for (int k = 0; k <= n; ++k) {
      const double t = k / rate;
      const double d = depth * std::min({1.0, t / press, std::max(0.0, (2 * press + hold - t) / press)});
      std::printf("%.6f,0,0,%.8f,0,0,%.6e\n", t, top - d, perMetre * d + gauss(rng));
      if (mf && k % markerEvery == 0) {
        for (std::size_t m = 0; m < marked.size(); ++m) {
          const Eigen::Vector3d x = nodes[marked[m]] + (d / unit) * u.nodeDisplacements[marked[m]];
          const double e = k == 0 ? 0.0 : 1.0;  // the rest exact
          std::fprintf(mf, "%.6f,%zu,%.8f,%.8f,%.8f\n", t, m, x.x() + e * jitter(rng), x.y() + e * jitter(rng),
                       x.z() + e * jitter(rng));
        }
      }
    }
    if (mf) std::fclose(mf);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fem_recording: %s\n", e.what());
    return 1;
  }
  return 0;
}
