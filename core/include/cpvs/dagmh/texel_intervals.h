// A dual-depth shadow map before compression: per texel, the depths any of which gives
// the same shadows (seed 001 §3; which interval a bake takes: NOTES §2.2.1).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cpvs {

/// Per texel of a side x side map (row-major), the interval [lo, hi] of depths, in the
/// light grid's slices, that a lookup may compare against: a voxel at slice k is shadowed
/// when k >= the stored depth, so the slices below lo are lit, those from hi on shadowed. lo <= hi, both finite; a texel nothing covers has
/// [R, kNoCasterDepth] (R the grid's slices).
struct TexelIntervals {
  uint32_t side = 0;
  std::vector<float> lo, hi;

  size_t texels() const { return size_t(side) * side; }
};

/// The upper end of a texel nothing covers: behind every point.
constexpr float kNoCasterDepth = 3.0e38f;

}  // namespace cpvs
