#include "cpvs/dagmh/mh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
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

// Four nodes' children at once (GCC's vector types: SSE on any x86-64): rows lo0/hi0 and
// the row nb below them, eight children across.
typedef float F4 __attribute__((vector_size(16)));
typedef int32_t I4 __attribute__((vector_size(16)));

struct Quad {
  F4 lo, hi;       // each node's intersection of its children's intervals
  bool allSuit;    // every intersection is an interval: one depth suits all four children
  bool valid;      // every child's interval is finite and ordered
};

F4 load4(const float* p) {
  F4 v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

Quad quadOf(const float* lo0, const float* hi0, uint32_t nb) {
  const F4 a0 = load4(lo0), a1 = load4(lo0 + 4), b0 = load4(lo0 + nb), b1 = load4(lo0 + nb + 4);
  const F4 c0 = load4(hi0), c1 = load4(hi0 + 4), d0 = load4(hi0 + nb), d1 = load4(hi0 + nb + 4);
  // Children 0 and 1 of the four nodes (even and odd columns), row 0 then row 1.
  const F4 lo00 = __builtin_shufflevector(a0, a1, 0, 2, 4, 6), lo01 = __builtin_shufflevector(a0, a1, 1, 3, 5, 7);
  const F4 lo10 = __builtin_shufflevector(b0, b1, 0, 2, 4, 6), lo11 = __builtin_shufflevector(b0, b1, 1, 3, 5, 7);
  const F4 hi00 = __builtin_shufflevector(c0, c1, 0, 2, 4, 6), hi01 = __builtin_shufflevector(c0, c1, 1, 3, 5, 7);
  const F4 hi10 = __builtin_shufflevector(d0, d1, 0, 2, 4, 6), hi11 = __builtin_shufflevector(d0, d1, 1, 3, 5, 7);
  // std::max and std::min's choices on ties, lane by lane.
  auto max = [](F4 p, F4 q) { return p < q ? q : p; };
  auto min = [](F4 p, F4 q) { return q < p ? q : p; };
  Quad q;
  // The scalar path's order: max(max(c0, c1), max(c2, c3)).
  q.lo = max(max(lo00, lo01), max(lo10, lo11));
  q.hi = min(min(hi00, hi01), min(hi10, hi11));
  const I4 suit = q.lo <= q.hi;
  q.allSuit = (suit[0] & suit[1] & suit[2] & suit[3]) != 0;
  // Finite and ordered: |v| <= FLT_MAX is false for infinities and NaN.
  const F4 big = {3.4028235e38f, 3.4028235e38f, 3.4028235e38f, 3.4028235e38f};
  auto finite = [&](F4 v) { return (v <= big) & (v >= -big); };
  const I4 ok = finite(a0) & finite(a1) & finite(b0) & finite(b1) & finite(c0) & finite(c1) & finite(d0) & finite(d1) &
                (a0 <= c0) & (a1 <= c1) & (b0 <= d0) & (b1 <= d1);
  q.valid = (ok[0] & ok[1] & ok[2] & ok[3]) != 0;
  return q;
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
        const size_t row = size_t(y) * n;
        // Node x of this row from its four children.
        auto one = [&](uint32_t x) {
          const float lo[4] = {lo0[2 * x], lo0[2 * x + 1], lo0[nb + 2 * x], lo0[nb + 2 * x + 1]};
          const float hi[4] = {hi0[2 * x], hi0[2 * x + 1], hi0[nb + 2 * x], hi0[nb + 2 * x + 1]};
          if (checkIntervals)
            for (int c = 0; c < 4; ++c) bad |= !(std::isfinite(lo[c]) && std::isfinite(hi[c]) && lo[c] <= hi[c]);
          const size_t i = row + x;
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
        };
        // Four nodes at a time where one depth suits all their children, the same as one
        // at a time (maxima and minima are exact); a quad where it does not, node by node.
        uint32_t x = 0;
        for (; x + 4 <= n; x += 4) {
          const Quad q = quadOf(lo0 + 2 * x, hi0 + 2 * x, nb);
          if (!q.allSuit || (checkIntervals && !q.valid)) {
            for (uint32_t k = 0; k < 4; ++k) one(x + k);
            continue;
          }
          std::memcpy(outLo + row + x, &q.lo, sizeof q.lo);
          std::memcpy(outHi + row + x, &q.hi, sizeof q.hi);
          std::memset(outCovered + row + x, 0xF, 4);
          for (uint32_t k = 0; k < 4; ++k) {
            const uint32_t cx = 2 * (x + k);
            outHasFull[row + x + k] = readFlags && (f0[cx] | f0[cx + 1] | f0[nb + cx] | f0[nb + cx + 1]) != 0;
          }
        }
        for (; x < n; ++x) one(x);
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
