// splitmix64: a tiny PRNG with the same output on every platform and standard library
// (std:: distributions are implementation-defined), so that generated scenes and sample
// points are the same everywhere for a seed.
#pragma once

#include <cstdint>

namespace cpvs {

class SplitMix64 {
 public:
  explicit SplitMix64(uint64_t seed) : state_(seed) {}
  uint64_t next() {
    uint64_t z = (state_ += 0x9E3779B97F4A7C15ull);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
  }
  /// Uniform in [0, 1), 53 bits.
  double uniform01() { return double(next() >> 11) * 0x1.0p-53; }
  /// Uniform-enough integer in [lo, hi] (the modulo bias is irrelevant here).
  int range(int lo, int hi) { return lo + static_cast<int>(next() % static_cast<uint64_t>(hi - lo + 1)); }
  bool chance(int percent) { return range(0, 99) < percent; }

  /// The stream of item i of a seeded set: independent of the order items are drawn in,
  /// so that parallel sampling gives the same items as serial.
  static SplitMix64 forItem(uint64_t seed, uint64_t i) {
    SplitMix64 s(seed * 0x9E3779B97F4A7C15ull + i);
    s.next();
    return s;
  }

 private:
  uint64_t state_;
};

}  // namespace cpvs
