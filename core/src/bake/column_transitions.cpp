// columnTransitions, once per SIMD target (Highway's foreach_target re-includes this
// file), chosen at run time. The new rule (§3.4) starts shadowing only where some texel
// must be shadowed (the smallest hi), then shadows every texel that may be shadowed
// (lo <= k) and keeps that mask until a lit texel must turn (the next smallest hi among
// the lit bits). The old rule shadows every texel as soon as it may be, once the column
// can no longer be all lit. The aligned rule is the new one on narrowed ranges (see
// columnTransitions). Each step compares the 64 texels at once: an open surface
// gives a column up to 64 transitions.
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "bake/column_transitions.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>

#include "cpvs/bake/column_masks.h"

HWY_BEFORE_NAMESPACE();
namespace cpvs {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// The transitions of one column whose 64 texels are in lo and hi (hi >= lo), by `rule`
// (New or Old).
HWY_INLINE void transitionsOf(const int32_t* loS, const int32_t* hiS, uint32_t R, UndefinedRule rule,
                              std::vector<uint32_t>& slices, std::vector<uint64_t>& masks, uint32_t& firstShadow,
                              uint32_t& fullShadow) {
  // Slices stay below 2^21: signed lanes compare them exactly.
  const hn::ScalableTag<int32_t> d;
  const size_t lanes = std::min<size_t>(hn::Lanes(d), 64);
  const auto* nextS = rule == UndefinedRule::New ? hiS : loS;
  const auto none = hn::Set(d, int32_t(R));
  firstShadow = fullShadow = R;
  auto best = none;
  for (size_t i = 0; i < 64; i += lanes) best = hn::Min(best, hn::LoadU(d, hiS + i));
  uint32_t k = uint32_t(hn::GetLane(hn::MinOfLanes(d, best)));
  uint64_t mask = 0;
  // One pass per step: the texels that may be shadowed at k (lo <= k, as lo < k + 1:
  // Highway 1.0 has no integer Le), and the smallest key of the others, the next step.
  while (k < R) {
    const auto above = hn::Set(d, int32_t(k + 1));
    uint64_t m = 0;
    best = none;
    for (size_t i = 0; i < 64; i += lanes) {
      const auto inside = hn::Lt(hn::LoadU(d, loS + i), above);
      uint8_t bits[8] = {};
      hn::StoreMaskBits(d, inside, bits);
      uint64_t word = 0;
      for (size_t b = 0; b < (lanes + 7) / 8; ++b) word |= uint64_t(bits[b]) << (8 * b);
      if (lanes < 64) word &= (uint64_t(1) << lanes) - 1;
      m |= word << i;
      best = hn::Min(best, hn::IfThenElse(inside, none, hn::LoadU(d, nextS + i)));
    }
    if (m != mask) {
      if (mask == 0) firstShadow = k;
      slices.push_back(k);
      masks.push_back(m);
      mask = m;
    }
    if (mask == ~uint64_t(0)) {
      fullShadow = k;
      return;
    }
    k = uint32_t(hn::GetLane(hn::MinOfLanes(d, best)));
  }
}

// The column of texels (tx, ty) at lo[ty * stride + tx] and hi[...] (hi read as at least
// lo): gathered row by row, narrowed as alignedRanges narrows them for the aligned rule,
// then its transitions.
void ColumnTransitionsImpl(const uint32_t* lo, const uint32_t* hi, size_t stride, uint32_t R, UndefinedRule rule,
                           std::vector<uint32_t>& slices, std::vector<uint64_t>& masks, uint32_t& firstShadow,
                           uint32_t& fullShadow) {
  const hn::CappedTag<int32_t, 8> d8;
  const size_t n8 = hn::Lanes(d8);
  HWY_ALIGN int32_t L[64], H[64];
  for (size_t ty = 0; ty < 8; ++ty)
    for (size_t tx = 0; tx < 8; tx += n8) {
      const auto l = hn::LoadU(d8, reinterpret_cast<const int32_t*>(lo) + ty * stride + tx);
      const auto h = hn::LoadU(d8, reinterpret_cast<const int32_t*>(hi) + ty * stride + tx);
      hn::Store(l, d8, L + ty * 8 + tx);
      hn::Store(hn::Max(l, h), d8, H + ty * 8 + tx);
    }
  if (rule == UndefinedRule::Aligned) {
    const hn::ScalableTag<int32_t> d;
    const size_t lanes = std::min<size_t>(hn::Lanes(d), 64);
    auto maxLo = hn::Zero(d), minHi = hn::Set(d, int32_t(R));
    for (size_t i = 0; i < 64; i += lanes) {
      maxLo = hn::Max(maxLo, hn::Load(d, L + i));
      minHi = hn::Min(minHi, hn::Load(d, H + i));
    }
    const int32_t litEnd = hn::GetLane(hn::MinOfLanes(d, minHi)) & ~7;
    const int32_t shadowStart = (hn::GetLane(hn::MaxOfLanes(d, maxLo)) + 7) & ~7;
    const auto lit = hn::Set(d, litEnd), shadow = hn::Set(d, shadowStart);
    for (size_t i = 0; i < 64; i += lanes) {
      if (shadowStart <= litEnd) {  // one transition for the whole column (none at R)
        hn::Store(lit, d, L + i);
        hn::Store(lit, d, H + i);
      } else {
        const auto l = hn::Max(hn::Load(d, L + i), lit);
        hn::Store(l, d, L + i);
        hn::Store(hn::Max(l, hn::Min(hn::Load(d, H + i), shadow)), d, H + i);
      }
    }
    rule = UndefinedRule::New;
  }
  transitionsOf(L, H, R, rule, slices, masks, firstShadow, fullShadow);
}

}  // namespace HWY_NAMESPACE
}  // namespace cpvs
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace cpvs {

HWY_EXPORT(ColumnTransitionsImpl);

void alignedRanges(const uint32_t lo[64], const uint32_t hi[64], uint32_t R, uint32_t outLo[64], uint32_t outHi[64]) {
  uint32_t maxLo = 0, minHi = R;
  for (int t = 0; t < 64; ++t) {
    maxLo = std::max(maxLo, lo[t]);
    minHi = std::min(minHi, std::max(lo[t], hi[t]));
  }
  // Every texel may be lit below litEnd and shadowed from shadowStart, both multiples of
  // 8: the column's 8-slice slabs there become whole lit or shadowed children of its
  // level-0 nodes, and no texel's transition falls inside them.
  const uint32_t litEnd = minHi & ~7u, shadowStart = (maxLo + 7) & ~7u;
  for (int t = 0; t < 64; ++t) {
    if (shadowStart <= litEnd) {
      outLo[t] = outHi[t] = litEnd;  // one transition for the whole column (none at R)
    } else {
      outLo[t] = std::max(lo[t], litEnd);
      outHi[t] = std::max(outLo[t], std::min(std::max(lo[t], hi[t]), shadowStart));
    }
  }
}

void columnTransitions(const uint32_t lo[64], const uint32_t hi[64], uint32_t R, UndefinedRule rule,
                       std::vector<uint32_t>& slices, std::vector<uint64_t>& masks, uint32_t& firstShadow,
                       uint32_t& fullShadow) {
  HWY_DYNAMIC_DISPATCH(ColumnTransitionsImpl)(lo, hi, 8, R, rule, slices, masks, firstShadow, fullShadow);
}

void columnTransitionsOfRows(const uint32_t* lo, const uint32_t* hi, size_t stride, uint32_t R, UndefinedRule rule,
                             std::vector<uint32_t>& slices, std::vector<uint64_t>& masks, uint32_t& firstShadow,
                             uint32_t& fullShadow) {
  HWY_DYNAMIC_DISPATCH(ColumnTransitionsImpl)(lo, hi, stride, R, rule, slices, masks, firstShadow, fullShadow);
}

}  // namespace cpvs
#endif
