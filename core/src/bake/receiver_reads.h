// The slices a receiver span reads along a run of one row's columns, applied to the
// band's freed ranges, and the passes that share a transition per 8x8 column: the inner
// loops of ReceiverSet::freeIntervals, compiled for every SIMD target Highway offers and
// chosen at run time. Private to the bake layer.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <utility>

namespace cpvs {

/// One planar span's run: columns x in [xa, xb] of a row, whose plane lies at depth
/// base + gx (x + 1/2) (in slices), read from loOff to hiOff around it, cut to [zLo, zHi]
/// and to the slices [0, top].
struct PlanarRun {
  double base, gx, zLo, zHi, loOff, hiOff, top;
  int64_t xa, xb;
};

/// The slices [a, b] that column x of the run reads; false when it reads none. The one
/// statement the scalar loops run and every SIMD target repeats operation for operation.
inline bool planarReads(const PlanarRun& r, int64_t x, uint32_t& a, uint32_t& b) {
  const double z = r.base + r.gx * (double(x) + 0.5);
  const double lower = std::max(r.zLo, z + r.loOff), upper = std::min(r.zHi, z + r.hiOff);
  if (!(lower <= upper) || upper < 0) return false;
  a = uint32_t(std::min(r.top, std::max(0.0, lower)));
  b = uint32_t(std::min(r.top, upper));
  return true;
}

/// A ring of a receiver span, row by row: the columns c in [xMin, xMax] with
/// dirX[k] (c + 1/2) <= support[k] - dirY[k] (y + 1/2) for every k < dirs (the arrays are
/// the span's and the ring's, ReceiverSet::Span and Ring).
struct RingRows {
  const double* support;
  const double* dirX;
  const double* invDirX;  // 1 / dirX (0 where dirX is 0)
  const double* dirY;
  uint32_t dirs;
  double xMin, xMax;
};

/// The columns [x0, x1] the ring reaches in one row y (whole numbers; none unless
/// x0 <= x1): the bound of each direction rounded inwards, as ReceiverSet::columnRange
/// rounds it. The one statement every SIMD target repeats operation for operation.
inline void ringColumns(const RingRows& r, int64_t y, double& x0, double& x1) {
  const double cy = double(y) + 0.5;
  double lo = r.xMin, hi = r.xMax;
  for (uint32_t k = 0; k < r.dirs; ++k) {
    const double room = r.support[k] - r.dirY[k] * cy;  // dirX * cx <= room
    if (r.dirX[k] > 0) {
      hi = std::min(hi, std::floor(room * r.invDirX[k] - 0.5));
    } else if (r.dirX[k] < 0) {
      lo = std::max(lo, std::ceil(room * r.invDirX[k] - 0.5));
    } else if (!(room >= 0)) {
      lo = std::numeric_limits<double>::infinity(), hi = -lo;
      break;
    }
  }
  x0 = lo, x1 = hi;
}

/// ringColumns for the rows y0 + i, i < n, into x0[i] and x1[i].
void ringColumnRows(const RingRows& ring, int64_t y0, size_t n, double* x0, double* x1);

/// The most rings ringRuns takes.
constexpr uint32_t kMostRings = 16;

/// A row's rings: ring k < rings (at most kMostRings) reaches the columns [from[k], to[k]]
/// (from <= to) and reads the depths [loOff[k], hiOff[k]] about the plane there. Calls
/// emit(xa, xb, lo, hi) for runs that cover each column some ring reaches once, none
/// other, with the union of the depths of the rings that reach it (the least loOff, the
/// greatest hiOff). How a row is cut into runs changes no column's union.
template <class Emit>
void ringRuns(const int64_t* from, const int64_t* to, const double* loOff, const double* hiOff, uint32_t rings,
              Emit&& emit) {
  // Most rows' rings nest, each inside the next: their runs are known without a sort,
  // each reading the union of the rings from its own outwards.
  bool nested = true;
  for (uint32_t k = 0; nested && k + 1 < rings; ++k) nested = from[k + 1] <= from[k] && to[k] <= to[k + 1];
  if (nested) {
    double outLo[kMostRings], outHi[kMostRings];  // the union of the rings k, k + 1, ...
    double ul = std::numeric_limits<double>::infinity(), uh = -ul;
    for (uint32_t k = rings; k-- > 0;) {
      ul = std::min(ul, loOff[k]), uh = std::max(uh, hiOff[k]);
      outLo[k] = ul, outHi[k] = uh;
    }
    for (uint32_t k = rings; k-- > 1;) {
      if (from[k] < from[k - 1]) emit(from[k], from[k - 1] - 1, outLo[k], outHi[k]);
      if (to[k - 1] < to[k]) emit(to[k - 1] + 1, to[k], outLo[k], outHi[k]);
    }
    if (rings > 0) emit(from[0], to[0], outLo[0], outHi[0]);
    return;
  }
  // Otherwise cut at every ring's ends (insertion sort: a few cuts), each run reading the
  // union of the rings that reach its first column.
  int64_t cuts[2 * kMostRings];
  const uint32_t ncuts = 2 * rings;
  for (uint32_t k = 0; k < rings; ++k) cuts[2 * k] = from[k], cuts[2 * k + 1] = to[k] + 1;
  for (uint32_t c = 1; c < ncuts; ++c)
    for (uint32_t d = c; d > 0 && cuts[d - 1] > cuts[d]; --d) std::swap(cuts[d - 1], cuts[d]);
  for (uint32_t c = 0; c + 1 < ncuts; ++c) {
    const int64_t xa = cuts[c], xb = cuts[c + 1] - 1;
    if (xa > xb) continue;
    double lo = std::numeric_limits<double>::infinity(), hi = -lo;
    bool reached = false;
    for (uint32_t k = 0; k < rings; ++k)
      if (from[k] <= xa && xa <= to[k]) lo = std::min(lo, loOff[k]), hi = std::max(hi, hiOff[k]), reached = true;
    if (reached) emit(xa, xb, lo, hi);  // none between rings
  }
}

/// For each column of the run (element x - xa of the arrays) whose reads [a, b] are not
/// empty: a lit slice read below the old range [lo, hi) raises newLo to min(b + 1, lo), a
/// shadowed one at or behind it lowers newHi to max(a, hi). Every target computes the
/// scalar loop's IEEE operations in its order, so the ranges are the same bits.
void applyPlanarRun(const PlanarRun& run, const uint32_t* lo, const uint32_t* hi, uint32_t* newLo, uint32_t* newHi);

/// Sets out[0, n) to v.
void fillSlices(uint32_t* out, size_t n, uint32_t v);

/// rowLo[x] = the greatest of lo[r * stride + x], rowHi[x] = the least of hi[r * stride + x]
/// over the `rows` rows (at least one), for x in [0, n).
void rowsMaxMin(const uint32_t* lo, const uint32_t* hi, size_t stride, size_t rows, size_t n, uint32_t* rowLo,
                uint32_t* rowHi);

/// out[x] = shared[x] unless it is kNoSharedSlice, else in[x], for x in [0, n).
constexpr uint32_t kNoSharedSlice = 0xFFFFFFFFu;
void selectShared(const uint32_t* shared, const uint32_t* in, uint32_t* out, size_t n);

}  // namespace cpvs
