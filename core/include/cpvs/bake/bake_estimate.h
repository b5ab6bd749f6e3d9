// What a bake will cost before it is run, measured rather than guessed: a few of its own
// tiles are baked (from the lightest to the heaviest by the triangles that reach them,
// evenly spread), the ETA's law (tile_eta.h) is fitted to their seconds, and every tile
// is priced by it. The DAG's bytes are the sampled sub-DAGs' bytes per triangle times the
// triangles of every tile (merging then shares subtrees across tiles and adds the levels
// above them; docs/measured.md compares estimates with bakes).
#pragma once

#include <cstddef>
#include <cstdint>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/options.h"

namespace cpvs {

struct BakeEstimate {
  uint64_t tiles = 0;          // in the plan
  uint64_t renderedTiles = 0;  // of them, those triangles touch and receivers read
  size_t sampledTiles = 0;     // baked to measure (untouched tiles not counted)
  double sampleSeconds = 0;    // spent baking them
  double tileSeconds = 0;      // every tile's, one after another, on this machine
  double dagBytes = 0;         // the sub-DAGs' bytes before merging shares them
};

/// Bakes `samples` rendered tiles of `scene` (0: a quarter of them, at least 3 and at most
/// 8; never more than there are) and one untouched tile, when there is one, and prices
/// the whole bake from them.
BakeEstimate estimateBake(const BakeScene& scene, const BakeOptions& options, size_t samples = 0);

}  // namespace cpvs
