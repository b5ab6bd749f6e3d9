#include "cpvs/bake/stage_times.h"

#include <algorithm>

#include "cpvs/base/error.h"

namespace cpvs {

bool isStageName(std::string_view name) {
  return std::find(kStageNames.begin(), kStageNames.end(), name) != kStageNames.end();
}

void StageTimes::add(const std::string& stage, double s) {
  CPVS_CHECK(isStageName(stage));
  seconds[stage] += s;
}

void StageTimes::add(const StageTimes& o) {
  for (const auto& [stage, s] : o.seconds) seconds[stage] += s;
  insert.nodesCreated += o.insert.nodesCreated;
  insert.leavesCreated += o.insert.leavesCreated;
  insert.culledNodes += o.insert.culledNodes;
  insert.culledLeaves += o.insert.culledLeaves;
  tilesSkipped += o.tilesSkipped;
  tilesReused += o.tilesReused;
}

}  // namespace cpvs
