// The rasterizer's inner loop over one bin of 8x8-texel blocks, compiled for every SIMD
// target Highway offers and chosen at run time. Private to the bake layer.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/bake/raster_scene.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/raytrace/ray_scene.h"

namespace cpvs {

/// Per-thread working memory of rasterBin, reused from bin to bin.
struct RasterBinScratch {
  std::vector<uint32_t> fragmentTriangle;  // per fragment: index into RasterScene::triangles()
  std::vector<uint64_t> fragmentMask;      // per fragment: the block's covered texels
  std::vector<double> fragmentDepth;       // per fragment: 64 depths, texel (tx, ty) at ty * 8 + tx
  std::vector<RayHit> hits;                // per texel of a block, its crossings
};

/// What a bin's blocks are, and where their results go.
struct RasterBinJob {
  const RasterScene* scene;
  const uint32_t* triangles;  // indices into scene->triangles() that may touch the bin
  size_t triangleCount;
  int64_t x0, y0;             // texel of the bin's first block (multiples of 8)
  uint32_t blocksX, blocksY;  // blocks in the bin
  ClosedMode closed;
  bool exact;
  /// Outputs, block after block (row by row within the bin), 64 texels a block in the
  /// order ty * 8 + tx: first undefined and first shadowed slice, as TexelSlices.
  uint32_t* lo;
  uint32_t* hi;
};

/// Rasterizes and classifies every texel of the job's blocks. The result of a texel
/// depends only on the scene and its global position (same bytes on every SIMD target:
/// the kernels round every operation as IEEE double and never fuse multiply-adds).
void rasterBin(const RasterBinJob& job, RasterBinScratch& scratch);

/// The SIMD target rasterBin runs on this machine ("AVX3", "AVX2", ...).
const char* rasterTargetName();

}  // namespace cpvs
