// A whole bake in one process: tiles rendered, inserted, compressed, merged, assembled.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "cpvs/dag.h"
#include "cpvs/dag_builder.h"
#include "cpvs/dag_compress.h"
#include "cpvs/depth_maps.h"
#include "cpvs/light_frame.h"
#include "cpvs/ray_scene.h"
#include "cpvs/tile_masks.h"

namespace cpvs {

/// Everything that decides the bytes of a bake besides the scene, light and resolution.
struct BakeOptions {
  ClosedMode closed = ClosedMode::Auto;
  ExitMode exit = ExitMode::Exact;
  bool cull = true;
  CompressMode compress = CompressMode::TopDown;
  UndefinedRule undefinedRule = UndefinedRule::New;
  int log2TileSize = 12;  // 4096 texels
  HashKind hash = HashKind::Xxh3;
};

/// Names of the stages, in pipeline order; stage times are keyed by them.
inline const std::vector<std::string>& bakeStageNames() {
  static const std::vector<std::string> names{"render", "masks", "insert", "compress", "merge", "write"};
  return names;
}

/// Wall-clock seconds spent per stage (summed over tiles), and insertion counters.
struct StageTimes {
  std::map<std::string, double> seconds;
  InsertStats insert;
  void add(const std::string& stage, double s) { seconds[stage] += s; }
  void merge(const StageTimes& o);
};

/// Progress of long work: stage name, units done, units total. Return false to cancel.
using ProgressFn = std::function<bool(const std::string& stage, uint64_t done, uint64_t total)>;

/// Number of tile columns per side for a grid (1 when R <= tile size).
uint64_t tilesPerSide(int log2Resolution, int log2TileSize);

/// Bakes one tile column: renders its texel depths, resolves the 8x8 column masks,
/// inserts the voxels and compresses the result into a sub-DAG with hashes whose roots are
/// the tile's blocks (R / T of them). What a farm worker runs for one tile job.
Dag bakeTile(const RayScene& rays, const Grid& grid, uint64_t tileX, uint64_t tileY,
             const BakeOptions& options, StageTimes* times = nullptr);

/// Bakes the whole grid: every tile (bakeTile), merged as they complete (StreamingMerger),
/// then the levels above the tile roots. Tiles run one after another, each stage inside
/// parallel (two tiles at once were measured slower on two cores: 6.6 s against 5.2 s for
/// the city at 8K). Throws Cancelled when `progress` returns false.
Dag bakeGrid(const RayScene& rays, const Grid& grid, const BakeOptions& options,
             StageTimes* times = nullptr, const ProgressFn& progress = nullptr);

/// Seconds since `start`, for stage timing.
inline double secondsSince(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace cpvs
