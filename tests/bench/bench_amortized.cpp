// Benchmark of the amortized bake: each scene and resolution baked one-shot and in steps
// of a fixed budget (2 ms by default) at two tile sizes, in the same run: how many steps,
// the longest step and the unit that made it, the total time against the one-shot bake,
// and that the DAG is the same. A program that prints, not a test.
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
  std::printf("| scene | R | tile | one-shot s | stepped s | steps | longest step ms | longest unit | over budget | same DAG |\n");
  std::printf("|---|---|---|---|---|---|---|---|---|---|\n");
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
        std::printf("| %s | %s | %s | %.2f | %.2f | %llu | %.1f | %s | %s | %s |\n", s->label.c_str(),
                    resolutionLabel(log2R).c_str(), resolutionLabel(std::min(log2T, log2R)).c_str(), oneShotS, steppedS,
                    static_cast<unsigned long long>(st.steps), st.longestStepSeconds * 1e3, st.longestUnit.c_str(),
                    times(st.longestStepSeconds * 1e3 / budgetMs).c_str(), same ? "yes" : "NO");
        std::fflush(stdout);
      }
    }
  }
  for (const std::string& n : notes) std::printf("\n%s\n", n.c_str());
  std::printf("\nover budget: the longest step over the budget. A unit is never split, so a step overruns by its\n"
              "last unit; smaller tiles make smaller units and change nothing in the DAG.\n");
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_amortized", cpvs::run, argc, argv); }
