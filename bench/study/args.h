/// @file args.h
/// The command line of the speed/accuracy study (flsm_study) and the methods a run selects.
#pragma once

#include "deformable_flsm/core/mesh.h"
#include "study/config.h"

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <sstream>
#include <string>
#include <vector>

namespace deformable_flsm {
namespace study {

struct Args {
  std::string out = "docs/study";
  std::string mesh = deformable_flsm::kBunnyMeshPath;
  int repeats = 3;
  bool quick = false;
  bool bullet = true;
  /// methods to run (--methods); empty: all
  std::vector<std::string> methods;
  /// only the indentation case (--indentation)
  bool indentationOnly = false;
};

/// The names of a comma-separated list, each checked against kAllMethods.
inline std::vector<std::string> parseMethods(const std::string& list) {
  std::vector<std::string> out;
  std::stringstream in(list);
  std::string name;
  while (std::getline(in, name, ',')) {
    if (std::find(kAllMethods.begin(), kAllMethods.end(), name) == kAllMethods.end()) {
      std::string known;
      for (const auto& m : kAllMethods) known += " " + m;
      std::fprintf(stderr, "flsm_study: unknown method '%s' in --methods (known:%s)\n", name.c_str(), known.c_str());
      std::exit(2);
    }
    out.push_back(name);
  }
  if (out.empty()) {
    std::fprintf(stderr, "flsm_study: --methods needs at least one method name\n");
    std::exit(2);
  }
  return out;
}

inline Args parse(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string k = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "flsm_study: %s needs a value\n", k.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (k == "--out") a.out = value();
    else if (k == "--mesh") a.mesh = value();
    else if (k == "--repeats") a.repeats = std::max(1, std::atoi(value().c_str()));
    else if (k == "--quick") a.quick = true;
    else if (k == "--no-bullet") a.bullet = false;
    else if (k == "--methods") a.methods = parseMethods(value());
    else if (k == "--indentation") a.indentationOnly = true;
    else {
      std::fprintf(stderr, "flsm_study: unknown option %s\n"
                           "usage: flsm_study [--out DIR] [--mesh PATH] [--repeats N] [--quick] [--no-bullet] "
                           "[--methods LIST] [--indentation]\n",
                   k.c_str());
      std::exit(2);
    }
  }
  return a;
}

/// The methods of this run: all (the Bullet peers when built in), or those of --methods.
struct Selection {
  const Args& args;
  bool withBullet;
  bool subset;
  bool operator()(const std::string& m) const {
    if ((m == "bullet" || m == "bullet-fem") && !withBullet) return false;
    return !subset || std::find(args.methods.begin(), args.methods.end(), m) != args.methods.end();
  }
};

/// The selected methods of the accuracy runs (all but the stress table's "fastlsm-nu0").
inline std::vector<std::string> accuracyMethods(const Selection& selected) {
  std::vector<std::string> methods;  // of the accuracy runs
  for (const std::string& m : kAllMethods)
    if (m != "fastlsm-nu0" && selected(m)) methods.push_back(m);
  return methods;
}

}  // namespace study
}  // namespace deformable_flsm
