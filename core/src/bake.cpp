#include "cpvs/bake.h"

#include <algorithm>
#include <mutex>

#include "cpvs/dag_builder.h"
#include "cpvs/dag_merge.h"

namespace cpvs {

void StageTimes::merge(const StageTimes& o) {
  for (const auto& [k, v] : o.seconds) seconds[k] += v;
  insert.nodesCreated += o.insert.nodesCreated;
  insert.leavesCreated += o.insert.leavesCreated;
  insert.culledNodes += o.insert.culledNodes;
  insert.culledLeaves += o.insert.culledLeaves;
}

uint64_t tilesPerSide(int log2Resolution, int log2TileSize) {
  return log2TileSize >= log2Resolution ? 1 : uint64_t(1) << (log2Resolution - log2TileSize);
}

Dag bakeTile(const RayScene& rays, const Grid& grid, uint64_t tileX, uint64_t tileY,
             const BakeOptions& options, StageTimes* times) {
  StageTimes local;
  StageTimes& st = times ? *times : local;
  const int t = std::min(options.log2TileSize, grid.log2Resolution);
  const uint32_t T = uint32_t(1) << t;
  const uint32_t R = uint32_t(grid.resolution());

  auto start = std::chrono::steady_clock::now();
  TexelDepths depths;
  renderTexelDepths(rays, grid, options.closed, options.exit, tileX * T, tileY * T, T, T, depths);
  st.add("render", secondsSince(start));

  start = std::chrono::steady_clock::now();
  ColumnMasks masks;
  buildColumnMasks(depths, T, T, R, options.undefinedRule, masks);
  depths = TexelDepths{};
  MinMaxPyramid pyramid;
  buildMinMaxPyramid(masks, pyramid);
  st.add("masks", secondsSince(start));

  start = std::chrono::steady_clock::now();
  Dag dag;
  insertTile(masks, pyramid, grid.log2Resolution, t, tileX, tileY, options.cull, dag, &st.insert);
  st.add("insert", secondsSince(start));

  start = std::chrono::steady_clock::now();
  if (options.compress != CompressMode::None) {
    computeHashes(dag, options.hash);
    dag = compressDag(std::move(dag), options.compress);
  }
  st.add("compress", secondsSince(start));
  return dag;
}

Dag bakeGrid(const RayScene& rays, const Grid& grid, const BakeOptions& options, StageTimes* times,
             const ProgressFn& progress) {
  StageTimes local;
  StageTimes& st = times ? *times : local;
  const uint64_t n = tilesPerSide(grid.log2Resolution, options.log2TileSize);
  const uint64_t total = n * n;
  StreamingMerger merger(options.compress);
  if (progress && !progress("bake", 0, total)) throw Cancelled();
  // Tiles run one after another; each stage inside a tile is parallel. Merges happen as
  // tiles complete, so at most ~log2(tiles) partial DAGs are held.
  for (uint64_t i = 0; i < total; ++i) {
    uint64_t tx = i % n, ty = i / n;
    Dag sub = bakeTile(rays, grid, tx, ty, options, &st);
    auto start = std::chrono::steady_clock::now();
    merger.add(std::move(sub));
    st.add("merge", secondsSince(start));
    if (progress && !progress("bake", i + 1, total)) throw Cancelled();
  }
  auto start = std::chrono::steady_clock::now();
  Dag merged = *merger.finish();
  Dag result = assembleRoots(std::move(merged), options.hash, options.compress);
  st.add("merge", secondsSince(start));
  return result;
}

}  // namespace cpvs
