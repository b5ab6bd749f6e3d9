#include "cpvs/bake/bake_dag_mh.h"

#include <chrono>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/base/error.h"

namespace cpvs {

void sliceIntervals(const TexelSlices& slices, uint64_t x0, uint64_t y0, uint32_t width, uint32_t height,
                    TexelIntervals& map) {
  CPVS_CHECK(slices.firstUndefined.size() == size_t(width) * height && x0 + width <= map.side && y0 + height <= map.side);
  for (uint32_t y = 0; y < height; ++y)
    for (uint32_t x = 0; x < width; ++x) {
      const size_t from = size_t(y) * width + x, to = (y0 + y) * map.side + x0 + x;
      const uint32_t shadowed = slices.firstShadowed[from];
      map.lo[to] = float(slices.firstUndefined[from]);
      map.hi[to] = shadowed >= map.side ? kNoCasterDepth : float(shadowed);
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

  const uint32_t R = uint32_t(grid.resolution());
  TexelIntervals map;
  map.side = R;
  map.lo.resize(map.texels());
  map.hi.resize(map.texels());
  // Bands of rows, so that progress moves and cancelling is prompt.
  const uint32_t band = std::min<uint32_t>(R, 256);
  TexelSlices slices;
  for (uint32_t y = 0; y < R; y += band) {
    start = std::chrono::steady_clock::now();
    rasterTexelSlices(prepared.raster(), options.closed, options.exit, 0, y, R, band, slices);
    st.add("render", secondsSince(start));
    start = std::chrono::steady_clock::now();
    prepared.receivers().freeIntervals(0, y, R, band, slices);
    sliceIntervals(slices, 0, y, R, band, map);
    st.add("receivers", secondsSince(start));
    if (progress && !progress({"render", y / band + 1, R / band})) throw Cancelled();
  }

  start = std::chrono::steady_clock::now();
  const Mh mh(std::move(map));
  st.add("hierarchy", secondsSince(start));
  start = std::chrono::steady_clock::now();
  DagMh dag = encodeDagMh(mh);
  st.add("compress", secondsSince(start));
  return dag;
}

}  // namespace cpvs
