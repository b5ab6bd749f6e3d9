// What decides a tile's sub-DAG, as one hash, so that a bake of an edited scene re-bakes
// only the tiles an edit reaches: the grid, every option, the rasterizer's scene-wide
// parameters (its snapping bits, tie distance and depth limit), the tile's place, and
// every triangle whose covered texels may lie in the tile, as the rasterizer holds it
// (snapped vertices, depth plane, the side the light sees, closedness), in scene order.
// A texel's column is decided by the triangles that cross it alone (the rasterizer, the
// exit count and the undefined rule look at nothing else), and a tile's insertion and
// compression by its columns, so two tiles with one key have one sub-DAG.
#pragma once

#include <cstdint>
#include <optional>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/options.h"
#include "cpvs/base/hash.h"

namespace cpvs {

/// The key of tile (tileX, tileY), or none where it cannot vouch for the tile: the Embree
/// renderer (its BVH answers for the unsnapped scene), a spot grid, declared receivers
/// (their reads are not keyed yet) and uncompressed DAGs (their bytes depend on order).
std::optional<Hash128> tileKey(const BakeScene& scene, const BakeOptions& options, uint64_t tileX, uint64_t tileY);

}  // namespace cpvs
