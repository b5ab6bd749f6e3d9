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

#include <algorithm>
#include <bit>

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
// range; returns the covered texels whose depth lies on the ray, [0, limit].
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
      t = hn::Min(hn::Max(t, tMin), tMax);
      hn::StoreU(t, d, out + k);
      uint8_t b[8] = {};
      hn::StoreMaskBits(d, hn::And(hn::Ge(t, zero), hn::Le(t, lim)), b);
      valid |= (uint64_t(b[0]) & ((uint64_t(1) << std::min<size_t>(n, 8)) - 1)) << k;
    }
  }
  return mask & valid;
}

void RasterBinImpl(const RasterBinJob& job, RasterBinScratch& s) {
  const RasterScene& scene = *job.scene;
  const auto& triangles = scene.triangles();
  const int subBits = scene.subBits();
  const int64_t one = int64_t(1) << subBits, half = one / 2;
  const TexelMapping texels = scene.grid().texelMapping(scene.grid().origin);
  const uint32_t R = texels.side();
  uint32_t counts[65];
  for (uint32_t b = 0; b < job.blocksX * job.blocksY; ++b) {
    const int64_t bx = job.x0 + 8 * int64_t(b % job.blocksX), by = job.y0 + 8 * int64_t(b / job.blocksX);
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
      mask = blockDepths(r, bx, by, scene.depthLimit(), mask, s.fragmentDepth.data() + 64 * fragments);
      if (mask == 0) continue;
      s.fragmentMask[fragments] = mask;
      s.fragmentTriangle[fragments] = job.triangles[c];
      ++fragments;
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
    const double tie = scene.grid().depthExtent * 1e-6;
    for (int l = 0; l < 64; ++l) {
      RayHit* h = s.hits.data() + counts[l];
      int n = int(counts[l + 1] - counts[l]);
      if (n == 0) {
        lo[l] = hi[l] = R;
        continue;
      }
      if (n == 1) {
        lo[l] = hi[l] = texels.slice(h[0].t);
        continue;
      }
      if (n > kMaxHitsPerRay) {  // too many crossings: keep the enter depth only
        std::swap(h[0], *std::min_element(h, h + n, [](const RayHit& a, const RayHit& c) { return a.t < c.t; }));
        h[0].closed = false;
        n = 1;
      } else {
        n = orderCrossings(h, n, tie);
      }
      classifyTexel(h, n, job.exact, texels, lo[l], hi[l]);
    }
  }
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
