#include "cpvs/bake/tile_eta.h"

#include <algorithm>

#include "cpvs/base/error.h"

namespace cpvs {

std::optional<TileCostLaw> TileCostLaw::fit(const TileCostSums& s) {
  if (s.n < 2) return std::nullopt;
  TileCostLaw law;
  const double det = s.n * s.ww - s.w * s.w;
  if (det > 1e-9 * s.n * s.ww) {
    law.perTriangle = (s.n * s.wt - s.w * s.t) / det;
    law.fixed = (s.t - law.perTriangle * s.w) / s.n;
  } else {
    law.fixed = s.t / s.n;  // every tile so far held as many triangles: a fixed cost explains them
  }
  if (law.perTriangle < 0) {
    law = {s.t / s.n, 0};
  } else if (law.fixed < 0) {
    law = {0, s.ww > 0 ? s.wt / s.ww : 0};
  }
  return law;
}

TileEta::TileEta(std::vector<uint32_t> work) : work_(std::move(work)), done_(work_.size(), false) {
  for (uint32_t w : work_)
    if (w > 0) {
      ++leftTiles_;
      leftWork_ += w;
    }
}

void TileEta::finished(size_t tile, double seconds) {
  CPVS_CHECK(tile < work_.size() && !done_[tile]);  // each of the bake's tiles finishes once
  done_[tile] = true;
  const double w = work_[tile];
  if (w == 0) return;
  --leftTiles_;
  leftWork_ -= w;
  sums_.add(w, seconds);
  law_ = TileCostLaw::fit(sums_);
}

void TileEta::skipped(size_t tile) {
  CPVS_CHECK(tile < work_.size() && !done_[tile]);
  done_[tile] = true;
  if (work_[tile] == 0) return;
  --leftTiles_;
  leftWork_ -= work_[tile];
}

double TileEta::secondsLeft() const {
  if (!law_) return -1;
  return std::max(0.0, law_->seconds(double(leftTiles_), leftWork_));
}

}  // namespace cpvs
