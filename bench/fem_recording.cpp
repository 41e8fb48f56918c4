// fem_recording: a recording of a poke made by an independent model, for the fit to recover the
// material from (docs/fit.md). The FEM oracle (test/support/fem_oracle.h, linear elastic, one
// hexahedron per lattice cell) presses a flat punch into a block held by its base: the punch is
// lowered to `depth` over `press` seconds, held, then raised over the same time; the force with
// Gaussian noise of `noise` times the largest force, seeded, is written as the fit's CSV (time,
// the tool's position, the force on the tool).
//
//   fem_recording --mesh block.obj --spacing 0.003846 --youngs 20000 --nu 0.3 [--depth 0.002]
//                 [--punch-cells 5] [--rate 30] [--press 1] [--hold 0.5] [--noise 0.02]
//                 [--seed 1] > recording.csv
//
// The punch's frame is its bottom face's centre: it starts on the block's top face, over the
// middle of the block (the scene's collider must be a box of the same footprint, its frame
// offset as in examples/fit/punch_scene.yaml).
#include "deformable_flsm/core/mesh.h"
#include "deformable_flsm/core/voxelizer.h"
#include "support/fem_oracle.h"
#include "support/indentation.h"

#include <cstdio>
#include <cstdlib>
#include <cstring>
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
  std::string mesh;
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
    else usage(("unknown option " + key).c_str());
  }
  if (mesh.empty() || !(spacing > 0) || !(youngs > 0) || !(nu >= 0 && nu < 0.5) || !(depth > 0) || cells < 1 ||
      !(rate > 0) || !(press > 0) || !(hold >= 0) || !(noise >= 0))
    usage("--mesh, --spacing > 0, --youngs > 0 and 0 <= --nu < 0.5 are needed; the rest positive");
  try {
    VoxelizeOptions o;
    o.spacing = spacing;
    const Voxelization vox = voxelize(loadMesh(mesh), o);
    const double top = indentation::topOf(vox);
    // linear elastic: the force is proportional to the depth
    const double perMetre = indentation::femPunch(vox, cells, 1e-3, FemMaterial{youngs, nu, 1000.0}) / 1e-3;
    std::mt19937 rng(seed);
    std::normal_distribution<double> gauss(0.0, noise * perMetre * depth);
    const int n = static_cast<int>(std::lround((2 * press + hold) * rate));
    std::printf("# fem_recording: FEM punch %d cells, E %g Pa, nu %g, depth %g m, noise %g, seed %u\n", cells,
                youngs, nu, depth, noise, seed);
    std::printf("time,x,y,z,fx,fy,fz\n");
    for (int k = 0; k <= n; ++k) {
      const double t = k / rate;
      const double d = depth * std::min({1.0, t / press, std::max(0.0, (2 * press + hold - t) / press)});
      std::printf("%.6f,0,0,%.8f,0,0,%.6e\n", t, top - d, perMetre * d + gauss(rng));
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "fem_recording: %s\n", e.what());
    return 1;
  }
  return 0;
}
