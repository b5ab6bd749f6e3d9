// The time a bake's remaining tiles will take, from what its finished tiles took: a
// tile costs a fixed part (its texels) and a part that grows with the triangles that
// reach it, and the two are fitted to the tiles done so far (least squares), so the
// estimate follows the scene and the machine rather than a count of tiles. Tiles no
// triangle reaches cost nothing. The local bake keeps a TileEta; the coordinator keeps
// the same sums in its store (per tile: triangles and seconds) and fits them the same way.
#pragma once

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

namespace cpvs {

/// Sums over finished tiles with work: how many, and of w, w², t and w·t (w triangles, t
/// seconds).
struct TileCostSums {
  double n = 0, w = 0, ww = 0, t = 0, wt = 0;
  void add(double work, double seconds) {
    n += 1, w += work, ww += work * work, t += seconds, wt += work * seconds;
  }
};

/// seconds = fixed + perTriangle * triangles, neither part negative.
struct TileCostLaw {
  double fixed = 0, perTriangle = 0;
  /// The least-squares law of the sums (a part that would be negative is noise: the fit
  /// with that part at zero instead); none before two tiles.
  static std::optional<TileCostLaw> fit(const TileCostSums& s);
  /// The seconds of `tiles` tiles holding `work` triangles in all.
  double seconds(double tiles, double work) const { return fixed * tiles + perTriangle * work; }
};

class TileEta {
 public:
  /// `work`: per tile, the triangles that reach it (0: none; the tile is not rendered).
  explicit TileEta(std::vector<uint32_t> work);

  /// Tile `tile` took `seconds`.
  void finished(size_t tile, double seconds);
  /// Tile `tile` is done without its work (taken from a tile cache): no longer left, and
  /// not a sample of the law.
  void skipped(size_t tile);
  /// Seconds the tiles not yet finished should take; negative until two tiles with work
  /// have finished (nothing to fit yet).
  double secondsLeft() const;
  /// The fitted law so far (zero before two tiles).
  double fixedSeconds() const { return law_ ? law_->fixed : 0; }
  double secondsPerTriangle() const { return law_ ? law_->perTriangle : 0; }

 private:
  std::vector<uint32_t> work_;
  std::vector<bool> done_;
  TileCostSums sums_;
  std::optional<TileCostLaw> law_;
  // Over tiles not finished that have work: how many, and their triangles.
  uint64_t leftTiles_ = 0;
  double leftWork_ = 0;
};

}  // namespace cpvs
