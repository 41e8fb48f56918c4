#include "deformable_flsm/core/region_summer.h"

namespace deformable_flsm {

void RegionSummer::gather(const std::vector<double>& in, int K, std::vector<double>& out) {
  out.resize(in.size());
  gather(in.data(), K, out.data());
}

void RegionSummer::scatter(const std::vector<double>& in, int K, std::vector<double>& out) {
  out.resize(in.size());
  scatter(in.data(), K, out.data());
}

}  // namespace deformable_flsm
