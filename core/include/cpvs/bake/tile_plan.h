// Which tiles a bake of a grid has and in what order: shared by the local bake and the
// coordinator, so that both enumerate the same tiles and give the same bytes.
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

namespace cpvs {

/// A tile: a column of T x T texels through the whole depth, at tile coordinates (x, y).
struct TileCoord {
  uint64_t x = 0, y = 0;
};

/// The tiles of a grid of 2^log2Resolution for tiles of 2^log2TileSize texels (a tile
/// larger than the grid is the whole grid). Tiles are numbered row by row: index =
/// y * perSide() + x, the order in which the local bake runs them and the coordinator
/// leases them.
class TilePlan {
 public:
  TilePlan(int log2Resolution, int log2TileSize);

  int log2Resolution() const { return log2Resolution_; }
  /// log2 of the tile's side actually used: min(log2TileSize, log2Resolution).
  int log2TileSize() const { return log2TileSize_; }
  uint64_t perSide() const { return uint64_t(1) << (log2Resolution_ - log2TileSize_); }
  uint64_t count() const { return perSide() * perSide(); }
  TileCoord tile(uint64_t index) const { return {index % perSide(), index / perSide()}; }
  uint64_t index(TileCoord t) const { return t.y * perSide() + t.x; }

 private:
  int log2Resolution_, log2TileSize_;
};

/// The tiles of many grids (a light bundle's) as one job's: grid 0's tiles in its
/// TilePlan's order, then grid 1's, and so on. The farm leases them by this index; the
/// bytes do not depend on it (each grid's DAG depends on its own tiles only).
class GridTiles {
 public:
  GridTiles(const std::vector<int>& log2Resolutions, int log2TileSize);

  uint64_t count() const { return first_.back(); }
  size_t grids() const { return plans_.size(); }
  const TilePlan& plan(size_t grid) const { return plans_[grid]; }
  /// The job's index of grid `grid`'s first tile.
  uint64_t first(size_t grid) const { return first_[grid]; }
  struct At {
    uint32_t grid = 0;
    TileCoord tile;
  };
  /// The grid of the job's tile `index` (< count()) and the tile within it.
  At at(uint64_t index) const;

 private:
  std::vector<TilePlan> plans_;
  std::vector<uint64_t> first_;  // one more than grids: first_.back() is the count
};

}  // namespace cpvs
