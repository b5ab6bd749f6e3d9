#include "cpvs/bake/bake_dag_mh.h"

#include <tbb/parallel_pipeline.h>

#include <algorithm>
#include <chrono>
#include <vector>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/base/error.h"

namespace cpvs {

void sliceIntervals(const TexelSlices& slices, uint32_t slicesPerColumn, uint64_t x0, uint64_t y0, uint32_t width,
                    uint32_t height, TexelIntervals& map) {
  CPVS_CHECK(slices.firstUndefined.size() == size_t(width) * height && x0 + width <= map.side && y0 + height <= map.side);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) {
      const size_t from = size_t(y) * width + x, to = (y0 + y) * map.side + x0 + x;
      const uint32_t shadowed = slices.firstShadowed[from];
      map.lo[to] = float(slices.firstUndefined[from]);
      map.hi[to] = shadowed >= slicesPerColumn ? kNoCasterDepth : float(shadowed);
    }
}

int dagMhPartLog2(int log2Resolution, int log2FarmTile) {
  return std::min({log2Resolution, log2FarmTile, kLog2DagMhTileSide});
}

void bakeDagMhTiles(const BakeScene& prepared, const BakeOptions& options, int log2Tile, uint64_t firstX,
                    uint64_t firstY, uint32_t tilesPerSide, const std::function<void(DagMhTile&&)>& take,
                    StageTimes& st, const ProgressFn& progress) {
  const OrthoGrid& grid = prepared.grid();
  const uint32_t side = 1u << log2Tile;
  CPVS_CHECK(log2Tile <= grid.log2Resolution && (firstX + tilesPerSide) << log2Tile <= grid.resolution() &&
             (firstY + tilesPerSide) << log2Tile <= grid.resolution());
  // Two tiles in flight: one rendered, its hierarchy built and its shapes gathered
  // (parallel inside) while the one before is handed on, in order (so the bytes are the
  // sequential ones). Each in-flight tile has its own buffers, reused by the tiles after it.
  struct Work {
    uint64_t tx = 0, ty = 0;
    TexelSlices slices;
    TexelIntervals tile;
    Mh mh;
    DagMhTile part;
    StageTimes times;
  };
  constexpr size_t kInFlight = 2;
  std::vector<Work> works(kInFlight);
  for (Work& w : works) {
    w.tile.side = side;
    w.tile.lo.resize(w.tile.texels());
    w.tile.hi.resize(w.tile.texels());
  }
  const uint64_t tiles = uint64_t(tilesPerSide) * tilesPerSide;
  uint64_t next = 0, handed = 0;
  tbb::parallel_pipeline(
      kInFlight,
      tbb::make_filter<void, Work*>(tbb::filter_mode::serial_in_order,
                                    [&](tbb::flow_control& fc) -> Work* {
                                      if (next == tiles) {
                                        fc.stop();
                                        return nullptr;
                                      }
                                      Work* w = &works[next % kInFlight];
                                      w->tx = firstX + next % tilesPerSide;
                                      w->ty = firstY + next / tilesPerSide;
                                      ++next;
                                      return w;
                                    }) &
          tbb::make_filter<Work*, Work*>(
              tbb::filter_mode::parallel,
              [&](Work* w) {
                const uint64_t x0 = w->tx * side, y0 = w->ty * side;
                auto start = std::chrono::steady_clock::now();
                if (prepared.touchesTile(w->tx, w->ty, log2Tile)) {
                  rasterTexelSlices(prepared.raster(), options.closed, options.exit, x0, y0, side, side, w->slices);
                  w->times.add("render", secondsSince(start));
                  start = std::chrono::steady_clock::now();
                  prepared.receivers().freeIntervals(x0, y0, side, side, w->slices);
                  sliceIntervals(w->slices, uint32_t(grid.resolution()), 0, 0, side, side, w->tile);
                  w->times.add("receivers", secondsSince(start));
                } else {  // nothing casts there, or nothing reads it: all lit, as rendering it gives
                  ++w->times.tilesSkipped;
                  std::fill(w->tile.lo.begin(), w->tile.lo.end(), float(grid.resolution()));
                  std::fill(w->tile.hi.begin(), w->tile.hi.end(), kNoCasterDepth);
                }
                start = std::chrono::steady_clock::now();
                w->mh.rebuild(w->tile);
                w->times.add("hierarchy", secondsSince(start));
                start = std::chrono::steady_clock::now();
                w->part = dagMhTile(grid.log2Resolution, w->tx, w->ty, w->mh);
                w->times.add("compress", secondsSince(start));
                return w;
              }) &
          tbb::make_filter<Work*, void>(tbb::filter_mode::serial_in_order, [&](Work* w) {
            take(std::move(w->part));
            ++handed;
            if (progress && !progress({"tiles", handed, tiles})) throw Cancelled();
          }));
  for (const Work& w : works) st.add(w.times);
}

std::vector<DagMhTile> bakeDagMhFarmTile(const BakeScene& prepared, const BakeOptions& options, uint64_t tileX,
                                         uint64_t tileY, StageTimes* times) {
  const OrthoGrid& grid = prepared.grid();
  const int log2Farm = std::min(grid.log2Resolution, options.log2TileSize);
  const int log2Part = dagMhPartLog2(grid.log2Resolution, options.log2TileSize);
  if (((tileX + 1) << log2Farm) > grid.resolution() || ((tileY + 1) << log2Farm) > grid.resolution())
    throw InputError("tile " + std::to_string(tileX) + "," + std::to_string(tileY) + " lies outside a grid of " +
                     std::to_string(grid.resolution()));
  const uint32_t perSide = 1u << (log2Farm - log2Part);
  std::vector<DagMhTile> parts;
  StageTimes local;
  bakeDagMhTiles(prepared, options, log2Part, tileX * perSide, tileY * perSide, perSide,
                 [&](DagMhTile&& p) { parts.push_back(std::move(p)); }, times ? *times : local, nullptr);
  return parts;
}

DagMh bakeDagMh(const Scene& scene, const OrthoGrid& grid, const BakeOptions& options,
                const ReceiverDeclaration& receivers, int threads, StageTimes* times, const ProgressFn& progress) {
  if (grid.log2Resolution > kMaxLog2DagMhResolution)
    throw InputError("a DAG-MH is baked up to " + std::to_string(1u << kMaxLog2DagMhResolution) + " texels a side, not " +
                     std::to_string(grid.resolution()));
  if (grid.depthSlices != 0) throw InputError("a DAG-MH's grid is cubic: no depth slices");
  StageTimes local;
  StageTimes& st = times ? *times : local;
  auto start = std::chrono::steady_clock::now();
  const BakeScene prepared(scene, grid, Renderer::Raster, threads, receivers);
  st.add("load", secondsSince(start));

  // Tile by tile (the hierarchy of a tile depends only on its texels): the memory of one
  // tile's intervals and hierarchy, whatever the resolution.
  const int log2Tile = std::min(grid.log2Resolution, kLog2DagMhTileSide);
  DagMhBuilder builder(grid.log2Resolution, log2Tile);
  double merging = 0;
  bakeDagMhTiles(prepared, options, log2Tile, 0, 0, uint32_t(grid.resolution() >> log2Tile),
                 [&](DagMhTile&& part) {
                   const auto start = std::chrono::steady_clock::now();
                   builder.addTile(std::move(part));
                   merging += secondsSince(start);
                 },
                 st, progress);
  st.add("compress", merging);
  start = std::chrono::steady_clock::now();
  DagMh dag = builder.finish();
  st.add("compress", secondsSince(start));
  return dag;
}

}  // namespace cpvs
