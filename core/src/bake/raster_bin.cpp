// The rasterizer's per-bin loop, once per SIMD target (Highway's foreach_target
// re-includes this file for each), chosen at run time by HWY_DYNAMIC_DISPATCH.
//
// Per 8x8 block (one DAG column), every candidate triangle is first classified by its
// three edge functions at the block's corner samples, exactly in 128-bit integers: out,
// fully inside, or crossed. Only crossed edges are evaluated per texel, in 64-bit lanes
// (the scene's sub-texel bits keep them below 2^63 there). Covered texels get the
// triangle's depth plane in double; each texel's crossings then go through the same
// ordering and classification as the ray tracer's (orderCrossings, classifyTexel).
#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "bake/raster_bin.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>
#include <hwy/contrib/math/math-inl.h>

#include <algorithm>
#include <bit>
#include <limits>
#include <type_traits>

#include "bake/raster_bin.h"
#include "cpvs/bake/texel_slices.h"

HWY_BEFORE_NAMESPACE();
namespace cpvs {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// Bits (lane i of 8 at bit i) of the texels of one block row where e0 + i * sx > 0.
HWY_INLINE uint64_t rowInside(int64_t e0, const int64_t* laneSteps) {
  const hn::ScalableTag<int64_t> d;
  constexpr size_t kMaxLanes = 8;
  const size_t n = std::min(hn::Lanes(d), kMaxLanes);
  uint64_t bits = 0;
  for (size_t i = 0; i < 8; i += n) {
    const auto e = hn::Add(hn::Set(d, e0), hn::LoadU(d, laneSteps + i));
    uint8_t b[8] = {};
    hn::StoreMaskBits(d, hn::Gt(e, hn::Zero(d)), b);
    bits |= (uint64_t(b[0]) & ((uint64_t(1) << n) - 1)) << i;
  }
  return bits;
}

// Bits of the block's texels whose centres lie inside the triangle (0 when none), the
// block's first texel centre at fixed point (px, py).
HWY_INLINE uint64_t blockCoverage(const RasterTriangle& r, int subBits, int64_t px, int64_t py) {
  uint64_t mask = ~uint64_t(0);
  for (int e = 0; e < 3; ++e) {
    const int f = e == 2 ? 0 : e + 1;
    const int64_t dx = r.fx[f] - r.fx[e], dy = r.fy[f] - r.fy[e];
    const __int128 e00 = __int128(dx) * (py - r.fy[e]) - __int128(dy) * (px - r.fx[e]) + r.bias[e];
    const int64_t sx = -dy * (int64_t(1) << subBits), sy = dx * (int64_t(1) << subBits);
    const __int128 low = e00 + std::min<int64_t>(0, 7 * sx) + std::min<int64_t>(0, 7 * sy);
    const __int128 high = e00 + std::max<int64_t>(0, 7 * sx) + std::max<int64_t>(0, 7 * sy);
    if (high <= 0) return 0;
    if (low > 0) continue;
    // Crossed: every sample of the block lies within [low, high], which fits 64 bits.
    alignas(64) int64_t laneSteps[8];
    for (int i = 0; i < 8; ++i) laneSteps[i] = i * sx;
    uint64_t edge = 0;
    for (int j = 0; j < 8; ++j) edge |= rowInside(int64_t(e00) + j * sy, laneSteps) << (8 * j);
    mask &= edge;
    if (mask == 0) return 0;
  }
  return mask;
}

// Depths of the triangle's plane at the block's 64 texel centres, clamped to its depth
// range; returns the covered texels whose depth lies on the ray, [0, limit]. For a spot
// light the plane is of 1 / depth (division rounds as IEEE double on every target).
template <bool kPerspective>
HWY_INLINE uint64_t blockDepths(const RasterTriangle& r, int64_t bx, int64_t by, double limit, uint64_t mask,
                                double* out) {
  const hn::ScalableTag<double> d;
  const size_t n = hn::Lanes(d);
  alignas(64) double column[8];
  for (int i = 0; i < 8; ++i) column[i] = double(bx + i) + 0.5 - r.ax;
  const auto gx = hn::Set(d, r.gx), gy = hn::Set(d, r.gy), at = hn::Set(d, r.at);
  const auto tMin = hn::Set(d, r.tMin), tMax = hn::Set(d, r.tMax), zero = hn::Zero(d), lim = hn::Set(d, limit);
  uint64_t valid = 0;
  for (int j = 0; j < 8; ++j) {
    const auto dy = hn::Mul(gy, hn::Set(d, double(by + j) + 0.5 - r.ay));
    for (size_t i = 0; i < 8; i += n) {
      const size_t k = size_t(j) * 8 + i;
      auto t = hn::Add(hn::Add(at, hn::Mul(gx, hn::LoadU(d, column + i))), dy);
      if constexpr (kPerspective) t = hn::Div(hn::Set(d, 1.0), t);
      t = hn::Min(hn::Max(t, tMin), tMax);
      hn::StoreU(t, d, out + k);
      uint8_t b[8] = {};
      hn::StoreMaskBits(d, hn::And(hn::Ge(t, zero), hn::Le(t, lim)), b);
      valid |= (uint64_t(b[0]) & ((uint64_t(1) << std::min<size_t>(n, 8)) - 1)) << k;
    }
  }
  return mask & valid;
}

// How one texel's crossings were ordered and which decided its slices, kept so that the
// next texels of the block, crossed by the same triangles, are resolved without ordering
// them again. The rule (orderCrossings, then exitCrossing) depends only on how the
// crossings fall into runs closer than the tie distance: runs of one or two crossings,
// in the same sequence, with the same first crossing in each pair of the same kind (a
// pair of an enter and an exit is ordered enter first whichever is nearer, which is what
// coinciding surfaces, a box standing on another, need). Texels where three crossings
// chain within the tie distance, or with many crossings, always take the full rule.
struct LaneOrder {
  static constexpr int kMax = 16;
  int count = 0;                        // 0: nothing to repeat
  uint32_t triangles[kMax];             // the crossings' triangles, in the order gathered
  int runs = 0;
  uint8_t first[kMax], second[kMax];    // per run, positions in gathered order (second: pairs)
  bool pair[kMax], pairOrdered[kMax];   // a run of two; its order must repeat (same kind)
  int enter = 0, exit = -1;             // positions (in gathered order) of the deciding crossings

  // True when `h` has the same triangles as the texel resolved last, in the same runs.
  bool repeats(const RayHit* h, int n, double tie) const {
    if (n != count) return false;
    for (int i = 0; i < n; ++i)
      if (h[i].triangle != triangles[i]) return false;
    double previous = 0;
    for (int r = 0; r < runs; ++r) {
      double lo = h[first[r]].t, hi = lo;
      if (pair[r]) {
        const RayHit& a = h[first[r]];
        const RayHit& b = h[second[r]];
        lo = std::min(a.t, b.t);
        hi = std::max(a.t, b.t);
        if (!(hi - lo <= tie)) return false;
        if (pairOrdered[r] && !closerCrossing(a, b)) return false;
      }
      if (r > 0 && !(lo - previous > tie)) return false;
      previous = hi;
    }
    return true;
  }

  // The full rule for `h` (reordered in place), remembered for the next texels when its
  // runs allow it.
  template <class Texels>
  void resolve(RayHit* h, int n, double tie, bool exact, const Texels& texels, uint32_t& lo, uint32_t& hi) {
    count = 0;
    if (n > kMaxHitsPerRay) {  // too many crossings: keep the enter depth only
      std::swap(h[0], *std::min_element(h, h + n, [](const RayHit& a, const RayHit& c) { return a.t < c.t; }));
      h[0].closed = false;
      classifyTexel(h, 1, exact, texels, lo, hi);
      return;
    }
    bool repeatable = n <= kMax;
    if (repeatable) {
      uint8_t sorted[kMax];
      for (int i = 0; i < n; ++i) {
        triangles[i] = h[i].triangle;
        sorted[i] = uint8_t(i);
      }
      for (int i = 1; i < n; ++i)
        for (int j = i; j > 0 && closerCrossing(h[sorted[j]], h[sorted[j - 1]]); --j) std::swap(sorted[j], sorted[j - 1]);
      runs = 0;
      for (int k = 0; k < n && repeatable;) {
        const bool joined = k + 1 < n && h[sorted[k + 1]].t - h[sorted[k]].t <= tie;
        repeatable = !(joined && k + 2 < n && h[sorted[k + 2]].t - h[sorted[k + 1]].t <= tie);
        first[runs] = sorted[k];
        second[runs] = joined ? sorted[k + 1] : 0;
        pair[runs] = joined;
        pairOrdered[runs] = joined && h[sorted[k]].front == h[sorted[k + 1]].front;
        ++runs;
        k += joined ? 2 : 1;
      }
    }
    const int m = orderCrossings(h, n, tie);
    classifyTexel(h, m, exact, texels, lo, hi);
    if (!repeatable) return;
    const int decided = exitCrossing(h, m, exact);
    auto position = [&](uint32_t triangle) { return int(std::find(triangles, triangles + n, triangle) - triangles); };
    enter = position(h[0].triangle);
    exit = decided < 0 ? -1 : position(h[decided].triangle);
    count = n;
  }
};

// The slice of each depth, as TexelMapping::slice computes it (the same IEEE operations).
template <class D, class V>
HWY_INLINE V slicesOf(D d, V t, const TexelMapping& texels) {
  const auto cells = hn::Set(d, double(texels.side()));
  auto k = hn::Floor(hn::Mul(t, hn::Set(d, texels.slicesPerUnit())));
  k = hn::IfThenElse(hn::Ge(k, hn::Zero(d)), k, hn::Zero(d));  // and NaN
  return hn::IfThenElse(hn::Ge(k, cells), cells, k);
}

// A spot light's slices as PerspectiveGrid::sliceOfDepth gives them, faster: eq. (1)
// through Highway's logarithm estimates the slice (to within one or two), and the grid's
// boundary table decides, so every target and the grid agree exactly. std::log per
// texel was most of a spot bake (8K grids of the city's lamps: 2.2 s each, 89 % render).
class SpotSlices {
 public:
  explicit SpotSlices(const PerspectiveGrid& g)
      : b_(g.sliceBoundaries()), near_(g.near()), far_(g.far()), perLog_(g.slicesPerLog()), side_(uint32_t(g.side())) {}
  uint32_t side() const { return side_; }
  uint32_t slice(double t) const {
    if (!(t >= near_)) return 0;  // and NaN
    if (t >= far_) return side_;
    const hn::CappedTag<double, 1> d1;
    const double e = std::floor(hn::GetLane(hn::Log(d1, hn::Set(d1, t / near_))) * perLog_);
    return settle(t, e);
  }
  // The slice from an estimate: the table's k with B[k] <= t < B[k + 1].
  uint32_t settle(double t, double estimate) const {
    uint32_t k = estimate >= 0 ? uint32_t(std::min(estimate, double(side_ - 1))) : 0;
    while (k > 0 && t < b_[k]) --k;
    while (k + 1 < side_ && t >= b_[k + 1]) ++k;
    return k;
  }
  const double* boundaries() const { return b_; }
  double near() const { return near_; }
  double perLog() const { return perLog_; }

 private:
  const double* b_;
  double near_, far_, perLog_;
  uint32_t side_;
};

// The slices of a vector of depths: lanes whose estimate the table confirms at once,
// the others (near, far, a boundary) one by one.
template <class D, class V>
HWY_INLINE V slicesOf(D d, V t, const SpotSlices& texels) {
  const hn::RebindToSigned<D> di;
  const auto top = hn::Set(d, double(texels.side() - 1));
  auto e = hn::Floor(hn::Mul(hn::Log(d, hn::Div(t, hn::Set(d, texels.near()))), hn::Set(d, texels.perLog())));
  e = hn::IfThenElse(hn::Ge(e, hn::Zero(d)), e, hn::Zero(d));  // and NaN
  e = hn::Min(e, top);
  const auto k = hn::ConvertTo(di, e);
  const auto lo = hn::GatherIndex(d, texels.boundaries(), k);
  const auto hi = hn::GatherIndex(d, texels.boundaries(), hn::Add(k, hn::Set(di, 1)));
  if (hn::AllTrue(d, hn::And(hn::Le(lo, t), hn::Lt(t, hi)))) return e;
  constexpr size_t kMaxLanes = 8;
  const size_t n = std::min(hn::Lanes(d), kMaxLanes);
  alignas(64) double depth[kMaxLanes] = {}, slice[kMaxLanes] = {};
  hn::StoreU(t, d, depth);
  for (size_t i = 0; i < n; ++i) slice[i] = double(texels.slice(depth[i]));
  return hn::LoadU(d, slice);
}

// A block every one of whose `n` fragments covers all 64 texels (inside a few large
// triangles: most blocks). Texel 0 is ordered by the full rule; every texel whose
// crossings keep that order and those ties takes its deciding crossings, 64 texels at a
// time; the others take the full rule.
template <class Texels>
HWY_INLINE void resolveUniformBlock(const RasterBinScratch& s, size_t n, const std::vector<RasterTriangle>& triangles,
                                    ClosedMode closedMode, bool exact, double tie, const Texels& texels,
                                    std::vector<RayHit>& buffer, uint32_t* lo, uint32_t* hi) {
  if (buffer.size() < n) buffer.resize(n);
  auto laneHits = [&](int l) {
    for (size_t f = 0; f < n; ++f) {
      const RasterTriangle& r = triangles[s.fragmentTriangle[f]];
      const bool closed = closedMode == ClosedMode::On || (closedMode == ClosedMode::Auto && r.closed);
      buffer[f] = RayHit{s.fragmentDepth[64 * f + size_t(l)], r.triangle, r.front, closed};
    }
    return buffer.data();
  };
  LaneOrder order;
  order.resolve(laneHits(0), int(n), tie, exact, texels, lo[0], hi[0]);
  uint64_t rest = ~uint64_t(1);  // texels still to resolve
  if (order.count != 0) {
    const hn::ScalableTag<double> d;
    const hn::Rebind<int32_t, decltype(d)> di;
    const size_t lanes = hn::Lanes(d);
    // Per ordered pair: which comes first when the depths are equal.
    bool firstWhenEqual[LaneOrder::kMax];
    for (int r = 0; r < order.runs; ++r) {
      if (!order.pairOrdered[r]) continue;
      const RasterTriangle& a = triangles[s.fragmentTriangle[order.first[r]]];
      const RasterTriangle& b = triangles[s.fragmentTriangle[order.second[r]]];
      firstWhenEqual[r] = a.front != b.front ? a.front : a.triangle < b.triangle;
    }
    const double* enter = s.fragmentDepth.data() + 64 * size_t(order.enter);
    const double* exit = order.exit < 0 ? nullptr : s.fragmentDepth.data() + 64 * size_t(order.exit);
    const auto tieV = hn::Set(d, tie);
    auto row = [&](uint8_t position, size_t i) { return hn::LoadU(d, s.fragmentDepth.data() + 64 * size_t(position) + i); };
    rest = 0;
    for (size_t i = 0; i < 64; i += lanes) {
      auto same = hn::FirstN(d, lanes);
      auto previous = hn::Zero(d);
      for (int r = 0; r < order.runs; ++r) {
        auto lo = row(order.first[r], i), hi = lo;
        if (order.pair[r]) {
          const auto a = lo, b = row(order.second[r], i);
          lo = hn::Min(a, b);
          hi = hn::Max(a, b);
          same = hn::And(same, hn::Le(hn::Sub(hi, lo), tieV));
          if (order.pairOrdered[r]) same = hn::And(same, firstWhenEqual[r] ? hn::Le(a, b) : hn::Lt(a, b));
        }
        if (r > 0) same = hn::And(same, hn::Gt(hn::Sub(lo, previous), tieV));
        previous = hi;
      }
      const auto loV = slicesOf(d, hn::LoadU(d, enter + i), texels);
      const auto hiV = exit ? hn::Max(loV, slicesOf(d, hn::LoadU(d, exit + i), texels)) : loV;
      hn::StoreU(hn::DemoteTo(di, loV), di, reinterpret_cast<int32_t*>(lo + i));
      hn::StoreU(hn::DemoteTo(di, hiV), di, reinterpret_cast<int32_t*>(hi + i));
      uint8_t bits[8] = {};
      hn::StoreMaskBits(d, hn::Not(same), bits);
      rest |= (uint64_t(bits[0]) & ((uint64_t(1) << std::min<size_t>(lanes, 8)) - 1)) << i;
    }
  }
  for (uint64_t m = rest; m; m &= m - 1) {
    const int l = std::countr_zero(m);
    LaneOrder own;
    own.resolve(laneHits(l), int(n), tie, exact, texels, lo[l], hi[l]);
  }
}

// The bin's blocks through `texels`, the grid's depth slices (TexelMapping for a
// directional light, SpotSlices for a spot light).
template <class Texels>
void rasterBlocks(const RasterBinJob& job, RasterBinScratch& s, const Texels& texels) {
  constexpr bool kPerspective = std::is_same_v<Texels, SpotSlices>;
  const RasterScene& scene = *job.scene;
  const auto& triangles = scene.triangles();
  const int subBits = scene.subBits();
  const int64_t one = int64_t(1) << subBits, half = one / 2;
  const uint32_t R = texels.side();
  const double tie = scene.tieDistance();
  uint32_t counts[65];
  for (uint32_t b = 0; b < job.blocksX * job.blocksY; ++b) {
    const int64_t bx = job.x0 + 8 * int64_t(b % job.blocksX), by = job.y0 + 8 * int64_t(b / job.blocksX);
    if constexpr (kPerspective) {
      // A block the spot light's cone misses gets no light: all undefined, not rendered.
      if (scene.spot()->coneMissesTexels(uint64_t(bx), uint64_t(by), 8, 8, scene.tanCone())) {
        std::fill(job.lo + 64 * size_t(b), job.lo + 64 * size_t(b) + 64, 0u);
        std::fill(job.hi + 64 * size_t(b), job.hi + 64 * size_t(b) + 64, R);
        continue;
      }
    }
    // Fragments: the triangles that cover some texel of the block, with their depths.
    size_t fragments = 0;
    for (size_t c = 0; c < job.triangleCount; ++c) {
      const RasterTriangle& r = triangles[job.triangles[c]];
      if (r.xMax < bx || r.xMin > bx + 7 || r.yMax < by || r.yMin > by + 7) continue;
      uint64_t mask = blockCoverage(r, subBits, bx * one + half, by * one + half);
      if (mask == 0) continue;
      if (s.fragmentMask.size() <= fragments) {
        s.fragmentMask.resize(fragments + 16);
        s.fragmentTriangle.resize(fragments + 16);
        s.fragmentDepth.resize(64 * (fragments + 16));
      }
      mask = blockDepths<kPerspective>(r, bx, by, scene.depthLimit(), mask, s.fragmentDepth.data() + 64 * fragments);
      if (mask == 0) continue;
      s.fragmentMask[fragments] = mask;
      s.fragmentTriangle[fragments] = job.triangles[c];
      ++fragments;
    }

    uint64_t everywhere = ~uint64_t(0);
    for (size_t f = 0; f < fragments; ++f) everywhere &= s.fragmentMask[f];
    if (fragments >= 2 && everywhere == ~uint64_t(0) && fragments <= size_t(LaneOrder::kMax)) {
      resolveUniformBlock(s, fragments, triangles, job.closed, job.exact, tie, texels, s.hits, job.lo + 64 * size_t(b),
                          job.hi + 64 * size_t(b));
      continue;
    }

    // Only open surfaces here: the nearest crossing decides each texel (classifyTexel),
    // unless another lies within the tie distance of it, which the full rule orders.
    bool anyClosed = false;
    for (size_t f = 0; f < fragments && !anyClosed; ++f) {
      const RasterTriangle& r = triangles[s.fragmentTriangle[f]];
      anyClosed = job.closed == ClosedMode::On || (job.closed == ClosedMode::Auto && r.closed);
    }
    if (!anyClosed && fragments > 0) {
      double nearest[64], second[64];
      std::fill(nearest, nearest + 64, std::numeric_limits<double>::infinity());
      std::fill(second, second + 64, std::numeric_limits<double>::infinity());
      for (size_t f = 0; f < fragments; ++f) {
        const double* depth = s.fragmentDepth.data() + 64 * f;
        for (uint64_t m = s.fragmentMask[f]; m; m &= m - 1) {
          const int l = std::countr_zero(m);
          const double t = depth[l];
          if (t < nearest[l]) {
            second[l] = nearest[l];
            nearest[l] = t;
          } else if (t < second[l]) {
            second[l] = t;
          }
        }
      }
      bool clear = true;
      for (int l = 0; l < 64 && clear; ++l) clear = !(second[l] - nearest[l] <= tie);
      if (clear) {
        uint32_t* lo = job.lo + 64 * size_t(b);
        uint32_t* hi = job.hi + 64 * size_t(b);
        for (int l = 0; l < 64; ++l) lo[l] = hi[l] = nearest[l] == std::numeric_limits<double>::infinity() ? R : texels.slice(nearest[l]);
        continue;
      }
    }

    // Each texel's crossings, gathered texel by texel (counting, then filling).
    std::fill(counts, counts + 65, 0u);
    for (size_t f = 0; f < fragments; ++f)
      for (uint64_t m = s.fragmentMask[f]; m; m &= m - 1) ++counts[std::countr_zero(m) + 1];
    for (int l = 0; l < 64; ++l) counts[l + 1] += counts[l];
    if (s.hits.size() < counts[64]) s.hits.resize(counts[64]);
    uint32_t fill[64];
    std::copy(counts, counts + 64, fill);
    for (size_t f = 0; f < fragments; ++f) {
      const RasterTriangle& r = triangles[s.fragmentTriangle[f]];
      const bool closed = job.closed == ClosedMode::On || (job.closed == ClosedMode::Auto && r.closed);
      const double* depth = s.fragmentDepth.data() + 64 * f;
      for (uint64_t m = s.fragmentMask[f]; m; m &= m - 1) {
        const int l = std::countr_zero(m);
        s.hits[fill[l]++] = RayHit{depth[l], r.triangle, r.front, closed};
      }
    }

    uint32_t* lo = job.lo + 64 * size_t(b);
    uint32_t* hi = job.hi + 64 * size_t(b);
    LaneOrder previous;
    for (int l = 0; l < 64; ++l) {
      RayHit* h = s.hits.data() + counts[l];
      const int n = int(counts[l + 1] - counts[l]);
      if (n == 0) {
        lo[l] = hi[l] = R;
      } else if (n == 1) {
        lo[l] = hi[l] = texels.slice(h[0].t);
      } else if (!previous.repeats(h, n, tie)) {
        previous.resolve(h, n, tie, job.exact, texels, lo[l], hi[l]);
      } else {
        lo[l] = texels.slice(h[previous.enter].t);
        hi[l] = previous.exit < 0 ? lo[l] : std::max(lo[l], texels.slice(h[previous.exit].t));
      }
    }
  }
}

void RasterBinImpl(const RasterBinJob& job, RasterBinScratch& s) {
  if (const PerspectiveGrid* spot = job.scene->spot())
    rasterBlocks(job, s, SpotSlices(*spot));
  else
    rasterBlocks(job, s, job.scene->grid().texelMapping(job.scene->grid().origin));
}

const char* TargetNameImpl() { return hwy::TargetName(HWY_TARGET); }

}  // namespace HWY_NAMESPACE
}  // namespace cpvs
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace cpvs {

HWY_EXPORT(RasterBinImpl);
HWY_EXPORT(TargetNameImpl);

void rasterBin(const RasterBinJob& job, RasterBinScratch& scratch) {
  HWY_DYNAMIC_DISPATCH(RasterBinImpl)(job, scratch);
}

const char* rasterTargetName() { return HWY_DYNAMIC_DISPATCH(TargetNameImpl)(); }

}  // namespace cpvs
#endif
