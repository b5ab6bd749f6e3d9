// A DAG-MH bake in one process (seed 001): per texel the depths a stored depth may take,
// the MH, the DAG of its shapes and its chunked values.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/options.h"
#include "cpvs/bake/receivers.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/base/progress.h"
#include "cpvs/dagmh/dag_mh.h"
#include "cpvs/dagmh/texel_intervals.h"
#include "cpvs/io/dmh_tile_file.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/scene.h"

namespace cpvs {

/// The largest DAG-MH a bake makes (its values and shapes are held until the end).
constexpr int kMaxLog2DagMhResolution = 16;
/// Texels a side of the tiles a bake builds the hierarchy in, one at a time.
constexpr int kLog2DagMhTileSide = 9;

/// A texel's classification (after the receivers freed what no lookup reads) as the depths
/// a DAG-MH may store: [firstUndefined, firstShadowed], or up to kNoCasterDepth for a
/// column with no shadowed voxel (firstShadowed = slicesPerColumn, the grid's resolution).
/// A lookup whose voxel is at slice k is shadowed when
/// k >= the stored depth, so any depth in it answers every defined voxel as the CPVS of
/// the same classification: lit below firstUndefined, shadowed from firstShadowed.
/// `slices` holds texels [x0, x0 + width) x [y0, y0 + height) of `map`.
void sliceIntervals(const TexelSlices& slices, uint32_t slicesPerColumn, uint64_t x0, uint64_t y0, uint32_t width,
                    uint32_t height, TexelIntervals& map);

/// log2 of the side of the tiles (DagMhTile) a farm tile of 2^log2FarmTile is baked in:
/// kLog2DagMhTileSide, or less in a smaller grid or farm tile.
int dagMhPartLog2(int log2Resolution, int log2FarmTile);

/// Bakes the tiles of 2^log2Tile texels [firstX, firstX + tilesPerSide) x [firstY, ...)
/// (in tiles) of `prepared`'s grid (prepared for the raster renderer) and hands their
/// parts to `take` in row order: each rendered, freed, its hierarchy built and its shapes
/// gathered ("render", "receivers", "hierarchy", "compress" into `times`), two at a time.
/// Progress is reported per tile ("tiles").
void bakeDagMhTiles(const BakeScene& prepared, const BakeOptions& options, int log2Tile, uint64_t firstX,
                    uint64_t firstY, uint32_t tilesPerSide, const std::function<void(DagMhTile&&)>& take,
                    StageTimes& times, const ProgressFn& progress);

/// A farm worker's share of a DAG-MH job: the parts of farm tile (tileX, tileY) (of
/// options.log2TileSize texels a side), in tiles of dagMhPartLog2, for the coordinator's
/// DagMhBuilder. InputError for a tile outside the grid.
std::vector<DagMhTile> bakeDagMhFarmTile(const BakeScene& prepared, const BakeOptions& options, uint64_t tileX,
                                         uint64_t tileY, StageTimes* times = nullptr);

/// The parts every farm tile of 2^log2FarmTile texels has in a grid of 2^log2Resolution:
/// what a coordinator expects of a worker's result (decodeDagMhTiles).
DagMhTileShape dagMhFarmTileShape(int log2Resolution, int log2FarmTile);

/// The parts of a farm tile nothing casts on or no receiver reads (a farm's plan marks
/// them): all lit, as bakeDagMhFarmTile makes them without rendering.
std::vector<DagMhTile> litDagMhFarmTile(int log2Resolution, int log2FarmTile, uint64_t tileX, uint64_t tileY);

/// InputError naming `source` unless `parts` are exactly farm tile (tileX, tileY)'s, each
/// once (what a coordinator checks of a worker's result; validateDagMhTile checks each).
void checkDagMhFarmTile(const std::vector<DagMhTile>& parts, int log2Resolution, int log2FarmTile, uint64_t tileX,
                        uint64_t tileY, const std::string& source);

/// Bakes the sun's DAG-MH over `grid` (cubic, 2^3 to 2^kMaxLog2DagMhResolution texels a
/// side), tile by tile (DagMhBuilder, tiles of 2^kLog2DagMhTileSide): the scene's opaque
/// casters rasterized (rasterTexelSlices with options.closed and options.exit; "render"),
/// the voxels no declared receiver reads freed (ReceiverSet::freeIntervals) and
/// sliceIntervals ("receivers"), the tile's hierarchy ("hierarchy") and its shapes merged
/// ("compress", with the levels above the tiles and the values at the end), timed into
/// `times`; a tile nothing casts on or no receiver reads is all lit, not rendered
/// (times->tilesSkipped). Progress is reported per tile ("tiles"). Its lookups answer
/// every voxel the receivers read as the CPVS of the same scene, grid and receivers. The
/// same bytes for any thread count. InputError for what it cannot bake; Cancelled when
/// `progress` returns false.
DagMh bakeDagMh(const Scene& scene, const OrthoGrid& grid, const BakeOptions& options,
                const ReceiverDeclaration& receivers = {}, int threads = 0, StageTimes* times = nullptr,
                const ProgressFn& progress = nullptr);

}  // namespace cpvs
