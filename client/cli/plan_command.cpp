// `cpvs plan`: what a bake of a scene will compute and why, without baking it.
#include <cstdio>
#include <iostream>
#include <memory>

#include "bake_flags.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/bake/bake_plan.h"
#include "cpvs/scene/source.h"

namespace cpvs::cli {

namespace {

struct PlanArgs {
  std::string scene, resolution = "4K";
  SunFlags sun;
  OptionFlags options;
  bool json = false;
};

int runPlan(const PlanArgs& a) {
  const BakeOptions options = optionsOf(a.options);
  const ReceiverDeclaration receivers = receiversOf(a.options);
  const int log2R = parseResolution(a.resolution);
  const LightFrame frame = lightFromFlags(a.sun.dir, a.sun.elevation, a.sun.azimuth);
  SceneStats stats;
  const Scene scene = openScene(a.scene, &stats);
  const OrthoGrid grid = makeGrid(scene, frame, log2R);
  const RasterScene raster(scene, grid);
  const ReceiverSet reads(scene, grid, receivers);
  const BakePlan plan = planBake(scene, stats, options, receivers, raster, reads);
  if (a.json)
    std::cout << planJson(plan) << "\n";
  else
    std::cout << planText(plan);
  return 0;
}

}  // namespace

void addPlanCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<PlanArgs>();
  CLI::App* c = app.add_subcommand(
      "plan", "Say what a bake will compute and why: closed parts, what the receivers leave free, the lights the scene "
              "file holds (and which are baked), the passes that run. Every bake records this plan in its file");
  c->add_option("scene", a->scene, "Scene file, city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]]")->required();
  addSunFlags(c, a->sun);
  c->add_option("--resolution,-r", a->resolution, "Grid resolution R, as for bake")->capture_default_str();
  addOptionFlags(c, a->options, "Tile size in texels (power of two >= 8)");
  c->add_flag("--json", a->json, "Print the plan as JSON (what the artifact records)");
  c->callback([a, &status] { status = runPlan(*a); });
}

}  // namespace cpvs::cli
