/// @file contact_tally.h
/// Which colliders each particle of an object touched in the sub-step being taken, whichever
/// contact solver met it (the explicit pass, the implicit solve, the object contact): a wrench's
/// contacts are the particles marked here, each once per collider.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace deformable_flsm {

class ContactTally {
 public:
  /// Sized for the particles and colliders (outside a step: touch() allocates nothing).
  void resize(std::size_t particles, std::size_t colliders) {
    words_ = (colliders + 63) / 64;
    stamp_.assign(particles, 0);
    bits_.assign(particles * words_, 0);
    current_ = 1;
  }
  /// A new sub-step: no particle has touched anything in it yet.
  void beginSubstep() { ++current_; }
  /// Particle i touches collider c in this sub-step (again, or first). Particles are the
  /// caller's to share out between threads: i's entries are written by whoever holds i.
  void touch(std::size_t i, std::size_t c) {
    std::uint64_t* bits = bits_.data() + i * words_;
    if (stamp_[i] != current_) {
      stamp_[i] = current_;
      for (std::size_t w = 0; w < words_; ++w) bits[w] = 0;
    }
    bits[c / 64] |= std::uint64_t{1} << (c % 64);
  }
  /// Adds to counts[c] the particles that touched collider c in this sub-step.
  template <typename Count>
  void count(Count&& countOne) const {
    for (std::size_t i = 0; i < stamp_.size(); ++i) {
      if (stamp_[i] != current_) continue;
      for (std::size_t w = 0; w < words_; ++w)
        for (std::uint64_t b = bits_[i * words_ + w]; b != 0; b &= b - 1)
          countOne(w * 64 + static_cast<std::size_t>(__builtin_ctzll(b)));
    }
  }

 private:
  std::size_t words_ = 0;
  std::uint64_t current_ = 1;
  std::vector<std::uint64_t> stamp_, bits_;
};

}  // namespace deformable_flsm
