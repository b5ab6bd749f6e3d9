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

}  // namespace cpvs
