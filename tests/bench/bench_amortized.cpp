// Benchmark of the amortized bake: each scene and resolution baked one-shot and in steps
// of a fixed budget (2 ms by default) at two tile sizes, in the same run: how many steps,
// the longest step and the unit that made it, the total time against the one-shot bake,
// and that the DAG is the same. A program that prints, not a test.
#include <algorithm>
#include <chrono>
#include <cstdio>

#include "bench_common.h"
#include "cpvs/bake/amortized_bake.h"
#include "cpvs/bake/bake.h"
#include "cpvs/base/error.h"
#include "cpvs/scene/source.h"
#include "dag_testing.h"

namespace cpvs {
namespace {

using namespace bench;
using Clock = std::chrono::steady_clock;

int run(int argc, char** argv) {
  CommonArgs a;
  a.scenes = {"city", "bunny"};
  a.log2Resolutions = {12, 14};
  double budgetMs = 2;
  std::vector<int> tiles{9, 12};
  parseBenchArgs(argc, argv, a, [&](const std::string& option, const std::string& value) {
    if (option == "--budget-ms") budgetMs = parseDouble(value, "--budget-ms");
    else return false;
    return true;
  });
  if (a.help) {
    std::printf("bench_amortized: a bake in steps of a budget against the one-shot bake\n\n"
                "  --scenes LIST       default city,bunny\n  --resolutions LIST  default 4K,16K\n"
                "  --budget-ms MS      the step budget (default 2)\n  --sun-dir X,Y,Z\n");
    return 0;
  }
  std::printf("# Amortized bake\n\n%s, CPU: %s; budget %.3g ms per step\n\n", now().c_str(), cpuModel().c_str(), budgetMs);
  std::printf("| scene | R | tile | one-shot s | stepped s | steps | longest step ms | longest unit | over budget | same DAG "
              "| units over the budget alone: count of all, longest ms |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|---|\n");
  // The target: steps of at most 2 ms on the city at 4K; the best tile size's row.
  std::string target;
  double targetLongestMs = 1e30;
  std::vector<std::string> notes;
  const auto budget = std::chrono::nanoseconds(int64_t(budgetMs * 1e6));
  for (const std::string& spec : a.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_amortized", notes);
    if (!s) continue;
    for (int log2R : a.log2Resolutions) {
      const OrthoGrid grid = makeGrid(s->scene, LightFrame::fromDirection(a.sunDir), log2R);
      const BakeScene prepared(s->scene, grid, Renderer::Raster);
      for (int log2T : tiles) {
        BakeOptions o;
        o.log2TileSize = log2T;
        auto start = Clock::now();
        const Dag oneShot = bakeGrid(prepared, o);
        const double oneShotS = std::chrono::duration<double>(Clock::now() - start).count();
        start = Clock::now();
        AmortizedBake bake(prepared, o);
        uint64_t over = 0;
        while (!bake.step(budget))
          if (bake.stats().longestStepSeconds * 1e9 > double(budget.count())) over = bake.stats().steps;
        const double steppedS = std::chrono::duration<double>(Clock::now() - start).count();
        const Dag stepped = bake.takeResult();
        const bool same = oneShot.bytes() == stepped.bytes() && oneShot.leaves == stepped.leaves;
        const auto& st = bake.stats();
        (void)over;
        // What bounds the steps: the kinds of unit that alone outlast the budget, longest first.
        std::vector<AmortizedBake::Stats::UnitKind> bounds;
        for (const auto& k : st.unitKinds)
          if (k.overBudget > 0) bounds.push_back(k);
        std::sort(bounds.begin(), bounds.end(), [](const auto& x, const auto& y) { return x.longestSeconds > y.longestSeconds; });
        std::string bound;
        for (const auto& k : bounds)
          bound += (bound.empty() ? "" : "; ") + k.name + " " + std::to_string(k.overBudget) + " of " + std::to_string(k.count) +
                   ", " + format("%.1f", k.longestSeconds * 1e3);
        if (bound.empty()) bound = "none";
        std::printf("| %s | %s | %s | %.2f | %.2f | %llu | %.1f | %s | %s | %s | %s |\n", s->label.c_str(),
                    resolutionLabel(log2R).c_str(), resolutionLabel(std::min(log2T, log2R)).c_str(), oneShotS, steppedS,
                    static_cast<unsigned long long>(st.steps), st.longestStepSeconds * 1e3, st.longestUnit.c_str(),
                    times(st.longestStepSeconds * 1e3 / budgetMs).c_str(), same ? "yes" : "NO", bound.c_str());
        if (spec == "city" && log2R == 12 && st.longestStepSeconds * 1e3 < targetLongestMs) {
          targetLongestMs = st.longestStepSeconds * 1e3;
          target = format("%.1f", targetLongestMs) + " ms with tiles of " + resolutionLabel(std::min(log2T, log2R)) +
                   "; bound by " + (bounds.empty() ? std::string("nothing") : bounds.front().name + " (" + bound + ")");
        }
        std::fflush(stdout);
      }
    }
  }
  for (const std::string& n : notes) std::printf("\n%s\n", n.c_str());
  if (!target.empty())
    std::printf("\nTarget, steps of at most 2 ms on the city at 4K: %s: the longest step %s.\n",
                targetLongestMs <= 2 ? "met" : "missed", target.c_str());
  std::printf("\nover budget: the longest step over the budget. A unit is never split, so a step overruns by its\n"
              "last unit; smaller tiles make smaller units and change nothing in the DAG.\n");
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_amortized", cpvs::run, argc, argv); }
