#include "cpvs/bake/min_max_pyramid.h"

#include <algorithm>

namespace cpvs {

void buildMinMaxPyramid(const ColumnMasks& masks, MinMaxPyramid& out) {
  out.levels.clear();
  MinMaxPyramid::Level base;
  base.width = masks.columnsX;
  base.height = masks.columnsY;
  base.minFirst = masks.firstShadow;
  base.maxFull = masks.fullShadow;
  out.levels.push_back(std::move(base));
  while (out.levels.back().width > 1 || out.levels.back().height > 1) {
    const auto& below = out.levels.back();
    MinMaxPyramid::Level up;
    up.width = std::max(1u, below.width / 2);
    up.height = std::max(1u, below.height / 2);
    up.minFirst.assign(size_t(up.width) * up.height, masks.resolution);
    up.maxFull.assign(size_t(up.width) * up.height, 0);
    for (uint32_t y = 0; y < below.height; ++y)
      for (uint32_t x = 0; x < below.width; ++x) {
        size_t from = size_t(y) * below.width + x, to = size_t(y / 2) * up.width + x / 2;
        up.minFirst[to] = std::min(up.minFirst[to], below.minFirst[from]);
        up.maxFull[to] = std::max(up.maxFull[to], below.maxFull[from]);
      }
    out.levels.push_back(std::move(up));
  }
}

}  // namespace cpvs
