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

void ApplyPlanarRunImpl(const PlanarRun& r, const uint32_t* lo, const uint32_t* hi, uint32_t* newLo, uint32_t* newHi) {
  const hn::ScalableTag<double> d;
  const hn::Rebind<int32_t, decltype(d)> di;  // slices < 2^31: signed lanes compare as unsigned
  const size_t N = hn::Lanes(d), n = size_t(r.xb - r.xa + 1);
  const auto base = hn::Set(d, r.base), gx = hn::Set(d, r.gx), zLo = hn::Set(d, r.zLo), zHi = hn::Set(d, r.zHi);
  const auto loOff = hn::Set(d, r.loOff), hiOff = hn::Set(d, r.hiOff), top = hn::Set(d, r.top);
  const auto half = hn::Set(d, 0.5), zero = hn::Zero(d), iota = hn::Iota(d, 0.0);
  // A column that reads nothing gets a = 2^31 - 1 and b = -1: neither update applies.
  const auto none = hn::Set(d, 2147483647.0), below = hn::Set(d, -1.0);
  const auto one = hn::Set(di, 1);
  auto* nlo = reinterpret_cast<int32_t*>(newLo);
  auto* nhi = reinterpret_cast<int32_t*>(newHi);
  size_t i = 0;
  for (; i + N <= n; i += N) {
    // double(x) exactly (|x| < 2^53), then the scalar statement's operations in order.
    const auto x = hn::Add(hn::Set(d, double(r.xa + int64_t(i))), iota);
    const auto z = hn::Add(base, hn::Mul(gx, hn::Add(x, half)));
    const auto lower = hn::Max(zLo, hn::Add(z, loOff)), upper = hn::Min(zHi, hn::Add(z, hiOff));
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
  for (; i < n; ++i) applyColumn(r, r.xa + int64_t(i), i, lo, hi, newLo, newHi);
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
HWY_EXPORT(FillSlicesImpl);
HWY_EXPORT(RowsMaxMinImpl);
HWY_EXPORT(SelectSharedImpl);

void applyPlanarRun(const PlanarRun& run, const uint32_t* lo, const uint32_t* hi, uint32_t* newLo, uint32_t* newHi) {
  HWY_DYNAMIC_DISPATCH(ApplyPlanarRunImpl)(run, lo, hi, newLo, newHi);
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
