// A bake that advances by bounded steps (seed 000 §4.3: a slowly moving sun rebuilt in
// the background across a game's frames). The work is cut into units — a stripe of a
// tile's texels rendered and resolved into masks, the tile's min-max pyramid, its
// insertion, its compression, one merge into the streaming merger, the final merge and
// root assembly — and step(budget) runs at least one unit and then more while the
// budget lasts. Column masks depend only on their own texels, and the merged DAG is
// canonical, so any sequence of budgets gives the one-shot bake's DAG, byte for byte.
#pragma once

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/min_max_pyramid.h"
#include "cpvs/bake/options.h"
#include "cpvs/bake/stage_times.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/dag/dag.h"
#include "cpvs/dag/streaming_merger.h"

namespace cpvs {

class AmortizedBake {
 public:
  /// `scene` must outlive the bake. The tile size is the options' (smaller tiles make
  /// smaller units and change nothing in the DAG).
  AmortizedBake(const BakeScene& scene, const BakeOptions& options);

  /// Runs one unit, then more while less than `budget` has passed since the call began
  /// (a unit is never split: a step can overrun by its last unit). Returns done().
  bool step(std::chrono::nanoseconds budget);
  bool done() const { return stage_ == Stage::Done; }
  /// Tiles finished of the plan's, for progress.
  uint64_t tilesDone() const { return tile_; }
  uint64_t tileCount() const { return plan_.count(); }
  /// The complete DAG, once done() (moved out: call once).
  Dag takeResult();

  struct Stats {
    uint64_t steps = 0, units = 0;
    double longestStepSeconds = 0, longestUnitSeconds = 0;
    std::string longestUnit;  // "insert", "render and masks", ...
    /// Each kind of unit, in the order first run: how many ran, how many alone took
    /// longer than their step's whole budget (what keeps a step over it: a unit is never
    /// split), their longest and their total.
    struct UnitKind {
      std::string name;
      uint64_t count = 0, overBudget = 0;
      double longestSeconds = 0, totalSeconds = 0;
    };
    std::vector<UnitKind> unitKinds;
  };
  const Stats& stats() const { return stats_; }
  const StageTimes& stageTimes() const { return times_; }

 private:
  enum class Stage { Masks, Pyramid, Insert, Compress, Merge, Finish, Done };
  /// One unit of the current stage; returns its name.
  const char* runUnit(std::chrono::nanoseconds budget);
  void startTile();

  const BakeScene& scene_;
  BakeOptions options_;
  TilePlan plan_;
  StreamingMerger merger_;
  StageTimes times_;
  Stats stats_;
  Stage stage_ = Stage::Masks;
  uint64_t tile_ = 0;
  uint32_t tileSide_ = 0, rowsDone_ = 0;
  bool touched_ = true;
  double secondsPerRow_ = 0;  // of the last stripe: sizes the next one to the budget
  ColumnMasks masks_;
  MinMaxPyramid pyramid_;
  Dag tileDag_;
  std::optional<Dag> result_;
};

}  // namespace cpvs
