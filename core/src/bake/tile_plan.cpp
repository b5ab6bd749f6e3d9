#include "cpvs/bake/tile_plan.h"

#include <algorithm>

#include "cpvs/base/error.h"

namespace cpvs {

TilePlan::TilePlan(int log2Resolution, int log2TileSize)
    : log2Resolution_(log2Resolution), log2TileSize_(std::min(log2TileSize, log2Resolution)) {
  CPVS_CHECK(log2TileSize >= 3 && log2Resolution >= 3);
}

}  // namespace cpvs
