#include "cpvs/bake/bake.h"

#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <chrono>
#include <memory>
#include <mutex>
#include <optional>

#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/insert_tile.h"
#include "cpvs/bake/min_max_pyramid.h"
#include "cpvs/bake/tile_cache.h"
#include "cpvs/bake/tile_eta.h"
#include "cpvs/bake/tile_key.h"
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

Dag bakeGrid(const BakeScene& scene, const BakeOptions& options, StageTimes* times, const ProgressFn& progress,
             TileCache* cache) {
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
  // Tiles are pipelined: while one tile's serial stages run (its insertion, its merge),
  // the next renders and compresses, so every core has work; the stages inside a tile are
  // parallel too. Merges follow the plan's order, so the bytes do not depend on timing,
  // and at most kTilesInFlight tiles' masks and sub-DAGs are held beside the merger's
  // ~log2(tiles) partial DAGs.
  constexpr size_t kTilesInFlight = 2;
  struct Baked {
    uint64_t index = 0;
    Dag dag;
    StageTimes times;
    double seconds = 0;
    std::optional<Hash128> key;  // with a cache, where it can vouch for the tile
    bool reused = false;
  };
  const auto bakeStart = std::chrono::steady_clock::now();
  double tileSeconds = 0;  // summed over tiles: more than the wall time when they overlap
  uint64_t next = 0;
  tbb::parallel_pipeline(
      kTilesInFlight,
      tbb::make_filter<void, uint64_t>(tbb::filter_mode::serial_in_order,
                                       [&](tbb::flow_control& fc) -> uint64_t {
                                         if (next == total) fc.stop();
                                         return next++;
                                       }) &
          tbb::make_filter<uint64_t, std::shared_ptr<Baked>>(
              tbb::filter_mode::parallel,
              [&](uint64_t i) {
                auto b = std::make_shared<Baked>();
                b->index = i;
                const auto start = std::chrono::steady_clock::now();
                const TileCoord tile = plan.tile(i);
                b->key = cache ? tileKey(scene, options, tile.x, tile.y) : std::nullopt;
                if (b->key)
                  if (std::optional<Dag> kept = cache->find(*b->key, tile.x, tile.y, options)) {
                    b->dag = std::move(*kept);
                    b->reused = true;
                    ++b->times.tilesReused;
                    b->seconds = secondsSince(start);
                    return b;
                  }
                // Isolated: a thread waiting inside this tile's parallel loops must not take
                // up the other tile in flight, whose stages would share its thread's scratch
                // buffers (BakeScene::columnMasks keeps its strips' texel slices and masks
                // per thread).
                tbb::this_task_arena::isolate(
                    [&] { b->dag = bakeTile(scene, tile.x, tile.y, options, &b->times); });
                b->seconds = secondsSince(start);
                return b;
              }) &
          tbb::make_filter<std::shared_ptr<Baked>, void>(tbb::filter_mode::serial_in_order, [&](std::shared_ptr<Baked> b) {
            // Stored here, not where it was baked: a tile still baking when the bake is
            // cancelled comes out cut short, and only tiles that reach this stage are whole.
            if (b->key && !b->reused) {
              const auto encodeStart = std::chrono::steady_clock::now();
              cache->store(*b->key, b->dag);
              b->times.add("encode", secondsSince(encodeStart));
            }
            st.add(b->times);
            const auto start = std::chrono::steady_clock::now();
            merger.add(std::move(b->dag));
            st.add("merge", secondsSince(start));
            if (!b->reused) tileSeconds += b->seconds;
            if (progress) {
              if (b->reused)
                eta->skipped(b->index);
              else
                eta->finished(b->index, b->seconds);
              // The fit is in one tile's seconds; tiles overlapping finish that much sooner.
              const double left = eta->secondsLeft();
              const double overlap = tileSeconds > 0 ? secondsSince(bakeStart) / tileSeconds : 1;
              if (!progress({"bake", b->index + 1, total, left < 0 ? left : left * std::min(overlap, 1.0)}))
                throw Cancelled();
            }
          }));
  auto start = std::chrono::steady_clock::now();
  Dag merged = *merger.finish();
  Dag result = assembleRoots(std::move(merged), options.hash, options.compress);
  st.add("merge", secondsSince(start));
  return result;
}

}  // namespace cpvs
