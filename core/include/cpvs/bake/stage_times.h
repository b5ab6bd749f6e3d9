// The stages of a bake and the time spent in each.
#pragma once

#include <array>
#include <map>
#include <span>
#include <string>
#include <string_view>

#include "cpvs/bake/insert_tile.h"

namespace cpvs {

/// Every stage any process reports, in pipeline order: the one list that stage times,
/// summaries and reports are keyed by. "load" (scene and BVH), "cameras" (sampled camera
/// visibility) and "write" belong to the command line, "encode" (a tile's sub-DAG bytes)
/// to a farm worker, "hierarchy" (a DAG-MH's MH) to a DAG-MH bake, "translucent" (the TOP tree of translucent casters) to the command
/// line and the coordinator.
inline constexpr std::array<const char*, 12> kStageNames{"load",  "cameras",     "render", "receivers", "masks", "insert",
                                                         "compress", "merge", "hierarchy", "translucent", "encode", "write"};
/// The stages bakeGrid reports: render .. merge.
inline constexpr std::span<const char* const> kBakeGridStages{kStageNames.data() + 2, 6};

/// True when `name` is in kStageNames.
bool isStageName(std::string_view name);

/// Wall-clock seconds spent per stage (summed over tiles), and insertion counters.
struct StageTimes {
  std::map<std::string, double> seconds;
  InsertStats insert;
  /// Tiles that needed no rendering: no triangle touches them, or no receiver reads them.
  uint64_t tilesSkipped = 0;
  /// Tiles taken from a tile cache (tile_cache.h) instead of baked.
  uint64_t tilesReused = 0;
  /// Adds `s` seconds to a stage of kStageNames (an unknown name is a bug: CPVS_CHECK).
  void add(const std::string& stage, double s);
  /// Adds everything another bake's times hold (grids baked side by side: their
  /// seconds add up to more than the wall time).
  void add(const StageTimes& other);
};

}  // namespace cpvs
