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

namespace {

// What a tile nothing casts on, or no receiver reads, holds: all lit, as rendering it gives.
void fillLit(TexelIntervals& tile, uint64_t resolution) {
  std::fill(tile.lo.begin(), tile.lo.end(), float(resolution));
  std::fill(tile.hi.begin(), tile.hi.end(), kNoCasterDepth);
}

// A farm tile's place and the side of its parts; InputError for a tile outside the grid.
struct FarmTile {
  int log2Farm, log2Part;
  uint32_t partsPerSide;
};
FarmTile farmTileOf(int log2Resolution, int log2FarmTile, uint64_t tileX, uint64_t tileY) {
  FarmTile f;
  f.log2Farm = std::min(log2Resolution, log2FarmTile);
  f.log2Part = dagMhPartLog2(log2Resolution, log2FarmTile);
  f.partsPerSide = 1u << (f.log2Farm - f.log2Part);
  const uint64_t perSide = uint64_t(1) << (log2Resolution - f.log2Farm);
  if (tileX >= perSide || tileY >= perSide)
    throw InputError("tile " + std::to_string(tileX) + "," + std::to_string(tileY) + " lies outside a grid of " +
                     std::to_string(uint64_t(1) << log2Resolution));
  return f;
}

}  // namespace

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
                } else {  // nothing casts there, or nothing reads it
                  ++w->times.tilesSkipped;
                  fillLit(w->tile, grid.resolution());
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

DagMhTileShape dagMhFarmTileShape(int log2Resolution, int log2FarmTile) {
  const FarmTile f = farmTileOf(log2Resolution, log2FarmTile, 0, 0);
  return {log2Resolution, f.log2Part, f.partsPerSide * f.partsPerSide};
}

std::vector<DagMhTile> bakeDagMhFarmTile(const BakeScene& prepared, const BakeOptions& options, uint64_t tileX,
                                         uint64_t tileY, StageTimes* times) {
  const FarmTile f = farmTileOf(prepared.grid().log2Resolution, options.log2TileSize, tileX, tileY);
  std::vector<DagMhTile> parts;
  StageTimes local;
  bakeDagMhTiles(prepared, options, f.log2Part, tileX * f.partsPerSide, tileY * f.partsPerSide, f.partsPerSide,
                 [&](DagMhTile&& p) { parts.push_back(std::move(p)); }, times ? *times : local, nullptr);
  return parts;
}

std::vector<DagMhTile> litDagMhFarmTile(int log2Resolution, int log2FarmTile, uint64_t tileX, uint64_t tileY) {
  const FarmTile f = farmTileOf(log2Resolution, log2FarmTile, tileX, tileY);
  TexelIntervals lit;
  lit.side = 1u << f.log2Part;
  lit.lo.resize(lit.texels());
  lit.hi.resize(lit.texels());
  fillLit(lit, uint64_t(1) << log2Resolution);
  const Mh mh(lit);
  std::vector<DagMhTile> parts;
  for (uint32_t y = 0; y < f.partsPerSide; ++y)
    for (uint32_t x = 0; x < f.partsPerSide; ++x)
      parts.push_back(dagMhTile(log2Resolution, tileX * f.partsPerSide + x, tileY * f.partsPerSide + y, mh));
  return parts;
}

void checkDagMhFarmTile(const std::vector<DagMhTile>& parts, int log2Resolution, int log2FarmTile, uint64_t tileX,
                        uint64_t tileY, const std::string& source) {
  const FarmTile f = farmTileOf(log2Resolution, log2FarmTile, tileX, tileY);
  if (parts.size() != size_t(f.partsPerSide) * f.partsPerSide)
    throw InputError(source + ": " + std::to_string(parts.size()) + " DAG-MH parts where the tile has " +
                     std::to_string(size_t(f.partsPerSide) * f.partsPerSide));
  std::vector<uint8_t> seen(parts.size(), 0);
  for (const DagMhTile& p : parts) {
    const uint64_t x = p.tileX - tileX * f.partsPerSide, y = p.tileY - tileY * f.partsPerSide;
    if (p.log2Side != log2Resolution || p.log2TileSide != f.log2Part || p.tileX < tileX * f.partsPerSide ||
        p.tileY < tileY * f.partsPerSide || x >= f.partsPerSide || y >= f.partsPerSide || seen[y * f.partsPerSide + x]++)
      throw InputError(source + ": a DAG-MH part " + std::to_string(p.tileX) + "," + std::to_string(p.tileY) + " of 2^" +
                       std::to_string(p.log2TileSide) + " texels in a map of 2^" + std::to_string(p.log2Side) +
                       " is not one of this tile's, or comes twice");
  }
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
