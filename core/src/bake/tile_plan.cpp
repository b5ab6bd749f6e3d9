#include "cpvs/bake/tile_plan.h"

#include <algorithm>

#include "cpvs/base/error.h"

namespace cpvs {

TilePlan::TilePlan(int log2Resolution, int log2TileSize)
    : log2Resolution_(log2Resolution), log2TileSize_(std::min(log2TileSize, log2Resolution)) {
  CPVS_CHECK(log2TileSize >= 3 && log2Resolution >= 3);
}

GridTiles::GridTiles(const std::vector<int>& log2Resolutions, int log2TileSize) : first_{0} {
  for (int log2R : log2Resolutions) {
    plans_.emplace_back(log2R, log2TileSize);
    first_.push_back(first_.back() + plans_.back().count());
  }
}

GridTiles::At GridTiles::at(uint64_t index) const {
  CPVS_CHECK(index < count());
  const size_t k = size_t(std::upper_bound(first_.begin(), first_.end(), index) - first_.begin()) - 1;
  return {uint32_t(k), plans_[k].tile(index - first_[k])};
}

}  // namespace cpvs
