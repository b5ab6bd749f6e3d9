// A whole bake in one process: tiles rendered, inserted, compressed, merged, assembled.
#pragma once

#include <cstdint>
#include <functional>
#include <vector>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/options.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/progress.h"
#include "cpvs/dag/dag.h"

namespace cpvs {

class TileCache;

/// Bakes one tile column: renders its texel depths, resolves the 8x8 column masks,
/// inserts the voxels and compresses the result into a sub-DAG with hashes whose roots are
/// the tile's blocks (R / T of them). A tile nothing touches is not rendered: its masks
/// are all lit, which is what rendering it would give. What a farm worker runs for one
/// tile job. options.renderer must be the scene's.
Dag bakeTile(const BakeScene& scene, uint64_t tileX, uint64_t tileY, const BakeOptions& options,
             StageTimes* times = nullptr);

/// The sub-DAG of a tile no triangle touches (BakeScene::touchesTile is false): all lit,
/// the bytes bakeTile gives it, made without the scene or the grid (of any light kind).
/// What the farm's coordinator merges for such tiles instead of leasing them.
Dag bakeUntouchedTile(int log2Resolution, uint64_t tileX, uint64_t tileY, const BakeOptions& options,
                      StageTimes* times = nullptr);

/// Per tile of `plan`, in its order, the triangles that reach it
/// (RasterScene::trianglesTouching; at least 1 for a tile that is rendered), 0 for a tile
/// that is not (BakeScene::touchesTile): the work TileEta weighs tiles by.
std::vector<uint32_t> tileWork(const BakeScene& scene, const TilePlan& plan);
/// The same from a projection and which tiles are rendered (by index in `plan`'s order),
/// for a planner that classified them (BakePlan::tileClasses).
std::vector<uint32_t> tileWork(const RasterScene& raster, const TilePlan& plan,
                               const std::function<bool(uint64_t tile)>& rendered);

/// Bakes the whole grid: every tile (bakeTile), merged in the plan's order as they
/// complete (StreamingMerger), then the levels above the tile roots. Tiles are pipelined,
/// two in flight, each stage inside parallel too; the bytes do not depend on it. Throws
/// Cancelled when `progress` returns false; its reports carry the seconds left as TileEta
/// estimates them from the tiles done. With a `cache`, a tile whose key (tile_key.h) is
/// there is taken from it instead of baked, and every tile baked is stored (times's
/// tilesReused counts the first).
Dag bakeGrid(const BakeScene& scene, const BakeOptions& options, StageTimes* times = nullptr,
             const ProgressFn& progress = nullptr, TileCache* cache = nullptr);

}  // namespace cpvs
