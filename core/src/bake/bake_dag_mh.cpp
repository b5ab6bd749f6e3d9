#include "cpvs/bake/bake_dag_mh.h"

#include <chrono>

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
  TexelSlices slices;
  TexelIntervals tile;
  tile.side = side;
  tile.lo.resize(tile.texels());
  tile.hi.resize(tile.texels());
  Mh mh;  // one tile's, its storage reused by the next
  for (uint32_t ty = 0; ty < tilesPerSide; ++ty)
    for (uint32_t tx = 0; tx < tilesPerSide; ++tx) {
      const uint64_t x0 = uint64_t(tx) * side, y0 = uint64_t(ty) * side;
      if (prepared.touchesTile(tx, ty, log2Tile)) {
        start = std::chrono::steady_clock::now();
        rasterTexelSlices(prepared.raster(), options.closed, options.exit, x0, y0, side, side, slices);
        st.add("render", secondsSince(start));
        start = std::chrono::steady_clock::now();
        prepared.receivers().freeIntervals(x0, y0, side, side, slices);
        sliceIntervals(slices, uint32_t(grid.resolution()), 0, 0, side, side, tile);
        st.add("receivers", secondsSince(start));
      } else {  // nothing casts there, or nothing reads it: all lit, as rendering it gives
        ++st.tilesSkipped;
        std::fill(tile.lo.begin(), tile.lo.end(), float(grid.resolution()));
        std::fill(tile.hi.begin(), tile.hi.end(), kNoCasterDepth);
      }
      start = std::chrono::steady_clock::now();
      mh.rebuild(tile);
      st.add("hierarchy", secondsSince(start));
      start = std::chrono::steady_clock::now();
      builder.addTile(tx, ty, mh);
      st.add("compress", secondsSince(start));
      if (progress && !progress({"tiles", uint64_t(ty) * tilesPerSide + tx + 1, uint64_t(tilesPerSide) * tilesPerSide}))
        throw Cancelled();
    }
  start = std::chrono::steady_clock::now();
  DagMh dag = builder.finish();
  st.add("compress", secondsSince(start));
  return dag;
}

}  // namespace cpvs
