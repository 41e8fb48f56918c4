#include "deformable_flsm/core/window_sums.h"

#include "sliding_window.h"

namespace deformable_flsm {

namespace {

/// One sliding-window pass over every run along `axis`, for a compile-time channel count.
template <int K>
void windowPassK(const Lattice& lattice, int axis, const double* in, double* out, int threads) {
  const auto& order = lattice.runOrder(axis);
  const auto& starts = lattice.runStarts(axis);
  const std::ptrdiff_t w = lattice.regionHalfWidth();
  const std::size_t runs = starts.size() - 1;
#pragma omp parallel for schedule(static) num_threads(threads) if (threads > 1)
  for (std::size_t q = 0; q < runs; ++q) {
    const std::uint32_t* run = order.data() + starts[q];
    const std::ptrdiff_t len = static_cast<std::ptrdiff_t>(starts[q + 1] - starts[q]);
    detail::slideRun<K>(in, out, len, w, [run](std::ptrdiff_t u) { return static_cast<std::ptrdiff_t>(run[u]); });
  }
}

}  // namespace

void windowPass(const Lattice& lattice, int axis, const double* in, int K, double* out, int threads) {
  detail::withChannels(K, [&](auto k) { windowPassK<decltype(k)::value>(lattice, axis, in, out, threads); });
}

}  // namespace deformable_flsm
