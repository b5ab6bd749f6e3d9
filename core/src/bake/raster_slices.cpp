#include "cpvs/bake/raster_slices.h"

#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cstring>

#include "bake/raster_bin.h"
#include "cpvs/base/error.h"

namespace cpvs {

namespace {

// Bins of 64 x 64 texels (8 x 8 blocks): big enough that a bin's triangle list is set up
// once for many blocks, small enough for thousands of parallel tasks per 4096^2 tile.
constexpr uint32_t kBinBlocks = 8;
constexpr uint32_t kBinSide = 8 * kBinBlocks;

// The triangles of a tile sorted into its bins, each bin's list in increasing order.
struct TileBins {
  uint32_t binsX = 0, binsY = 0;
  std::vector<uint32_t> begin, items;
};

void binTile(const RasterScene& scene, uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, TileBins& bins) {
  std::vector<uint32_t> touching;
  scene.trianglesTouching(x0, y0, width, height, touching);
  bins.binsX = (width + kBinSide - 1) / kBinSide;
  bins.binsY = (height + kBinSide - 1) / kBinSide;
  const size_t count = size_t(bins.binsX) * bins.binsY;
  bins.begin.assign(count + 1, 0);
  const auto& triangles = scene.triangles();
  auto forBins = [&](const RasterTriangle& r, auto&& fn) {
    const int64_t bx0 = std::max<int64_t>(0, (r.xMin - int64_t(x0)) / kBinSide);
    const int64_t by0 = std::max<int64_t>(0, (r.yMin - int64_t(y0)) / kBinSide);
    const int64_t bx1 = std::min<int64_t>(bins.binsX - 1, (r.xMax - int64_t(x0)) / kBinSide);
    const int64_t by1 = std::min<int64_t>(bins.binsY - 1, (r.yMax - int64_t(y0)) / kBinSide);
    for (int64_t by = by0; by <= by1; ++by)
      for (int64_t bx = bx0; bx <= bx1; ++bx) fn(size_t(by) * bins.binsX + size_t(bx));
  };
  for (uint32_t t : touching) forBins(triangles[t], [&](size_t b) { ++bins.begin[b + 1]; });
  for (size_t b = 0; b < count; ++b) bins.begin[b + 1] += bins.begin[b];
  bins.items.resize(bins.begin[count]);
  std::vector<uint32_t> fill(bins.begin.begin(), bins.begin.end() - 1);
  for (uint32_t t : touching) forBins(triangles[t], [&](size_t b) { bins.items[fill[b]++] = t; });
}

// A spot light's texels its cone misses get no light: every voxel of them is undefined
// (lo = 0, hi = R). A block whose corner texels the cone all reaches has none: the part
// of a texel nearest the axis is farthest from it at a corner of the block.
void maskCone(const RasterScene& scene, const RasterBinJob& job) {
  const PerspectiveGrid* spot = scene.spot();
  if (!spot) return;
  const uint32_t R = uint32_t(scene.resolution());
  const double tanCone = scene.tanCone();
  for (uint32_t k = 0; k < job.blocksX * job.blocksY; ++k) {
    const uint64_t bx = uint64_t(job.x0) + 8 * (k % job.blocksX), by = uint64_t(job.y0) + 8 * (k / job.blocksX);
    if (!spot->coneMissesTexel(bx, by, tanCone) && !spot->coneMissesTexel(bx + 7, by, tanCone) &&
        !spot->coneMissesTexel(bx, by + 7, tanCone) && !spot->coneMissesTexel(bx + 7, by + 7, tanCone))
      continue;
    if (spot->coneMissesTexels(bx, by, 8, 8, tanCone)) {  // the whole block (rasterBin filled those it ran)
      std::fill_n(job.lo + 64 * size_t(k), 64, 0u);
      std::fill_n(job.hi + 64 * size_t(k), 64, R);
      continue;
    }
    for (int t = 0; t < 64; ++t)
      if (spot->coneMissesTexel(bx + uint64_t(t % 8), by + uint64_t(t / 8), tanCone)) {
        job.lo[64 * size_t(k) + size_t(t)] = 0;
        job.hi[64 * size_t(k) + size_t(t)] = R;
      }
  }
}

struct BinOutput {
  RasterBinScratch scratch;
  std::vector<uint32_t> lo, hi;
  bool allLit = false;  // lo and hi hold an empty bin's answer (all R) from the bin before
};

// Rasterizes a tile bin by bin in parallel; `sink(bin, job)` receives each bin's block
// slices (job.lo, job.hi) on the thread that computed them.
template <class Sink>
void rasterTile(const RasterScene& scene, ClosedMode closed, ExitMode exit, uint64_t x0, uint64_t y0,
                uint32_t width, uint32_t height, Sink&& sink) {
  CPVS_CHECK(width % 8 == 0 && height % 8 == 0 && x0 % 8 == 0 && y0 % 8 == 0);
  CPVS_CHECK(x0 + width <= scene.resolution() && y0 + height <= scene.resolution());
  TileBins bins;
  binTile(scene, x0, y0, width, height, bins);
  tbb::enumerable_thread_specific<BinOutput> outputs;
  const uint32_t R = uint32_t(scene.resolution());
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, bins.binsX * bins.binsY), [&](const auto& range) {
    BinOutput& o = outputs.local();
    o.lo.resize(64 * kBinBlocks * kBinBlocks);
    o.hi.resize(64 * kBinBlocks * kBinBlocks);
    for (uint32_t b = range.begin(); b != range.end(); ++b) {
      const uint32_t bx = b % bins.binsX, by = b / bins.binsX;
      RasterBinJob job{&scene, bins.items.data() + bins.begin[b], bins.begin[b + 1] - bins.begin[b],
                       int64_t(x0 + bx * kBinSide), int64_t(y0 + by * kBinSide),
                       std::min(kBinBlocks, (width - bx * kBinSide) / 8), std::min(kBinBlocks, (height - by * kBinSide) / 8),
                       closed, exit == ExitMode::Exact, o.lo.data(), o.hi.data()};
      // Empty bins come in runs (open sky): the buffers keep their answer between them.
      if (job.triangleCount == 0) {
        if (!o.allLit) {
          std::fill(o.lo.begin(), o.lo.end(), R);
          std::fill(o.hi.begin(), o.hi.end(), R);
        }
        o.allLit = scene.spot() == nullptr;  // maskCone writes into them
      } else {
        rasterBin(job, o.scratch);
        o.allLit = false;
      }
      maskCone(scene, job);
      sink(b, job);
    }
  });
}

}  // namespace

void rasterTexelSlices(const RasterScene& scene, ClosedMode closed, ExitMode exit, uint64_t x0, uint64_t y0,
                       uint32_t width, uint32_t height, TexelSlices& out) {
  out.firstUndefined.resize(size_t(width) * height);
  out.firstShadowed.resize(size_t(width) * height);
  rasterTile(scene, closed, exit, x0, y0, width, height, [&](uint32_t, const RasterBinJob& job) {
    for (uint32_t k = 0; k < job.blocksX * job.blocksY; ++k) {
      const size_t tx = size_t(job.x0 - int64_t(x0)) + 8 * (k % job.blocksX);
      const size_t ty = size_t(job.y0 - int64_t(y0)) + 8 * (k / job.blocksX);
      // memcpy of a constant 32 bytes is two moves; std::copy_n is a memmove call each.
      for (int row = 0; row < 8; ++row) {
        const size_t at = (ty + size_t(row)) * width + tx;
        std::memcpy(out.firstUndefined.data() + at, job.lo + 64 * size_t(k) + 8 * row, 8 * sizeof(uint32_t));
        std::memcpy(out.firstShadowed.data() + at, job.hi + 64 * size_t(k) + 8 * row, 8 * sizeof(uint32_t));
      }
    }
  });
}

void rasterColumnMasks(const RasterScene& scene, ClosedMode closed, ExitMode exit, UndefinedRule rule,
                       uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, ColumnMasks& out) {
  const uint32_t R = uint32_t(scene.resolution());
  out.columnsX = width / 8;
  out.columnsY = height / 8;
  out.resolution = R;
  const size_t columns = size_t(out.columnsX) * out.columnsY;
  out.firstShadow.assign(columns, R);
  out.fullShadow.assign(columns, R);
  // Each bin's transitions, column after column, and where each column's start there.
  const uint32_t binsX = (width + kBinSide - 1) / kBinSide, binsY = (height + kBinSide - 1) / kBinSide;
  std::vector<std::vector<uint32_t>> binSlices(size_t(binsX) * binsY);
  std::vector<std::vector<uint64_t>> binMasks(size_t(binsX) * binsY);
  std::vector<uint32_t> columnStart(columns), columnCount(columns);
  rasterTile(scene, closed, exit, x0, y0, width, height, [&](uint32_t b, const RasterBinJob& job) {
    auto& slices = binSlices[b];
    auto& masks = binMasks[b];
    slices.clear();
    masks.clear();
    for (uint32_t k = 0; k < job.blocksX * job.blocksY; ++k) {
      const size_t cx = size_t(job.x0 - int64_t(x0)) / 8 + k % job.blocksX;
      const size_t cy = size_t(job.y0 - int64_t(y0)) / 8 + k / job.blocksX;
      const size_t c = out.column(uint32_t(cx), uint32_t(cy));
      columnStart[c] = uint32_t(slices.size());
      // The block's 64 texels in row order, a stride of 8 (hi read as at least lo).
      columnTransitionsOfRows(job.lo + 64 * size_t(k), job.hi + 64 * size_t(k), 8, R, rule, slices, masks,
                              out.firstShadow[c], out.fullShadow[c]);
      columnCount[c] = uint32_t(slices.size()) - columnStart[c];
    }
  });
  out.begin.assign(columns + 1, 0);
  for (size_t c = 0; c < columns; ++c) out.begin[c + 1] = out.begin[c] + columnCount[c];
  out.slice.resize(out.begin[columns]);
  out.mask.resize(out.begin[columns]);
  tbb::parallel_for(uint32_t(0), out.columnsY, [&](uint32_t cy) {
    for (uint32_t cx = 0; cx < out.columnsX; ++cx) {
      const size_t c = out.column(cx, cy);
      const size_t b = size_t(cy / kBinBlocks) * binsX + cx / kBinBlocks;
      std::copy_n(binSlices[b].begin() + columnStart[c], columnCount[c], out.slice.begin() + out.begin[c]);
      std::copy_n(binMasks[b].begin() + columnStart[c], columnCount[c], out.mask.begin() + out.begin[c]);
    }
  });
}

const char* rasterInstructionSet() { return rasterTargetName(); }

}  // namespace cpvs
