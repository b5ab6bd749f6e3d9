#include "cpvs/dagmh/mh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <string>

#include "cpvs/base/error.h"

namespace cpvs {

namespace {

bool contains(float lo, float hi, float v) { return lo <= v && v <= hi; }

// One node from its four children's intervals: which it covers and its own interval.
void combine(const float lo[4], const float hi[4], float& outLo, float& outHi, uint8_t& covered) {
  const float gmin = std::max(std::max(lo[0], lo[1]), std::max(lo[2], lo[3]));
  const float gmax = std::min(std::min(hi[0], hi[1]), std::min(hi[2], hi[3]));
  if (gmin <= gmax) {
    outLo = gmin;
    outHi = gmax;
    covered = 0xF;
    return;
  }
  // No depth suits all four: the lower end that most children's intervals contain (ties:
  // the lowest child), and the intersection of those that contain it.
  int best = 0, bestCount = 0;
  for (int c = 0; c < 4; ++c) {
    int count = 0;
    for (int o = 0; o < 4; ++o) count += contains(lo[o], hi[o], lo[c]);
    if (count > bestCount) {
      bestCount = count;
      best = c;
    }
  }
  const float v = lo[best];
  outLo = -3.4e38f;
  outHi = 3.4e38f;
  covered = 0;
  for (int c = 0; c < 4; ++c)
    if (contains(lo[c], hi[c], v)) {
      covered |= uint8_t(1u << c);
      outLo = std::max(outLo, lo[c]);
      outHi = std::min(outHi, hi[c]);
    }
}

}  // namespace

Mh::Mh(TexelIntervals texels, std::vector<uint8_t> bottomHasFull) {
  const uint32_t side = texels.side;
  if (side == 0 || !std::has_single_bit(side)) throw InputError("an MH needs a power-of-two side, not " + std::to_string(side));
  CPVS_CHECK(texels.lo.size() == texels.texels() && texels.hi.size() == texels.texels());
  CPVS_CHECK(bottomHasFull.empty() || bottomHasFull.size() == texels.texels());
  for (size_t i = 0; i < texels.texels(); ++i)
    if (!std::isfinite(texels.lo[i]) || !std::isfinite(texels.hi[i]) || texels.lo[i] > texels.hi[i])
      throw InputError("texel " + std::to_string(i % side) + "," + std::to_string(i / side) + " has no valid depth interval [" +
                       std::to_string(texels.lo[i]) + ", " + std::to_string(texels.hi[i]) + "]");
  log2Side_ = std::countr_zero(side);
  levels_.resize(size_t(log2Side_) + 1);
  Level& bottom = levels_.back();
  bottom.lo = std::move(texels.lo);
  bottom.hi = std::move(texels.hi);
  bottom.hasFull = bottomHasFull.empty() ? std::vector<uint8_t>(texels.texels(), 0) : std::move(bottomHasFull);

  for (int l = log2Side_ - 1; l >= 0; --l) {
    const Level& below = levels_[size_t(l) + 1];
    Level& level = levels_[size_t(l)];
    const uint32_t n = side >> (log2Side_ - l), nb = n * 2;
    level.lo.resize(size_t(n) * n);
    level.hi.resize(size_t(n) * n);
    level.covered.resize(size_t(n) * n);
    level.hasFull.resize(size_t(n) * n);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, std::max(1u, 4096u / n)), [&](const auto& rows) {
      for (uint32_t y = rows.begin(); y != rows.end(); ++y)
        for (uint32_t x = 0; x < n; ++x) {
          float lo[4], hi[4];
          bool childHasFull[4];
          for (uint32_t c = 0; c < 4; ++c) {
            const size_t b = size_t(2 * y + (c >> 1)) * nb + 2 * x + (c & 1);
            lo[c] = below.lo[b];
            hi[c] = below.hi[b];
            childHasFull[c] = below.hasFull[b] != 0;
          }
          const size_t i = size_t(y) * n + x;
          combine(lo, hi, level.lo[i], level.hi[i], level.covered[i]);
          bool any = level.covered[i] != 0xF;
          for (int c = 0; c < 4; ++c) any = any || (level.covered[i] >> c & 1 && childHasFull[c]);
          level.hasFull[i] = any;
        }
    });
  }
}

float Mh::value(int level, uint64_t x, uint64_t y) const {
  const float lo = this->lo(level, x, y), hi = this->hi(level, x, y);
  const float m = 0.5f * lo + 0.5f * hi;
  return contains(lo, hi, m) ? m : lo;
}

MhState Mh::state(int level, uint64_t x, uint64_t y) const {
  if (level == 0) return MhState::Full;
  const uint32_t c = mhChild(x, y, 0);
  if (!(covered(level - 1, x / 2, y / 2) >> c & 1)) return MhState::Full;
  return hasFull(level, x, y) ? MhState::Empty : MhState::Absent;
}

float Mh::lookup(uint64_t x, uint64_t y) const {
  float v = value(0, 0, 0);
  for (int l = 1; l <= log2Side_; ++l) {
    const int shift = log2Side_ - l;
    const MhState s = state(l, x >> shift, y >> shift);
    if (s == MhState::Absent) break;
    if (s == MhState::Full) v = value(l, x >> shift, y >> shift);
  }
  return v;
}

}  // namespace cpvs
