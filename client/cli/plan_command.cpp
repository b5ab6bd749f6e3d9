// `cpvs plan`: what a bake of a scene will compute and why, without baking it.
#include <cstdio>
#include <iostream>
#include <memory>
#include <optional>

#include "bake_flags.h"
#include "bundle_text.h"
#include "cpvs/bake/bake_lights.h"
#include "cli_util.h"
#include "commands.h"
#include "cpvs/bake/bake_estimate.h"
#include "cpvs/bake/bake_plan.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/tile_plan.h"
#include "cpvs/eval/image.h"
#include "cpvs/scene/source.h"

namespace cpvs::cli {

namespace {

struct PlanArgs {
  std::string scene, resolution = "4K";
  SunFlags sun;
  LightFlags lights;
  OptionFlags options;
  std::string coveragePng;
  bool json = false, noEstimate = false;
  int threads = 0;
};

/// The estimate as text: what was sampled, the tiles' seconds and the DAG's bytes.
std::string estimateText(const BakeEstimate& e) {
  char buf[512];
  if (e.sampledTiles == 0) {
    std::snprintf(buf, sizeof buf, "cost: no tile to render: %llu tiles all lit, %.2f s in all\n",
                  static_cast<unsigned long long>(e.tiles), e.tileSeconds);
    return buf;
  }
  std::snprintf(buf, sizeof buf,
                "cost, measured (%zu of the %llu tiles to render baked now, %.2f s):\n"
                "  tiles: about %s of work on this machine, one tile after another (the bake overlaps two)\n"
                "  DAG:   about %s (the sampled sub-DAGs' bytes per triangle, for every tile)\n",
                e.sampledTiles, static_cast<unsigned long long>(e.renderedTiles), e.sampleSeconds,
                formatSeconds(e.tileSeconds).c_str(), humanBytes(uint64_t(e.dagBytes)).c_str());
  return buf;
}

std::string estimateJson(const BakeEstimate& e) {
  return "{\"tiles\": " + std::to_string(e.tiles) + ", \"rendered_tiles\": " + std::to_string(e.renderedTiles) +
         ", \"sampled_tiles\": " + std::to_string(e.sampledTiles) + ", \"sample_seconds\": " + jsonNumber(e.sampleSeconds) +
         ", \"tile_seconds\": " + jsonNumber(e.tileSeconds) + ", \"dag_bytes\": " + std::to_string(uint64_t(e.dagBytes)) + "}";
}

// The grid seen from the sun, at most 1024 pixels a side: tiles no triangle touches
// (black), tiles no receiver reads (dark grey), tiles to render (light grey), and over
// them the columns the receivers' lookups reach (orange, counted at min(R, 4096)).
void writeCoveragePng(const std::string& path, const Scene& scene, const OrthoGrid& grid, const BakeOptions& options,
                      const ReceiverDeclaration& receivers, const BakePlan& plan) {
  const OrthoGrid coarse = grid.withResolution(std::min(grid.log2Resolution, kLog2PlanColumns));
  const std::vector<uint8_t> reached = ReceiverSet(scene, coarse, receivers).reachedColumns();
  const uint64_t C = coarse.resolution(), side = std::min<uint64_t>(C, 1024), per = C / side;
  const uint64_t perSide = TilePlan(grid.log2Resolution, options.log2TileSize).perSide();
  constexpr float kShade[] = {0.0f, 0.06f, 0.45f};  // by BakePlan::TileClass
  Image image{int(side), int(side)};
  for (uint64_t py = 0; py < side; ++py)
    for (uint64_t px = 0; px < side; ++px) {
      bool hit = false;
      for (uint64_t y = py * per; y < (py + 1) * per && !hit; ++y)
        for (uint64_t x = px * per; x < (px + 1) * per && !hit; ++x) hit = reached[y * C + x] != 0;
      const uint64_t tx = px * perSide / side, ty = py * perSide / side;
      const bool border = perSide <= 64 && side / perSide >= 8 && ((px * perSide) % side == 0 || (py * perSide) % side == 0);
      const float g = border ? 0.02f : kShade[plan.tileClasses[ty * perSide + tx]];
      image.at(int(px), int(py)) = hit ? Rgb{1.0f, 0.35f, 0.03f} : Rgb{g, g, g};
    }
  writePng(path, image);
}

// Local lights: each light's grids as the bake would plan them, one line per light.
int runLightPlan(const PlanArgs& a) {
  checkNoSunWithLights(a.sun);
  if (!a.coveragePng.empty()) throw InputError("--coverage-png draws a sun's grid; local lights have no coverage picture yet");
  const BakeOptions options = optionsOf(a.options);
  std::vector<Light> given = flagLights(a.lights);
  const Scene scene = openScene(a.scene);
  const std::vector<Light> lights = withSceneLights(a.lights, std::move(given), scene, a.scene);
  const double footprint = footprintOf(a.lights, scene);
  std::vector<double> closest;
  const ReceiverDeclaration receivers = receiversOf(a.options);
  const LightBundle planned = planLights(scene, lights, footprint, options, closest, receivers);
  if (a.json)
    std::cout << "{\"footprint\": " << jsonNumber(footprint) << ", \"lights\": " << planned.lights.size()
              << ", \"plan\": " << lightPlanJson(planned, closest) << "}\n";
  else {
    std::cout << lightPlanTable(planned, closest, footprint, receivers);
    // Only the sun's artifact carries a translucent casters' tree: say what local lights do.
    size_t meshes = 0, triangles = 0;
    for (const SceneMesh& m : scene.meshes)
      if (m.triangles > 0 && isTranslucent(m)) ++meshes, triangles += m.triangles;
    if (meshes)
      std::cout << "translucent casters: " << meshes << " meshes, " << triangles
                << " triangles: local lights' grids bake them as opaque casters (only a sun bake keeps their "
                   "transmittance, in a TOP tree beside its CPVS)\n";
  }
  return 0;
}

int runPlan(const PlanArgs& a) {
  const auto limit = threadLimit(a.threads);  // cameras cast rays, receivers are gathered in parallel
  if (a.lights.given()) {
    if (a.options.depthSlices != 0) throw InputError("--depth-slices is the sun's: a light's grids are cubic");
    return runLightPlan(a);
  }
  const BakeOptions options = optionsOf(a.options);
  const ReceiverDeclaration receivers = receiversOf(a.options);
  const int log2R = parseResolution(a.resolution);
  checkDepthSlices(a.options.depthSlices, log2R, "--depth-slices");
  const LightFrame frame = lightFromFlags(a.sun.dir, a.sun.elevation, a.sun.azimuth);
  SceneStats stats;
  const Scene scene = openScene(a.scene, &stats);
  const OrthoGrid grid = makeGrid(scene, frame, log2R, a.options.depthSlices);
  const BakeScene prepared(scene, grid, options.renderer, a.threads, receivers);
  const BakePlan plan =
      planBake(scene, stats, options, receivers, prepared.raster(), prepared.receivers(), declaredMedia(a.options));
  if (!a.coveragePng.empty()) writeCoveragePng(a.coveragePng, scene, grid, options, receivers, plan);
  std::optional<BakeEstimate> estimate;
  if (!a.noEstimate) estimate = estimateBake(prepared, options);
  if (a.json) {
    std::string json = planJson(plan);
    // The artifact records the plan; the estimate stands beside it here.
    if (estimate) json.insert(json.rfind('}'), ", \"estimate\": " + estimateJson(*estimate));
    std::cout << json << "\n";
  } else {
    std::cout << planText(plan);
    if (estimate) std::cout << estimateText(*estimate);
  }
  return 0;
}

}  // namespace

void addPlanCommand(CLI::App& app, int& status) {
  auto a = std::make_shared<PlanArgs>();
  CLI::App* c = app.add_subcommand(
      "plan", "Say what a bake will compute and why: closed parts, what the receivers leave free, the lights the scene "
              "file holds (and which are baked), the passes that run; with local lights (--spot, --point, --lights, "
              "--scene-lights) each light's grids: near, far, resolution. Every bake records this plan in its file");
  c->add_option("scene", a->scene, "Scene file, city[:BLOCKS[:SEED]] or landscape[:SIZE[:SEED]]")->required();
  addSunFlags(c, a->sun);
  addLightFlags(c, a->lights);
  c->add_option("--resolution,-r", a->resolution, "Grid resolution R, as for bake")->capture_default_str();
  addOptionFlags(c, a->options, "Tile size in texels (power of two >= 8)");
  c->add_flag("--json", a->json, "Print the plan as JSON (what the artifact records, with \"estimate\" beside it)");
  c->add_flag("--no-estimate", a->noEstimate,
              "Skip the cost estimate (by default a few of the bake's own tiles are baked to price the rest: "
              "seconds of tile work and DAG bytes)");
  addThreadsFlag(c, a->threads);
  c->add_option("--coverage-png", a->coveragePng,
                "Also draw the grid from the sun: tiles no triangle touches (black), tiles no receiver reads (dark "
                "grey), tiles to render (grey), the columns receivers' lookups reach (orange)");
  c->callback([a, &status] { status = runPlan(*a); });
}

}  // namespace cpvs::cli
