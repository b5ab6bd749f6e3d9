#include "cpvs/bake/bake_scene.h"

#include <chrono>

#include "cpvs/bake/raster_slices.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/base/error.h"
#include "cpvs/base/progress.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

const Scene& sunCasters(const Scene& scene, std::optional<Scene>& storage) {
  if (!hasTranslucentMeshes(scene)) return scene;
  storage = opaquePart(scene);
  return *storage;
}

BakeScene::BakeScene(const Scene& scene, const OrthoGrid& grid, Renderer renderer, int threads,
                     const ReceiverDeclaration& receivers)
    : renderer_(renderer), raster_(sunCasters(scene, opaque_), grid), receivers_(scene, grid, receivers) {
  if (renderer == Renderer::Embree) rays_ = std::make_unique<RayScene>(opaque_ ? *opaque_ : scene, grid.origin, threads);
}

BakeScene::BakeScene(const Scene& scene, const PerspectiveGrid& grid, double tanCone, Renderer renderer, int threads,
                     const ReceiverDeclaration& receivers, const Scene* receiving)
    : renderer_(renderer), raster_(scene, grid, tanCone), receivers_(receiving ? *receiving : scene, grid, receivers) {
  if (renderer == Renderer::Embree) rays_ = std::make_unique<RayScene>(scene, grid.position(), threads);
}

BakeScene::~BakeScene() = default;

bool BakeScene::touchesTile(uint64_t tileX, uint64_t tileY, int log2TileSize) const {
  const uint64_t T = uint64_t(1) << log2TileSize;
  return raster_.touchesRectangle(tileX * T, tileY * T, T, T) && receivers_.touchesRectangle(tileX * T, tileY * T, T, T);
}

void BakeScene::columnMasks(const BakeOptions& options, uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                            ColumnMasks& out, StageTimes& times) const {
  CPVS_CHECK(options.renderer == renderer_);
  CPVS_CHECK(options.receivers == receivers_.kind() &&
             (options.receivers == ReceiverKind::Everywhere || options.receiverPcf == receivers_.maxPcf()));
  const uint32_t R = uint32_t(raster_.resolution());
  auto start = std::chrono::steady_clock::now();
  if (renderer_ == Renderer::Raster && receivers_.kind() == ReceiverKind::Everywhere) {
    rasterColumnMasks(raster_, options.closed, options.exit, options.undefinedRule, x0, y0, width, height, out);
    times.add("render", secondsSince(start));
    return;
  }
  // One pair of depth buffers per thread, reused from tile to tile (a fresh 128 MiB per
  // 4096^2 tile costs its page faults and zeroing every time).
  thread_local TexelSlices depths;
  if (renderer_ == Renderer::Raster)
    rasterTexelSlices(raster_, options.closed, options.exit, x0, y0, width, height, depths);
  else if (const PerspectiveGrid* spot = raster_.spot())
    renderTexelSlices(*rays_, *spot, raster_.tanCone(), options.closed, options.exit, x0, y0, width, height, depths);
  else
    renderTexelSlices(*rays_, grid(), options.closed, options.exit, x0, y0, width, height, depths);
  times.add("render", secondsSince(start));
  if (receivers_.kind() != ReceiverKind::Everywhere) {
    start = std::chrono::steady_clock::now();
    receivers_.freeIntervals(x0, y0, width, height, depths);
    times.add("receivers", secondsSince(start));
  }
  start = std::chrono::steady_clock::now();
  buildColumnMasks(depths, width, height, R, options.undefinedRule, out);
  times.add("masks", secondsSince(start));
}

}  // namespace cpvs
