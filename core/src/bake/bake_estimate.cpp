#include "cpvs/bake/bake_estimate.h"

#include <algorithm>
#include <chrono>
#include <vector>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/tile_eta.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/base/progress.h"

namespace cpvs {

BakeEstimate estimateBake(const BakeScene& scene, const BakeOptions& options, size_t samples) {
  const TilePlan plan(scene.log2Resolution(), options.log2TileSize);
  const std::vector<uint32_t> work = tileWork(scene, plan);
  BakeEstimate e;
  e.tiles = plan.count();
  std::vector<uint64_t> rendered;
  double totalWork = 0;
  uint64_t untouched = UINT64_MAX;  // the first tile not rendered, if any
  for (uint64_t i = 0; i < plan.count(); ++i) {
    if (work[i] == 0) {
      untouched = std::min(untouched, i);
      continue;
    }
    rendered.push_back(i);
    totalWork += work[i];
  }
  e.renderedTiles = rendered.size();
  // From the lightest to the heaviest, evenly spread: the law's two parts are told apart
  // by tiles of different weight.
  if (samples == 0) samples = std::clamp<size_t>(rendered.size() / 4, 3, 8);
  std::stable_sort(rendered.begin(), rendered.end(), [&](uint64_t a, uint64_t b) { return work[a] < work[b]; });
  std::vector<uint64_t> picks;
  const size_t n = std::min(samples, rendered.size());
  for (size_t k = 0; k < n; ++k) {
    const uint64_t at = rendered[n == 1 ? rendered.size() - 1 : k * (rendered.size() - 1) / (n - 1)];
    if (std::find(picks.begin(), picks.end(), at) == picks.end()) picks.push_back(at);
  }
  TileCostSums sums;
  double sampledWork = 0, sampledBytes = 0;
  const auto start = std::chrono::steady_clock::now();
  for (uint64_t i : picks) {
    const TileCoord tile = plan.tile(i);
    const auto tileStart = std::chrono::steady_clock::now();
    const Dag dag = bakeTile(scene, tile.x, tile.y, options);
    sums.add(work[i], secondsSince(tileStart));
    sampledWork += work[i];
    sampledBytes += double(dag.bytes());
  }
  double untouchedSeconds = 0;
  if (untouched != UINT64_MAX) {
    const TileCoord tile = plan.tile(untouched);
    const auto tileStart = std::chrono::steady_clock::now();
    (void)bakeTile(scene, tile.x, tile.y, options);
    untouchedSeconds = secondsSince(tileStart);
  }
  e.sampleSeconds = secondsSince(start);
  e.sampledTiles = picks.size();
  if (!picks.empty()) {
    // One sample, or samples of one weight, give a cost per tile and none per triangle.
    const TileCostLaw law = TileCostLaw::fit(sums).value_or(TileCostLaw{sums.t / sums.n, 0});
    e.tileSeconds = law.seconds(double(rendered.size()), totalWork);
    e.dagBytes = sampledBytes / sampledWork * totalWork;
  }
  e.tileSeconds += double(e.tiles - e.renderedTiles) * untouchedSeconds;
  return e;
}

}  // namespace cpvs
