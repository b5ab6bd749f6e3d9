// Benchmark of a light bundle's bake (seed 000 §5-6): the procedural city's street lamps,
// every grid at one resolution, baked in one process as `cpvs bake --scene-lights` does.
// Prints the machine, each grid's bytes and bake seconds (their distribution), the
// bundle's shared pool against the sum of separate DAGs and against 16-bit shadow maps of
// the same grids, and the whole bundle's wall time, with the targets beside them.
// A program that prints, not a test.
#include <tbb/global_control.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/base/error.h"
#include "cpvs/base/parse.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/scene/source.h"

namespace cpvs {
namespace {

using namespace bench;

constexpr const char* kUsage =
    "bench_lights: bake the scene's own lights (the procedural city's street lamps) into one light bundle\n"
    "  --scene SPEC        scene with lights (default city: 12 blocks, 153 lamps)\n"
    "  --resolution R      every grid's resolution (default 8K, as seed 000's city)\n"
    "  --lights N          the first N lights only (default all)\n"
    "  --renderer raster|embree (default raster)\n"
    "  --threads N         worker threads (default all cores)\n";

struct Args {
  std::string scene = "city";
  int log2R = 13;
  size_t lights = 0;
  Renderer renderer = Renderer::Raster;
  int threads = 0;
  bool help = false;
};

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string o = argv[i];
    if (o == "--help" || o == "-h") {
      a.help = true;
      continue;
    }
    if (i + 1 >= argc) throw InputError(o + " needs a value (see --help)");
    const std::string v = argv[++i];
    if (o == "--scene") a.scene = v;
    else if (o == "--resolution") a.log2R = parseResolution(v);
    else if (o == "--lights") a.lights = size_t(parsePositive(v, o));
    else if (o == "--renderer") a.renderer = parseOption<Renderer>(v, o);
    else if (o == "--threads") a.threads = parsePositive(v, o);
    else throw InputError("unknown option " + o + " (see --help)");
  }
  return a;
}

// The value at fraction q of sorted values.
double quantile(std::vector<double> v, double q) {
  std::sort(v.begin(), v.end());
  return v.empty() ? 0 : v[std::min(v.size() - 1, size_t(q * double(v.size() - 1) + 0.5))];
}

int run(const Args& a) {
  std::unique_ptr<tbb::global_control> limit;
  if (a.threads > 0) limit = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  Scene scene = openScene(a.scene);
  std::vector<Light> lights = sceneLights(scene);
  if (lights.empty()) throw InputError(a.scene + " holds no point or spot light");
  if (a.lights > 0 && a.lights < lights.size()) lights.resize(a.lights);
  for (Light& l : lights) l.log2Resolution = a.log2R;
  BakeOptions options;
  options.renderer = a.renderer;

  std::printf("# bench_lights: %s, %s\n\nCPU: %s; rasterizer SIMD: %s; %s renderer; every grid %s^3\n\n", a.scene.c_str(),
              now().c_str(), cpuModel().c_str(), rasterInstructionSet(), optionName(a.renderer),
              resolutionLabel(a.log2R).c_str());
  // Each grid's bake time: between the progress calls that follow each grid.
  std::vector<double> gridSeconds;
  auto last = std::chrono::steady_clock::now();
  const auto start = last;
  StageTimes stages;
  const LightBundle b = bakeLights(scene, lights, 1, options, sceneHash(scene), &stages,
                                   [&](const std::string&, uint64_t done, uint64_t) {
                                     const auto t = std::chrono::steady_clock::now();
                                     if (done > 0) gridSeconds.push_back(std::chrono::duration<double>(t - last).count());
                                     last = t;
                                     return true;
                                   });
  const double wall = secondsSince(start);
  const std::vector<uint8_t> file = encodeBundle(b, true);

  std::vector<double> gridBytes;
  uint64_t separate = 0, maps = 0;
  for (const BundleGrid& g : b.grids) {
    gridBytes.push_back(double(g.bytes));
    separate += g.bytes;
    maps += 2 * g.grid.resolution() * g.grid.resolution();
  }
  std::printf("%zu lights, %zu grids\n\n", b.lights.size(), b.grids.size());
  std::printf("| per grid | min | median | 90th | max | total |\n|---|---:|---:|---:|---:|---:|\n");
  auto mb = [](double bytes) { return format("%.3f MB", bytes / 1e6); };
  std::printf("| bytes (its DAG alone) | %s | %s | %s | %s | %s |\n", mb(quantile(gridBytes, 0)).c_str(),
              mb(quantile(gridBytes, 0.5)).c_str(), mb(quantile(gridBytes, 0.9)).c_str(), mb(quantile(gridBytes, 1)).c_str(),
              mb(double(separate)).c_str());
  double bakeTotal = 0;
  for (double s : gridSeconds) bakeTotal += s;
  std::printf("| bake seconds | %s | %s | %s | %s | %s |\n\n", format("%.3f", quantile(gridSeconds, 0)).c_str(),
              format("%.3f", quantile(gridSeconds, 0.5)).c_str(), format("%.3f", quantile(gridSeconds, 0.9)).c_str(),
              format("%.3f", quantile(gridSeconds, 1)).c_str(), format("%.2f", bakeTotal).c_str());
  std::printf("| bundle | bytes | against the pool |\n|---|---:|---:|\n");
  std::printf("| shared node pool | %s | 1x |\n", mb(double(b.poolBytes)).c_str());
  std::printf("| separate DAGs (sum) | %s | %s |\n", mb(double(separate)).c_str(), times(ratio(double(separate), double(b.poolBytes))).c_str());
  std::printf("| 16-bit shadow maps of the same grids | %s | %s |\n", mb(double(maps)).c_str(),
              times(ratio(double(maps), double(b.poolBytes))).c_str());
  std::printf("| the file (zstd) | %s | %s |\n\n", mb(double(file.size())).c_str(),
              times(ratio(double(file.size()), double(b.poolBytes))).c_str());
  std::printf("| stage (all grids) | seconds |\n|---|---:|\n");
  for (const char* name : kStageNames)
    if (auto it = stages.seconds.find(name); it != stages.seconds.end()) std::printf("| %s | %.2f |\n", name, it->second);
  std::printf("\ntiles not rendered (nothing there, or outside the cone): %llu\n\n", (unsigned long long)stages.tilesSkipped);
  std::printf("whole bundle: %.2f s wall (planning, %zu grid bakes, sharing, packing)\n", wall, b.grids.size());
  std::printf("targets (issue, the city's ~165 lamps at 8K, 2 cores): bundle <= 48 MB: %s (%s); whole bundle <= 120 s: %s (%.1f s)\n",
              b.poolBytes <= 48'000'000 ? "met" : "missed", mb(double(b.poolBytes)).c_str(), wall <= 120 ? "met" : "missed", wall);
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) {
  try {
    const cpvs::Args args = cpvs::parseArgs(argc, argv);
    if (args.help) {
      std::fputs(cpvs::kUsage, stdout);
      return 0;
    }
    return cpvs::run(args);
  } catch (const cpvs::InputError& e) {
    std::fprintf(stderr, "bench_lights: error: %s\n", e.what());
    return 2;
  }
}
