#include "cpvs/bake/bake.h"

#include <algorithm>
#include <chrono>
#include <mutex>
#include <optional>

#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/insert_tile.h"
#include "cpvs/bake/min_max_pyramid.h"
#include "cpvs/bake/tile_eta.h"
#include "cpvs/base/error.h"
#include "cpvs/dag/compress.h"
#include "cpvs/dag/assemble_roots.h"
#include "cpvs/dag/merge.h"
#include "cpvs/dag/streaming_merger.h"

namespace cpvs {

namespace {

// Insertion and compression of a tile's resolved masks.
Dag buildTile(const ColumnMasks& masks, int log2R, int log2T, uint64_t tileX, uint64_t tileY,
              const BakeOptions& options, StageTimes& st) {
  auto start = std::chrono::steady_clock::now();
  MinMaxPyramid pyramid;
  buildMinMaxPyramid(masks, pyramid);
  st.add("masks", secondsSince(start));

  start = std::chrono::steady_clock::now();
  Dag dag;
  insertTile(masks, pyramid, log2R, log2T, tileX, tileY, options.cull, dag, &st.insert);
  st.add("insert", secondsSince(start));

  start = std::chrono::steady_clock::now();
  if (options.compress != CompressMode::None) {
    computeHashes(dag, options.hash);
    dag = compressDag(std::move(dag), options.compress);
  }
  st.add("compress", secondsSince(start));
  return dag;
}

}  // namespace

Dag bakeTile(const BakeScene& scene, uint64_t tileX, uint64_t tileY, const BakeOptions& options,
             StageTimes* times) {
  const int log2R = scene.log2Resolution();
  const int t = TilePlan(log2R, options.log2TileSize).log2TileSize();
  if (!scene.touchesTile(tileX, tileY, t)) {
    if (times) ++times->tilesSkipped;
    return bakeUntouchedTile(log2R, tileX, tileY, options, times);
  }
  StageTimes local;
  StageTimes& st = times ? *times : local;
  const uint32_t T = uint32_t(1) << t;
  ColumnMasks masks;
  scene.columnMasks(options, tileX * T, tileY * T, T, T, masks, st);
  return buildTile(masks, log2R, t, tileX, tileY, options, st);
}

Dag bakeUntouchedTile(int log2R, uint64_t tileX, uint64_t tileY, const BakeOptions& options,
                      StageTimes* times) {
  StageTimes local;
  StageTimes& st = times ? *times : local;
  const int t = TilePlan(log2R, options.log2TileSize).log2TileSize();
  const uint32_t T = uint32_t(1) << t;
  ColumnMasks masks;
  litColumnMasks(T, T, uint32_t(1) << log2R, masks);
  return buildTile(masks, log2R, t, tileX, tileY, options, st);
}

std::vector<uint32_t> tileWork(const RasterScene& raster, const TilePlan& plan,
                               const std::function<bool(uint64_t tile)>& rendered) {
  std::vector<uint32_t> work(plan.count(), 0);
  std::vector<uint32_t> touching;
  const uint64_t T = uint64_t(1) << plan.log2TileSize();
  for (uint64_t i = 0; i < plan.count(); ++i) {
    if (!rendered(i)) continue;
    const TileCoord tile = plan.tile(i);
    raster.trianglesTouching(tile.x * T, tile.y * T, T, T, touching);
    work[i] = uint32_t(std::max<size_t>(touching.size(), 1));  // rendered, so it costs something
  }
  return work;
}

std::vector<uint32_t> tileWork(const BakeScene& scene, const TilePlan& plan) {
  return tileWork(scene.raster(), plan, [&](uint64_t i) {
    const TileCoord tile = plan.tile(i);
    return scene.touchesTile(tile.x, tile.y, plan.log2TileSize());
  });
}

Dag bakeGrid(const BakeScene& scene, const BakeOptions& options, StageTimes* times, const ProgressFn& progress) {
  StageTimes local;
  StageTimes& st = times ? *times : local;
  const TilePlan plan(scene.log2Resolution(), options.log2TileSize);
  const uint64_t total = plan.count();
  StreamingMerger merger(options.compress);
  std::optional<TileEta> eta;
  if (progress) {
    eta.emplace(tileWork(scene, plan));
    if (!progress({"bake", 0, total})) throw Cancelled();
  }
  // Tiles run one after another; each stage inside a tile is parallel. Merges happen as
  // tiles complete, so at most ~log2(tiles) partial DAGs are held.
  for (uint64_t i = 0; i < total; ++i) {
    const TileCoord tile = plan.tile(i);
    const auto tileStart = std::chrono::steady_clock::now();
    Dag sub = bakeTile(scene, tile.x, tile.y, options, &st);
    auto start = std::chrono::steady_clock::now();
    merger.add(std::move(sub));
    st.add("merge", secondsSince(start));
    if (progress) {
      eta->finished(i, secondsSince(tileStart));
      if (!progress({"bake", i + 1, total, eta->secondsLeft()})) throw Cancelled();
    }
  }
  auto start = std::chrono::steady_clock::now();
  Dag merged = *merger.finish();
  Dag result = assembleRoots(std::move(merged), options.hash, options.compress);
  st.add("merge", secondsSince(start));
  return result;
}

}  // namespace cpvs
