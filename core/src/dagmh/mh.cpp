#include "cpvs/dagmh/mh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <string>

#include "cpvs/base/error.h"

namespace cpvs {

namespace {

bool contains(float lo, float hi, float v) { return lo <= v && v <= hi; }

// One node from its four children's intervals when no depth suits all four: the lower
// end that most children's intervals contain (ties: the lowest child), and the
// intersection of those that contain it, which are the children it covers.
[[gnu::noinline]] void combineApart(const float lo[4], const float hi[4], float& outLo, float& outHi, uint8_t& covered) {
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

Mh::Mh(TexelIntervals texels, std::vector<uint8_t> bottomHasFull) { rebuild(texels, std::move(bottomHasFull)); }

void Mh::rebuild(TexelIntervals& texels, std::vector<uint8_t> bottomHasFull) {
  const uint32_t side = texels.side;
  if (side == 0 || !std::has_single_bit(side)) throw InputError("an MH needs a power-of-two side, not " + std::to_string(side));
  CPVS_CHECK(texels.lo.size() == texels.texels() && texels.hi.size() == texels.texels());
  CPVS_CHECK(bottomHasFull.empty() || bottomHasFull.size() == texels.texels());
  if (levels_.size() != size_t(std::countr_zero(side)) + 1) levels_.clear();
  log2Side_ = std::countr_zero(side);
  levels_.resize(size_t(log2Side_) + 1);
  Level& bottom = levels_.back();
  // Swapped, not moved: a caller building tile after tile gets buffers of the same size
  // back, and no tile allocates (and faults in) its storage anew.
  std::swap(bottom.lo, texels.lo);
  std::swap(bottom.hi, texels.hi);
  texels.lo.resize(bottom.lo.size());
  texels.hi.resize(bottom.hi.size());
  // Texels store nothing below them: no flags to read (bottomHasFull, the roots of tiles,
  // is the exception).
  const bool texelsAtBottom = bottomHasFull.empty();
  if (texelsAtBottom)
    bottom.hasFull.assign(bottom.lo.size(), 0);
  else
    bottom.hasFull = std::move(bottomHasFull);
  std::atomic<bool> invalid{false};

  for (int l = log2Side_ - 1; l >= 0; --l) {
    const Level& below = levels_[size_t(l) + 1];
    Level& level = levels_[size_t(l)];
    const uint32_t n = side >> (log2Side_ - l), nb = n * 2;
    level.lo.resize(size_t(n) * n);
    level.hi.resize(size_t(n) * n);
    level.covered.resize(size_t(n) * n);
    level.hasFull.resize(size_t(n) * n);
    float* outLo = level.lo.data();
    float* outHi = level.hi.data();
    uint8_t* outCovered = level.covered.data();
    uint8_t* outHasFull = level.hasFull.data();
    const bool checkIntervals = l == log2Side_ - 1;
    const bool readFlags = !(checkIntervals && texelsAtBottom);
    tbb::parallel_for(tbb::blocked_range<uint32_t>(0, n, std::max(1u, 4096u / n)), [&](const auto& rows) {
      bool bad = false;
      for (uint32_t y = rows.begin(); y != rows.end(); ++y) {
        const float* lo0 = below.lo.data() + size_t(2 * y) * nb;
        const float* hi0 = below.hi.data() + size_t(2 * y) * nb;
        const uint8_t* f0 = below.hasFull.data() + size_t(2 * y) * nb;
        for (uint32_t x = 0; x < n; ++x) {
          const float lo[4] = {lo0[2 * x], lo0[2 * x + 1], lo0[nb + 2 * x], lo0[nb + 2 * x + 1]};
          const float hi[4] = {hi0[2 * x], hi0[2 * x + 1], hi0[nb + 2 * x], hi0[nb + 2 * x + 1]};
          if (checkIntervals)
            for (int c = 0; c < 4; ++c) bad |= !(std::isfinite(lo[c]) && std::isfinite(hi[c]) && lo[c] <= hi[c]);
          const size_t i = size_t(y) * n + x;
          // Mostly one depth suits all four children: they are all covered.
          const float gmin = std::max(std::max(lo[0], lo[1]), std::max(lo[2], lo[3]));
          const float gmax = std::min(std::min(hi[0], hi[1]), std::min(hi[2], hi[3]));
          uint8_t covered = 0xF;
          if (gmin <= gmax) {
            outLo[i] = gmin;
            outHi[i] = gmax;
          } else {
            combineApart(lo, hi, outLo[i], outHi[i], covered);
          }
          outCovered[i] = covered;
          bool any = covered != 0xF;
          if (readFlags) {
            const uint8_t f[4] = {f0[2 * x], f0[2 * x + 1], f0[nb + 2 * x], f0[nb + 2 * x + 1]};
            for (int c = 0; c < 4; ++c) any = any || (covered >> c & 1 && f[c]);
          }
          outHasFull[i] = any;
        }
      }
      if (bad) invalid = true;
    });
    if (invalid) break;
  }
  if (invalid || side == 1)
    for (size_t i = 0; i < bottom.lo.size(); ++i)
      if (!std::isfinite(bottom.lo[i]) || !std::isfinite(bottom.hi[i]) || bottom.lo[i] > bottom.hi[i])
          throw InputError("texel " + std::to_string(i % side) + "," + std::to_string(i / side) +
                         " has no valid depth interval [" + std::to_string(bottom.lo[i]) + ", " +
                         std::to_string(bottom.hi[i]) + "]");
}

float Mh::value(int level, uint64_t x, uint64_t y) const {
  const float lo = this->lo(level, x, y), hi = this->hi(level, x, y);
  const float m = 0.5f * lo + 0.5f * hi;
  return contains(lo, hi, m) ? m : lo;
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
