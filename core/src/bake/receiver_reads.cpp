// applyPlanarRun and the column-sharing passes for every SIMD target (Highway's foreach_target re-includes this file
// for each), chosen at run time by HWY_DYNAMIC_DISPATCH.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "bake/receiver_reads.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>

#include "bake/receiver_reads.h"

HWY_BEFORE_NAMESPACE();
namespace cpvs {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// One column, as the vector lanes compute it (and every column of a run's tail).
HWY_INLINE void applyColumn(const PlanarRun& r, int64_t x, size_t i, const uint32_t* lo, const uint32_t* hi,
                            uint32_t* newLo, uint32_t* newHi) {
  uint32_t a = 0, b = 0;
  if (!planarReads(r, x, a, b)) return;
  if (a < lo[i]) newLo[i] = std::max(newLo[i], std::min(b + 1, lo[i]));
  if (b >= hi[i]) newHi[i] = std::min(newHi[i], std::max(a, hi[i]));
}

// The columns [i, i + Lanes(d)) of the run, each with the scalar statement's operations
// in order.
template <class D>
HWY_INLINE void applyColumns(D d, const PlanarRun& r, size_t i, const uint32_t* lo, const uint32_t* hi, uint32_t* newLo,
                             uint32_t* newHi) {
  const hn::Rebind<int32_t, D> di;  // slices < 2^31: signed lanes compare as unsigned
  const auto half = hn::Set(d, 0.5), zero = hn::Zero(d);
  // A column that reads nothing gets a = 2^31 - 1 and b = -1: neither update applies.
  const auto none = hn::Set(d, 2147483647.0), below = hn::Set(d, -1.0);
  const auto one = hn::Set(di, 1), top = hn::Set(d, r.top);
  auto* nlo = reinterpret_cast<int32_t*>(newLo);
  auto* nhi = reinterpret_cast<int32_t*>(newHi);
  // double(x) exactly (|x| < 2^53), then the scalar statement's operations in order.
  const auto x = hn::Add(hn::Set(d, double(r.xa + int64_t(i))), hn::Iota(d, 0.0));
  const auto z = hn::Add(hn::Set(d, r.base), hn::Mul(hn::Set(d, r.gx), hn::Add(x, half)));
  const auto lower = hn::Max(hn::Set(d, r.zLo), hn::Add(z, hn::Set(d, r.loOff)));
  const auto upper = hn::Min(hn::Set(d, r.zHi), hn::Add(z, hn::Set(d, r.hiOff)));
  const auto reads = hn::And(hn::Le(lower, upper), hn::Ge(upper, zero));
  // Truncated towards zero, as uint32_t() does.
  const auto a = hn::DemoteTo(di, hn::IfThenElse(reads, hn::Min(top, hn::Max(zero, lower)), none));
  const auto b = hn::DemoteTo(di, hn::IfThenElse(reads, hn::Min(top, upper), below));
  const auto l = hn::LoadU(di, reinterpret_cast<const int32_t*>(lo) + i);
  const auto h = hn::LoadU(di, reinterpret_cast<const int32_t*>(hi) + i);
  auto nl = hn::LoadU(di, nlo + i), nh = hn::LoadU(di, nhi + i);
  nl = hn::IfThenElse(hn::Lt(a, l), hn::Max(nl, hn::Min(hn::Add(b, one), l)), nl);
  nh = hn::IfThenElse(hn::Gt(b, hn::Sub(h, one)), hn::Min(nh, hn::Max(a, h)), nh);  // b >= h
  hn::StoreU(nl, di, nlo + i);
  hn::StoreU(nh, di, nhi + i);
}

void ApplyPlanarRunImpl(const PlanarRun& r, const uint32_t* lo, const uint32_t* hi, uint32_t* newLo, uint32_t* newHi) {
  const hn::ScalableTag<double> d;
  const size_t N = hn::Lanes(d), n = size_t(r.xb - r.xa + 1);
  // A column's update only raises newLo and lowers newHi to values of its own: applied
  // twice it changes nothing. So a run's last columns are one more whole vector that
  // overlaps the one before, and a run shorter than a vector two overlapping halves:
  // most runs are a few vectors long, and their tails were a third of the columns.
  if (n >= N) {
    size_t i = 0;
    for (; i + N <= n; i += N) applyColumns(d, r, i, lo, hi, newLo, newHi);
    if (i < n) applyColumns(d, r, n - N, lo, hi, newLo, newHi);
    return;
  }
#if HWY_TARGET != HWY_SCALAR
  const hn::Half<decltype(d)> dh;
  const size_t H = hn::Lanes(dh);
  if (H >= 2 && n >= H) {  // H <= n < 2H
    applyColumns(dh, r, 0, lo, hi, newLo, newHi);
    applyColumns(dh, r, n - H, lo, hi, newLo, newHi);
    return;
  }
#endif
  for (size_t i = 0; i < n; ++i) applyColumn(r, r.xa + int64_t(i), i, lo, hi, newLo, newHi);
}

// ringColumns for the rows y0 + i + [0, Lanes(d)), lane by lane.
template <class D>
HWY_INLINE void ringColumnsOf(D d, const RingRows& r, int64_t y0, size_t i, double* x0, double* x1) {
  const auto cy = hn::Add(hn::Add(hn::Set(d, double(y0 + int64_t(i))), hn::Iota(d, 0.0)), hn::Set(d, 0.5));
  const auto half = hn::Set(d, 0.5), zero = hn::Zero(d);
  auto lo = hn::Set(d, r.xMin), hi = hn::Set(d, r.xMax);
  auto dead = hn::Lt(zero, zero);  // no lane yet
  for (uint32_t k = 0; k < r.dirs; ++k) {
    const auto room = hn::Sub(hn::Set(d, r.support[k]), hn::Mul(hn::Set(d, r.dirY[k]), cy));
    if (r.dirX[k] > 0) {
      const auto bound = hn::Floor(hn::Sub(hn::Mul(room, hn::Set(d, r.invDirX[k])), half));
      hi = hn::IfThenElse(hn::Lt(bound, hi), bound, hi);  // std::min(hi, bound)
    } else if (r.dirX[k] < 0) {
      const auto bound = hn::Ceil(hn::Sub(hn::Mul(room, hn::Set(d, r.invDirX[k])), half));
      lo = hn::IfThenElse(hn::Lt(lo, bound), bound, lo);  // std::max(lo, bound)
    } else {
      dead = hn::Or(dead, hn::Not(hn::Ge(room, zero)));
    }
  }
  const auto inf = hn::Set(d, std::numeric_limits<double>::infinity());
  hn::StoreU(hn::IfThenElse(dead, inf, lo), d, x0 + i);
  hn::StoreU(hn::IfThenElse(dead, hn::Neg(inf), hi), d, x1 + i);
}

void RingColumnRowsImpl(const RingRows& r, int64_t y0, size_t n, double* x0, double* x1) {
  const hn::ScalableTag<double> d;
  const size_t N = hn::Lanes(d);
  // A row's columns depend on the row alone: the last rows are one more whole vector
  // overlapping the one before, rewritten alike.
  if (n >= N) {
    size_t i = 0;
    for (; i + N <= n; i += N) ringColumnsOf(d, r, y0, i, x0, x1);
    if (i < n) ringColumnsOf(d, r, y0, n - N, x0, x1);
    return;
  }
  for (size_t i = 0; i < n; ++i) ringColumns(r, y0 + int64_t(i), x0[i], x1[i]);
}

void FillSlicesImpl(uint32_t* out, size_t n, uint32_t v) {
  const hn::ScalableTag<uint32_t> d;
  const size_t N = hn::Lanes(d);
  const auto value = hn::Set(d, v);
  size_t i = 0;
  for (; i + N <= n; i += N) hn::StoreU(value, d, out + i);
  for (; i < n; ++i) out[i] = v;
}

void RowsMaxMinImpl(const uint32_t* lo, const uint32_t* hi, size_t stride, size_t rows, size_t n, uint32_t* rowLo,
                    uint32_t* rowHi) {
  const hn::ScalableTag<uint32_t> d;
  const size_t N = hn::Lanes(d);
  size_t x = 0;
  for (; x + N <= n; x += N) {
    auto ml = hn::LoadU(d, lo + x), mh = hn::LoadU(d, hi + x);
    for (size_t r = 1; r < rows; ++r) {
      ml = hn::Max(ml, hn::LoadU(d, lo + r * stride + x));
      mh = hn::Min(mh, hn::LoadU(d, hi + r * stride + x));
    }
    hn::StoreU(ml, d, rowLo + x);
    hn::StoreU(mh, d, rowHi + x);
  }
  for (; x < n; ++x) {
    uint32_t ml = lo[x], mh = hi[x];
    for (size_t r = 1; r < rows; ++r) ml = std::max(ml, lo[r * stride + x]), mh = std::min(mh, hi[r * stride + x]);
    rowLo[x] = ml, rowHi[x] = mh;
  }
}

void SelectSharedImpl(const uint32_t* shared, const uint32_t* in, uint32_t* out, size_t n) {
  const hn::ScalableTag<uint32_t> d;
  const size_t N = hn::Lanes(d);
  const auto none = hn::Set(d, kNoSharedSlice);
  size_t i = 0;
  for (; i + N <= n; i += N) {
    const auto s = hn::LoadU(d, shared + i);
    hn::StoreU(hn::IfThenElse(hn::Eq(s, none), hn::LoadU(d, in + i), s), d, out + i);
  }
  for (; i < n; ++i) out[i] = shared[i] == kNoSharedSlice ? in[i] : shared[i];
}

}  // namespace HWY_NAMESPACE
}  // namespace cpvs
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace cpvs {

HWY_EXPORT(ApplyPlanarRunImpl);
HWY_EXPORT(RingColumnRowsImpl);
HWY_EXPORT(FillSlicesImpl);
HWY_EXPORT(RowsMaxMinImpl);
HWY_EXPORT(SelectSharedImpl);

void applyPlanarRun(const PlanarRun& run, const uint32_t* lo, const uint32_t* hi, uint32_t* newLo, uint32_t* newHi) {
  HWY_DYNAMIC_DISPATCH(ApplyPlanarRunImpl)(run, lo, hi, newLo, newHi);
}

void ringColumnRows(const RingRows& ring, int64_t y0, size_t n, double* x0, double* x1) {
  HWY_DYNAMIC_DISPATCH(RingColumnRowsImpl)(ring, y0, n, x0, x1);
}

void fillSlices(uint32_t* out, size_t n, uint32_t v) { HWY_DYNAMIC_DISPATCH(FillSlicesImpl)(out, n, v); }

void rowsMaxMin(const uint32_t* lo, const uint32_t* hi, size_t stride, size_t rows, size_t n, uint32_t* rowLo,
                uint32_t* rowHi) {
  HWY_DYNAMIC_DISPATCH(RowsMaxMinImpl)(lo, hi, stride, rows, n, rowLo, rowHi);
}

void selectShared(const uint32_t* shared, const uint32_t* in, uint32_t* out, size_t n) {
  HWY_DYNAMIC_DISPATCH(SelectSharedImpl)(shared, in, out, n);
}

}  // namespace cpvs
#endif
