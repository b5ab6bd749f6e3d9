// Visibility masks of 8x8-texel columns (§3.4) and their min-max hierarchy (§6.1).
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/depth_maps.h"

namespace cpvs {

/// How voxels in undefined regions get a value.
enum class UndefinedRule : uint8_t {
  New = 0,  // §3.4: per 8x8 column, the fewest masks that describe the transitions
  Old = 1,  // Sintorn et al.: lit or shadowed where homogeneous, else shadowed
};

/// The resolved voxels of a block of 8x8-texel columns. Each column is a monotone
/// sequence of 64-bit masks along depth: all lit (mask 0) before its first transition,
/// then each transition (slice, mask) replaces the mask from that slice on; bits only ever
/// turn on (shadowed). Bit (ty * 8 + tx) is texel (8 cx + tx, 8 cy + ty).
/// firstShadow is the first transition's slice (R if none) and fullShadow the slice from
/// which the mask is all ones (R if never).
struct ColumnMasks {
  uint32_t columnsX = 0, columnsY = 0;
  uint32_t resolution = 0;                  // R
  std::vector<uint32_t> begin;              // columnsX * columnsY + 1, into slice/mask
  std::vector<uint32_t> slice;
  std::vector<uint64_t> mask;
  std::vector<uint32_t> firstShadow, fullShadow;

  size_t column(uint32_t cx, uint32_t cy) const { return size_t(cy) * columnsX + cx; }
  /// Mask of column c at slice k (binary search over its transitions).
  uint64_t maskAt(size_t c, uint32_t k) const;
};

/// Resolves the texel depths of a width x height block (multiples of 8) into column masks.
/// Every voxel's value satisfies its texel's classification: lit where it must be lit,
/// shadowed where it must be shadowed, and a choice by `rule` where it is undefined.
/// Depends only on each column's own texels, so the result is independent of tiling.
void buildColumnMasks(const TexelDepths& depths, uint32_t width, uint32_t height, uint32_t R,
                      UndefinedRule rule, ColumnMasks& out);

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
