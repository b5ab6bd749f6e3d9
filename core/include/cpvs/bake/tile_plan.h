// Which tiles a bake of a grid has and in what order: shared by the local bake and the
// coordinator, so that both enumerate the same tiles and give the same bytes.
#pragma once

#include <cstdint>

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

}  // namespace cpvs
