#include "cpvs/bake/amortized_bake.h"

#include <algorithm>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/insert_tile.h"
#include "cpvs/base/error.h"
#include "cpvs/dag/assemble_roots.h"
#include "cpvs/dag/compress.h"

namespace cpvs {

namespace {

using Clock = std::chrono::steady_clock;

double secondsBetween(Clock::time_point a, Clock::time_point b) { return std::chrono::duration<double>(b - a).count(); }

}  // namespace

AmortizedBake::AmortizedBake(const BakeScene& scene, const BakeOptions& options)
    : scene_(scene),
      options_(options),
      plan_(scene.grid().log2Resolution, options.log2TileSize),
      merger_(options.compress) {
  startTile();
}

void AmortizedBake::startTile() {
  const TileCoord t = plan_.tile(tile_);
  tileSide_ = uint32_t(1) << plan_.log2TileSize();
  touched_ = scene_.touchesTile(t.x, t.y, plan_.log2TileSize());
  rowsDone_ = 0;
  masks_ = ColumnMasks{};
  stage_ = Stage::Masks;
}

const char* AmortizedBake::runUnit(std::chrono::nanoseconds budget) {
  const TileCoord t = plan_.tile(tile_);
  switch (stage_) {
    case Stage::Masks: {
      if (!touched_) {  // all lit: no rendering (bakeUntouchedTile's masks)
        litColumnMasks(tileSide_, tileSide_, uint32_t(scene_.grid().resolution()), masks_);
        stage_ = Stage::Pyramid;
        return "masks of an untouched tile";
      }
      // A stripe of whole rows of 8x8 columns, as many as the budget's share allows by
      // the last stripe's pace (at least one row of columns).
      uint32_t rows = 8;
      if (secondsPerRow_ > 0)
        rows = uint32_t(std::clamp(std::chrono::duration<double>(budget).count() / secondsPerRow_, 8.0, double(tileSide_)));
      rows = std::min(rows & ~7u, tileSide_ - rowsDone_);
      const auto start = Clock::now();
      ColumnMasks stripe;
      scene_.columnMasks(options_, t.x * tileSide_, t.y * tileSide_ + rowsDone_, tileSide_, rows, stripe, times_);
      appendColumnRows(masks_, stripe);
      secondsPerRow_ = secondsBetween(start, Clock::now()) / rows;
      rowsDone_ += rows;
      if (rowsDone_ == tileSide_) stage_ = Stage::Pyramid;
      return "render and masks";
    }
    case Stage::Pyramid: {
      const auto start = Clock::now();
      buildMinMaxPyramid(masks_, pyramid_);
      times_.add("masks", secondsBetween(start, Clock::now()));
      stage_ = Stage::Insert;
      return "pyramid";
    }
    case Stage::Insert: {
      const auto start = Clock::now();
      tileDag_ = Dag{};
      insertTile(masks_, pyramid_, scene_.grid().log2Resolution, plan_.log2TileSize(), t.x, t.y, options_.cull, tileDag_,
                 &times_.insert);
      times_.add("insert", secondsBetween(start, Clock::now()));
      masks_ = ColumnMasks{};
      stage_ = options_.compress != CompressMode::None ? Stage::Compress : Stage::Merge;
      return "insert";
    }
    case Stage::Compress: {
      const auto start = Clock::now();
      computeHashes(tileDag_, options_.hash);
      tileDag_ = compressDag(std::move(tileDag_), options_.compress);
      times_.add("compress", secondsBetween(start, Clock::now()));
      stage_ = Stage::Merge;
      return "compress";
    }
    case Stage::Merge: {
      const auto start = Clock::now();
      merger_.add(std::move(tileDag_));
      times_.add("merge", secondsBetween(start, Clock::now()));
      if (++tile_ < plan_.count()) startTile();
      else stage_ = Stage::Finish;
      return "merge";
    }
    case Stage::Finish: {
      const auto start = Clock::now();
      Dag merged = *merger_.finish();
      result_ = assembleRoots(std::move(merged), options_.hash, options_.compress);
      times_.add("merge", secondsBetween(start, Clock::now()));
      stage_ = Stage::Done;
      return "final merge and roots";
    }
    case Stage::Done: break;
  }
  return "nothing";
}

bool AmortizedBake::step(std::chrono::nanoseconds budget) {
  if (done()) return true;
  const auto start = Clock::now();
  do {
    const auto unitStart = Clock::now();
    const auto left = std::max(std::chrono::nanoseconds(0), budget - std::chrono::duration_cast<std::chrono::nanoseconds>(unitStart - start));
    const char* name = runUnit(left);
    const double seconds = secondsBetween(unitStart, Clock::now());
    ++stats_.units;
    if (seconds > stats_.longestUnitSeconds) {
      stats_.longestUnitSeconds = seconds;
      stats_.longestUnit = name;
    }
    auto kind = std::find_if(stats_.unitKinds.begin(), stats_.unitKinds.end(), [&](const auto& k) { return k.name == name; });
    if (kind == stats_.unitKinds.end()) kind = stats_.unitKinds.insert(kind, Stats::UnitKind{name});
    ++kind->count;
    kind->overBudget += seconds * 1e9 > double(budget.count());
    kind->longestSeconds = std::max(kind->longestSeconds, seconds);
    kind->totalSeconds += seconds;
  } while (!done() && Clock::now() - start < budget);
  ++stats_.steps;
  stats_.longestStepSeconds = std::max(stats_.longestStepSeconds, secondsBetween(start, Clock::now()));
  return done();
}

Dag AmortizedBake::takeResult() {
  if (!result_) throw std::logic_error("AmortizedBake::takeResult before the bake is done");
  Dag d = std::move(*result_);
  result_.reset();
  return d;
}

}  // namespace cpvs
