// The min-max hierarchy over column masks (§6.1): which blocks are all lit or all shadowed.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/bake/column_masks.h"

namespace cpvs {

/// The min-max hierarchy over columns: level j covers 2^j x 2^j columns (blocks of
/// 2^(j+3) texels) with the least firstShadow and the greatest fullShadow inside. A block
/// of voxels is all lit iff its depth range ends at or before minFirst, and all shadowed
/// iff it starts at or after maxFull: the test is exact for the resolved voxels.
struct MinMaxPyramid {
  struct Level {
    uint32_t width = 0, height = 0;
    std::vector<uint32_t> minFirst, maxFull;
  };
  std::vector<Level> levels;  // levels[0] = one entry per column
};

void buildMinMaxPyramid(const ColumnMasks& masks, MinMaxPyramid& out);

}  // namespace cpvs
