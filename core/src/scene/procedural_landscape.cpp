#include "cpvs/scene/procedural_landscape.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/base/split_mix64.h"

namespace cpvs {

namespace {

constexpr double kCell = 2.0, kRelief = 90.0, kBaseDepth = 10.0;

// Value noise: a random value per lattice point of each octave, smoothly interpolated.
class ValueNoise {
 public:
  ValueNoise(uint32_t seed, int octave) : seed_(uint64_t(seed) << 8 | uint64_t(octave)) {}
  double at(double x, double z) const {
    const double fx = std::floor(x), fz = std::floor(z);
    const int64_t ix = int64_t(fx), iz = int64_t(fz);
    const double tx = smooth(x - fx), tz = smooth(z - fz);
    const double a = lattice(ix, iz), b = lattice(ix + 1, iz), c = lattice(ix, iz + 1), d = lattice(ix + 1, iz + 1);
    return (a + (b - a) * tx) + ((c + (d - c) * tx) - (a + (b - a) * tx)) * tz;
  }

 private:
  static double smooth(double t) { return t * t * (3 - 2 * t); }
  double lattice(int64_t x, int64_t z) const {
    return SplitMix64::forItem(seed_, uint64_t(x) * 0x100000001B3ull ^ uint64_t(z)).uniform01() * 2 - 1;
  }
  uint64_t seed_;
};

}  // namespace

Scene makeFractalLandscape(int size, uint32_t seed) {
  if (size < 2 || size > 4096)
    throw InputError("landscape size " + std::to_string(size) + " is outside [2, 4096] cells");
  const int n = size + 1;  // vertices per side
  std::vector<double> height(size_t(n) * size_t(n));
  double lowest = 1e300;
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      // Six octaves, the first spanning the whole terrain in four hills a side.
      double h = 0, amplitude = 0.5, frequency = 4.0 / size;
      for (int o = 0; o < 6; ++o) {
        h += amplitude * ValueNoise(seed, o).at(i * frequency, j * frequency);
        amplitude *= 0.5;
        frequency *= 2;
      }
      height[size_t(j) * size_t(n) + size_t(i)] = (h * 0.5 + 0.5) * kRelief;
      lowest = std::min(lowest, height[size_t(j) * size_t(n) + size_t(i)]);
    }
  const double base = lowest - kBaseDepth;
  Scene s;
  auto top = [&](int i, int j) { return uint32_t(j * n + i); };
  auto bottom = [&](int i, int j) { return uint32_t(n * n + j * n + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) s.positions.push_back({i * kCell, height[size_t(j) * size_t(n) + size_t(i)], j * kCell});
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) s.positions.push_back({i * kCell, base, j * kCell});
  auto tri = [&](uint32_t a, uint32_t b, uint32_t c) { s.indices.insert(s.indices.end(), {a, b, c}); };
  for (int j = 0; j < size; ++j)
    for (int i = 0; i < size; ++i) {
      // Counter-clockwise seen from outside: up for the surface, down for the bottom.
      const uint32_t a = top(i, j), b = top(i + 1, j), c = top(i + 1, j + 1), d = top(i, j + 1);
      tri(a, c, b);
      tri(a, d, c);
      const uint32_t e = bottom(i, j), f = bottom(i + 1, j), g = bottom(i + 1, j + 1), h = bottom(i, j + 1);
      tri(e, f, g);
      tri(e, g, h);
    }
  for (int k = 0; k < size; ++k) {
    // The four skirts, each facing out of the terrain.
    tri(top(k, 0), top(k + 1, 0), bottom(k + 1, 0));  // -z
    tri(top(k, 0), bottom(k + 1, 0), bottom(k, 0));
    tri(top(k, size), bottom(k + 1, size), top(k + 1, size));  // +z
    tri(top(k, size), bottom(k, size), bottom(k + 1, size));
    tri(top(0, k), bottom(0, k + 1), top(0, k + 1));  // -x
    tri(top(0, k), bottom(0, k), bottom(0, k + 1));
    tri(top(size, k), top(size, k + 1), bottom(size, k + 1));  // +x
    tri(top(size, k), bottom(size, k + 1), bottom(size, k));
  }
  finalizeScene(s);
  s.name = "procedural-landscape";
  return s;
}

}  // namespace cpvs
