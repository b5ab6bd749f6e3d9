#include "cpvs/bake/bake_scene.h"

#include <chrono>
#include <optional>

#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>

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

namespace {

// The rasterizer's scene and the receivers' spans need nothing of each other: each is
// made on its own core, the receivers into `receivers`, the scene returned.
template <class MakeRaster, class MakeReceivers>
RasterScene makeBoth(MakeRaster&& makeRaster, MakeReceivers&& makeReceivers, ReceiverSet& receivers) {
  std::optional<RasterScene> raster;
  // Isolated: a farm worker builds scenes under a lock, where waiting must not take up
  // another task's tile.
  tbb::this_task_arena::isolate(
      [&] { tbb::parallel_invoke([&] { raster.emplace(makeRaster()); }, [&] { receivers = makeReceivers(); }); });
  return std::move(*raster);
}

}  // namespace

BakeScene::BakeScene(const Scene& scene, const OrthoGrid& grid, Renderer renderer, int threads,
                     const ReceiverDeclaration& receivers)
    : renderer_(renderer),
      receivers_(ReceiverSet::everywhere(0)),
      raster_(makeBoth([&] { return RasterScene(sunCasters(scene, opaque_), grid); },
                       [&] { return ReceiverSet(scene, grid, receivers); }, receivers_)) {
  if (renderer == Renderer::Embree) rays_ = std::make_unique<RayScene>(opaque_ ? *opaque_ : scene, grid.origin, threads);
}

BakeScene::BakeScene(const Scene& scene, const PerspectiveGrid& grid, double tanCone, Renderer renderer, int threads,
                     const ReceiverDeclaration& receivers, const Scene* receiving)
    : renderer_(renderer),
      receivers_(ReceiverSet::everywhere(0)),
      raster_(makeBoth([&] { return RasterScene(scene, grid, tanCone); },
                       [&] { return ReceiverSet(receiving ? *receiving : scene, grid, receivers); }, receivers_)) {
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
  // The block is rendered, freed and resolved in strips of rows, each in one pair of depth
  // buffers per thread reused from strip to strip: a 4096-wide strip of 128 rows is 4 MiB,
  // which the three passes over it find in cache, where a whole 4096^2 tile's 128 MiB came
  // from memory three times (and cost its page faults and zeroing on every thread).
  // Every stage depends only on each texel's position and its 8x8 column, so the masks are
  // the whole block's.
  constexpr uint32_t kStripRows = 128;
  thread_local TexelSlices depths;
  thread_local ColumnMasks rows;
  const size_t columns = size_t(width / 8) * (height / 8);
  out.columnsX = width / 8;
  out.columnsY = 0;
  out.resolution = R;
  out.begin.assign(1, 0);
  out.begin.reserve(columns + 1);
  out.slice.clear();
  out.mask.clear();
  out.firstShadow.clear();
  out.fullShadow.clear();
  out.firstShadow.reserve(columns);
  out.fullShadow.reserve(columns);
  for (uint32_t y = 0; y < height; y += kStripRows) {
    const uint32_t strip = std::min(kStripRows, height - y);
    start = std::chrono::steady_clock::now();
    if (renderer_ == Renderer::Raster)
      rasterTexelSlices(raster_, options.closed, options.exit, x0, y0 + y, width, strip, depths);
    else if (const PerspectiveGrid* spot = raster_.spot())
      renderTexelSlices(*rays_, *spot, raster_.tanCone(), options.closed, options.exit, x0, y0 + y, width, strip, depths);
    else
      renderTexelSlices(*rays_, grid(), options.closed, options.exit, x0, y0 + y, width, strip, depths);
    times.add("render", secondsSince(start));
    if (receivers_.kind() != ReceiverKind::Everywhere) {
      start = std::chrono::steady_clock::now();
      receivers_.freeIntervals(x0, y0 + y, width, strip, depths);
      times.add("receivers", secondsSince(start));
    }
    start = std::chrono::steady_clock::now();
    buildColumnMasks(depths, width, strip, R, options.undefinedRule, rows);
    appendColumnRows(out, rows);
    times.add("masks", secondsSince(start));
  }
}

}  // namespace cpvs
