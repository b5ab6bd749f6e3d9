#include "cpvs/bake/bake_dag_mh.h"

#include <tbb/parallel_pipeline.h>

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
  const uint32_t side = 1u << log2Tile, tilesPerSide = uint32_t(grid.resolution() >> log2Tile);
  DagMhBuilder builder(grid.log2Resolution, log2Tile);
  // Two tiles in flight: one rendered and its hierarchy built (parallel inside) while the
  // one before is merged into the builder, in order (so the bytes are the sequential
  // ones). Each in-flight tile has its own buffers, reused by the tiles after it.
  struct Work {
    uint32_t tx = 0, ty = 0;
    TexelSlices slices;
    TexelIntervals tile;
    Mh mh;
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
  uint64_t next = 0, merged = 0;
  tbb::parallel_pipeline(
      kInFlight,
      tbb::make_filter<void, Work*>(tbb::filter_mode::serial_in_order,
                                    [&](tbb::flow_control& fc) -> Work* {
                                      if (next == tiles) {
                                        fc.stop();
                                        return nullptr;
                                      }
                                      Work* w = &works[next % kInFlight];
                                      w->tx = uint32_t(next % tilesPerSide);
                                      w->ty = uint32_t(next / tilesPerSide);
                                      ++next;
                                      return w;
                                    }) &
          tbb::make_filter<Work*, Work*>(
              tbb::filter_mode::parallel,
              [&](Work* w) {
                const uint64_t x0 = uint64_t(w->tx) * side, y0 = uint64_t(w->ty) * side;
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
                return w;
              }) &
          tbb::make_filter<Work*, void>(tbb::filter_mode::serial_in_order, [&](Work* w) {
            const auto start = std::chrono::steady_clock::now();
            builder.addTile(w->tx, w->ty, w->mh);
            w->times.add("compress", secondsSince(start));
            ++merged;
            if (progress && !progress({"tiles", merged, tiles})) throw Cancelled();
          }));
  for (const Work& w : works) st.add(w.times);
  start = std::chrono::steady_clock::now();
  DagMh dag = builder.finish();
  st.add("compress", secondsSince(start));
  return dag;
}

}  // namespace cpvs
