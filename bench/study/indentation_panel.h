/// @file indentation_panel.h
/// The indentation panel of the speed/accuracy study (flsm_study): every method that has a
/// force to read pressed by the bonded punch (study/indentation.h), against the FEM oracle;
/// indentation.csv.
#pragma once

#include "study/args.h"
#include "study/config.h"
#include "study/csv.h"
#include "study/indentation.h"
#include "study/peers.h"
#include "study/setting.h"

#include <cstdio>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace deformable_flsm {
namespace study {

inline const std::string kIndentationHeader =
    "scenario,method,resolution,substeps,particles,punch_cells,nu,force_N,oracle_N,force_vs_fem,blew_up,cpu_s_per_sim_s,"
    "ns_per_particle_step";
/// Block resolutions (cells along a side) of the indentation case.
inline const std::vector<int> kBlockResolutions = {9, 13, 17};

/// The sub-steps per 1/60 s frame each method runs the punch at: FastLSM's explicit step at the
/// fewest that leave alpha uncapped (a power of two) and twice that; the mass-spring lattice at
/// its fewest stable and four times that; the implicit steps at 1 and 4.
inline std::vector<int> punchSubsteps(const std::string& method, const Block& b, const Calibration& c, double nu) {
  if (method == "fastlsm") {
    int s = 1;
    while (s < 1024 && flsmCapped(b.lattice, punchSetting(b.voxels.dims.x(), s, nu), c)) s *= 2;
    return {s, 2 * s};
  }
  if (method == "mass-spring") {
    const int s = massSpringMinSubsteps(b.lattice, c, kBlockYoungsModulus, kPunchFrameStep);
    return {s, 4 * s};
  }
  return {1, 4};
}

/// Runs the indentation case with every selected method (not naive LSM, which gives FastLSM's
/// answer at a higher cost, nor the stress table's nu = 0 run, nor the legacy soft body, which
/// has no force to read) and writes <out>/indentation.csv
/// (with --methods, the other methods' rows kept). Returns false after printing why it could not.
template <typename Selected>
bool runIndentation(const Args& args, const Calibration& calib, const Selected& selected, bool subset) {
  const double nu = kStudyPoissonRatio;
  const std::vector<int> resolutions = args.quick ? std::vector<int>{9} : kBlockResolutions;
  std::printf("indentation: a bonded punch %.0f %% of the side pressed %.1f mm into a %.0f cm cube at E %.3g Pa, "
              "nu %.1f, against the FEM oracle on the same voxels\n",
              100 * kPunchWidthFraction, 1e3 * kPunchDepth, 100 * kBlockSize, kBlockYoungsModulus, nu);
  std::vector<std::string> lines;
  for (int n : resolutions) {
    const Block b = makeBlock(n);
    const double oracle = oraclePunchForce(b, kBlockYoungsModulus, nu);
    for (const std::string& method : kAllMethods) {
      if (method == "naive-lsm" || method == "fastlsm-nu0" || !selected(method)) continue;
      if (method == "bullet") {  // BulletVolumeMethod::grabForce()
        if (n == resolutions.front()) std::printf("  bullet: no force to read (position-based links): not in the panel\n");
        continue;
      }
      for (int sub : punchSubsteps(method, b, calib, nu)) {
        const auto m = makeMethod(method, b.lattice, punchSetting(n, sub, nu), calib);
        const PunchRecord r = runPunch(b, *m);
        const double ratio = r.force / oracle;
        std::printf("  %-17s res %3d sub %4d  %5zu particles  force %.4f N, oracle %.4f N: %+6.1f %%  %9.4f CPU s/sim-s\n",
                    method.c_str(), n, sub, b.lattice->size(), r.force, oracle, 100 * (ratio - 1), r.cpuPerSimSecond);
        std::ostringstream f;
        f << "punch," << method << ',' << n << ',' << sub << ',' << b.lattice->size() << ',' << b.punchCells << ',' << num(nu) << ','
          << num(r.force) << ',' << num(oracle) << ',' << num(ratio) << ',' << (r.blewUp ? 1 : 0) << ','
          << num(r.cpuPerSimSecond) << ','
          << num(1e9 * r.cpuPerSimSecond * kPunchFrameStep / (double(sub) * double(b.lattice->size())));
        lines.push_back(f.str());
      }
    }
  }
  return writeCsv(args.out + "/indentation.csv", kIndentationHeader, std::move(lines), subset, selected, kAllMethods,
                  CsvOrder::Method);
}

}  // namespace study
}  // namespace deformable_flsm
