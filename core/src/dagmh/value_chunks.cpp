#include "cpvs/dagmh/value_chunks.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>

#include "cpvs/base/error.h"
#include "dagmh/bit_count.h"

// Compiled with -ffp-contract=off: base + step * i must round as the decoder, the GPU
// (precise) and the encoder's own check round it.

namespace cpvs {

namespace {

// The largest factor a grid may use: float(i) is exact below 2^24, so base + step * i is
// one rounding of an exact product and sum.
constexpr uint32_t kMaxGridBits = 24;

float decodeFactor(const ValueChunk& c, uint32_t iv) {
  if (c.factorBits() == kRawFactorBits) return std::bit_cast<float>(iv);
  return c.base + c.step * float(iv);
}

bool contains(float lo, float hi, float v) { return lo <= v && v <= hi; }

float midpoint(float lo, float hi) {
  const float m = 0.5f * lo + 0.5f * hi;  // never overflows
  return contains(lo, hi, m) ? m : lo;
}

// The point most intervals contain: the middle of the intersection of those that contain
// the lowest-count-maximizing lower end (the maximal overlap always starts at a lower end).
float representativeOf(const float* lo, const float* hi, uint32_t n) {
  // Four intervals at a time (GCC's vector types: SSE on any x86-64), all 32 lanes, those
  // past n holding an interval no point lies in (finite intervals: no NaN). Maxima and
  // minima are exact, so the answer is the one-at-a-time loop's.
  typedef float F4 __attribute__((vector_size(16)));
  typedef int32_t I4 __attribute__((vector_size(16)));
  constexpr float kMax = std::numeric_limits<float>::max();
  constexpr uint32_t kGroups = kValuesPerChunk / 4;
  F4 l[kGroups], h[kGroups];
  for (uint32_t m = 0; m < kValuesPerChunk; ++m) {
    l[m / 4][m % 4] = m < n ? lo[m] : kMax;
    h[m / 4][m % 4] = m < n ? hi[m] : -kMax;
  }
  const F4 lowest = {-kMax, -kMax, -kMax, -kMax}, highest = {kMax, kMax, kMax, kMax};
  uint32_t best = 0;
  float bestLo = 0, bestHi = 0;
  for (uint32_t k = 0; k < n; ++k) {
    const float p = lo[k];
    // A lower end seen just before gives the same count and intersection, which never
    // replaces the best (p is not below the intersection's lower end): runs of equal
    // intervals are common.
    if (k > 0 && p == lo[k - 1]) continue;
    const F4 pv = {p, p, p, p};
    I4 in4 = {0, 0, 0, 0};
    F4 iLo4 = lowest, iHi4 = highest;
    for (uint32_t g = 0; g < kGroups; ++g) {
      const I4 in = (l[g] <= pv) & (pv <= h[g]);  // -1 where the interval holds p
      in4 -= in;
      const F4 a = in ? l[g] : lowest, b = in ? h[g] : highest;
      iLo4 = a > iLo4 ? a : iLo4;
      iHi4 = b < iHi4 ? b : iHi4;
    }
    const uint32_t count = uint32_t(in4[0] + in4[1] + in4[2] + in4[3]);
    const float iLo = std::max(std::max(iLo4[0], iLo4[1]), std::max(iLo4[2], iLo4[3]));
    const float iHi = std::min(std::min(iHi4[0], iHi4[1]), std::min(iHi4[2], iHi4[3]));
    if (count > best || (count == best && p < bestLo)) {
      best = count;
      bestLo = iLo;
      bestHi = iHi;
    }
  }
  return midpoint(bestLo, bestHi);
}

// Factors on the grid base + step * i for the values `which` of the chunk, or false when
// some interval holds no point of it below 2^kMaxGridBits (after shrinking the step by a
// few ulps, for intervals exactly one step wide).
bool fitGrid(const float* lo, const float* hi, const uint32_t* which, uint32_t m, float base, float& step,
             uint32_t* factors) {
  for (int attempt = 0; attempt < 4; ++attempt, step = std::nextafter(step, 0.0f)) {
    if (!(step > 0) || !std::isfinite(step)) return false;
    bool fits = true;
    for (uint32_t j = 0; j < m && fits; ++j) {
      const float a = lo[which[j]], b = hi[which[j]];
      const double ideal = std::ceil((double(a) - double(base)) / double(step));
      if (!(ideal < double(1u << kMaxGridBits))) return false;
      fits = false;
      for (const double candidate : {ideal, ideal - 1, ideal + 1}) {
        if (candidate < 0 || candidate >= double(1u << kMaxGridBits)) continue;
        const uint32_t i = uint32_t(candidate);
        if (contains(a, b, base + step * float(i))) {
          factors[j] = i;
          fits = true;
          break;
        }
      }
    }
    if (fits) return true;
  }
  return false;
}

// The grid of fewest bits that fits: a step of the narrowest interval from the lowest
// start, the power of two below it, or one slice from a whole slice (intervals of whole
// slices, some of them a single depth: the CPVS's classification). Returns the factor
// width, 0 when none fits.
uint32_t bestGrid(const float* lo, const float* hi, const uint32_t* which, uint32_t m, float& base, float& step,
                  uint32_t* factors) {
  float lowest = lo[which[0]], narrowest = std::numeric_limits<float>::max();
  for (uint32_t j = 0; j < m; ++j) {
    lowest = std::min(lowest, lo[which[j]]);
    narrowest = std::min(narrowest, hi[which[j]] - lo[which[j]]);
  }
  uint32_t best = 0, trial[kValuesPerChunk];
  // A power of two no wider than the narrowest interval, from a multiple of it: every
  // interval holds a multiple, and the grid's points are exact floats.
  const float dyadic = narrowest > 0 && std::isfinite(narrowest) ? std::ldexp(1.0f, std::ilogb(narrowest)) : 1.0f;
  const float candidates[3][2] = {{lowest, narrowest}, {std::floor(lowest / dyadic) * dyadic, dyadic}, {std::floor(lowest), 1.0f}};
  for (const auto& [b, s] : candidates) {
    float grid = s;
    if (!fitGrid(lo, hi, which, m, b, grid, trial)) continue;
    const uint32_t width = std::max(1u, uint32_t(std::bit_width(*std::max_element(trial, trial + m))));
    if (best == 0 || width < best) {
      best = width;
      base = b;
      step = grid;
      std::copy(trial, trial + m, factors);
    }
  }
  return best;
}

class BitWriter {
 public:
  explicit BitWriter(std::vector<uint8_t>& out) : out_(out) {}
  // Starts a chunk's factors on a byte boundary; returns its byte offset.
  uint64_t alignToByte() {
    bits_ = (bits_ + 7) & ~uint64_t(7);
    return bits_ / 8;
  }
  void put(uint32_t value, uint32_t width) {
    if (out_.size() < size_t(bits_ / 8 + 16)) out_.resize(std::max(out_.size() * 2, size_t(bits_ / 8 + 16)), 0);
    // Little-endian: the value's bits from bit bits_ % 8 of byte bits_ / 8 on.
    uint64_t window;
    std::memcpy(&window, out_.data() + bits_ / 8, 8);
    window |= uint64_t(width == 32 ? value : value & ((1u << width) - 1)) << (bits_ % 8);
    std::memcpy(out_.data() + bits_ / 8, &window, 8);
    bits_ += width;
  }
  void finish() { out_.resize(size_t((bits_ + 7) / 8 + kFactorStreamPadding), 0); }

 private:
  std::vector<uint8_t>& out_;
  uint64_t bits_ = 0;
};

}  // namespace

float ValueChunks::value(uint64_t index) const {
  const ValueChunk& c = chunks[size_t(index / kValuesPerChunk)];
  const uint32_t k = uint32_t(index % kValuesPerChunk);
  if (!(c.bitmap >> k & 1)) return c.representative;
  const uint32_t j = uint32_t(bitCount(c.bitmap & ((1u << k) - 1)));
  const uint32_t width = c.factorBits();
  const uint64_t bit = uint64_t(j) * width;
  uint64_t window = 0;
  std::memcpy(&window, factors.data() + c.factorByte() + bit / 8, sizeof window);
  window >>= bit % 8;
  return decodeFactor(c, uint32_t(width == 32 ? window : window & ((uint64_t(1) << width) - 1)));
}

ValueChunks encodeValueChunks(const float* lo, const float* hi, size_t count) {
  for (size_t k = 0; k < count; ++k)
    if (!std::isfinite(lo[k]) || !std::isfinite(hi[k]) || lo[k] > hi[k])
      throw InputError("DAG-MH value " + std::to_string(k) + " has no valid interval [" + std::to_string(lo[k]) +
                       ", " + std::to_string(hi[k]) + "]");
  ValueChunks out;
  out.count = count;
  out.chunks.resize((count + kValuesPerChunk - 1) / kValuesPerChunk);
  // Each chunk on its own, in parallel (its width in `meta` for now, its factors aside);
  // then the stream, in order.
  std::vector<uint32_t> factors(out.chunks.size() * kValuesPerChunk);
  tbb::parallel_for(tbb::blocked_range<size_t>(0, out.chunks.size(), 256), [&](const auto& range) {
    uint32_t which[kValuesPerChunk];
    for (size_t ci = range.begin(); ci != range.end(); ++ci) {
      ValueChunk& c = out.chunks[ci];
      uint32_t* f = factors.data() + ci * kValuesPerChunk;
      const size_t first = ci * kValuesPerChunk;
      const uint32_t n = uint32_t(std::min<size_t>(kValuesPerChunk, count - first));
      const float* clo = lo + first;
      const float* chi = hi + first;
      c.representative = representativeOf(clo, chi, n);
      uint32_t m = 0;
      for (uint32_t k = 0; k < n; ++k)
        if (!contains(clo[k], chi[k], c.representative)) {
          c.bitmap |= 1u << k;
          which[m++] = k;
        }
      uint32_t width = 1;
      if (m > 0) {
        width = bestGrid(clo, chi, which, m, c.base, c.step, f);
        if (width == 0) {
          width = kRawFactorBits;
          c.base = c.step = 0;
          for (uint32_t j = 0; j < m; ++j) f[j] = std::bit_cast<uint32_t>(midpoint(clo[which[j]], chi[which[j]]));
        }
      }
      c.meta = width - 1;
    }
  });
  BitWriter writer(out.factors);
  for (size_t ci = 0; ci < out.chunks.size(); ++ci) {
    ValueChunk& c = out.chunks[ci];
    const uint64_t byte = writer.alignToByte();
    if (byte >= kMaxFactorStreamBytes)
      throw InputError("a DAG-MH of " + std::to_string(count) + " values needs a factor stream beyond 128 MiB");
    const uint32_t width = c.meta + 1, m = uint32_t(bitCount(c.bitmap));
    for (uint32_t j = 0; j < m; ++j) writer.put(factors[ci * kValuesPerChunk + j], width);
    c.meta = uint32_t(byte) << 5 | (width - 1);
  }
  writer.finish();
  return out;
}

ValueChunkStats valueChunkStats(const ValueChunks& values) {
  ValueChunkStats s;
  s.values = values.count;
  for (const ValueChunk& c : values.chunks) {
    const uint32_t f = uint32_t(bitCount(c.bitmap));
    s.factors += f;
    if (c.factorBits() == kRawFactorBits) s.rawFactors += f;
    s.factorBitsTotal += uint64_t(f) * c.factorBits();
  }
  return s;
}

}  // namespace cpvs
