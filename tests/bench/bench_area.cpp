// Benchmark of area lights as VPL bundles, the shape of seed 002's Table 1: K VPLs of one
// panel over the city, each a cube of RES^3 grids, for K = 1, 4, 16, 64, 256: bake seconds
// (each VPL and the whole bundle), bundle bytes, soft-lookup nanoseconds, and the error of
// the soft visibility against a Monte Carlo integral over the emitter (4,096 exact rays a
// point), beside the error of the same K VPLs with exact rays (sampling alone); each K with
// the VPLs' cubes rolled (the default) and along the world's axes. Prints the CPU model. A program that prints, not a test.
#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

#include "area_testing.h"
#include "bench_common.h"
#include "cpvs/bake/bake_lights.h"
#include "cpvs/base/error.h"
#include "cpvs/base/progress.h"
#include "cpvs/io/bundle_file.h"
#include "cpvs/query/bundle_query.h"
#include "cpvs/scene/source.h"

namespace cpvs {
namespace {

using namespace bench;

struct Args : CommonArgs {
  std::string area = "36,66,36:12,0,0:0,0,12";  // above city:3:5's roofs, shining down
  std::vector<int> counts{1, 4, 16, 64, 256};
  int points = 600;
};

void printUsage() {
  std::printf(
      "bench_area: an area light as K VPLs, bake and soft-shadow error against K\n\n"
      "  --scene SPEC         the scene (default city:3:5)\n"
      "  --area C:U:V         the panel: centre and two edges (default 36,66,36:12,0,0:0,0,12)\n"
      "  --resolutions LIST   the VPLs' grids (default 128)\n"
      "  --points N           surface points under the panel, within 2.5 panel sizes across, for the error\n"
      "                       (default 600)\n"
      "  --threads N          bake threads (default: all)\n");
}

int run(int argc, char** argv) {
  Args a;
  a.scenes = {"city:3:5"};
  a.log2Resolutions = {7};
  parseBenchArgs(argc, argv, a, [&](const std::string& option, const std::string& value) {
    if (option == "--area") a.area = value;
    else if (option == "--points") a.points = parsePositive(value, "--points");
    else return false;
    return true;
  });
  if (a.help) {
    printUsage();
    return 0;
  }
  std::unique_ptr<tbb::global_control> threads;
  if (a.threads > 0) threads = std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism, a.threads);
  std::printf("# Area lights as VPL bundles\n\n%s, CPU: %s (%d threads)\n", now().c_str(), cpuModel().c_str(),
              a.threads > 0 ? a.threads : tbb::info::default_concurrency());
  std::vector<std::string> notes;
  for (const std::string& spec : a.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_area", notes);
    if (!s) continue;
    for (int log2R : a.log2Resolutions) {
      AreaLight area = parseAreaLightFlag(a.area);
      area.seed = 1;
      area.log2Resolution = log2R;
      const RayScene rays(s->scene, area.centre);
      // Points within 2.5 panel sizes across of its centre (30 units for the default).
      const double radius = 2.5 * std::max(length(area.edgeU), length(area.edgeV));
      const std::vector<SurfaceSample> points = testing::pointsUnderArea(s->scene, rays, area, radius, size_t(a.points), 5);
      std::vector<double> truth;
      for (size_t k = 0; k < points.size(); ++k)
        truth.push_back(testing::emitterVisibility(rays, area, points[k].point, points[k].normal, 64, k));
      std::printf("\n## %s, a %.3g x %.3g panel, VPL grids %s^3, %zu points under it\n\n", s->label.c_str(),
                  length(area.edgeU), length(area.edgeV), resolutionLabel(log2R).c_str(), points.size());
      std::printf("| K | cubes | bake s | s / VPL | shared nodes | on a device | file (zstd) | soft lookup ns | mean error | p99 | "
                  "K VPLs exact: mean | p99 |\n");
      std::printf("|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
      for (int k : a.counts)
      for (bool roll : {true, false}) {
        area.vpls = uint32_t(k);
        area.roll = roll;
        const std::vector<Light> vpls = vplsOf(area, 1);
        const auto start = std::chrono::steady_clock::now();
        const LightBundle bundle = bakeLights(s->scene, vpls, defaultFootprint(s->scene), BakeOptions{}, sceneHash(s->scene));
        const double bake = secondsSince(start);
        const std::vector<uint8_t> file = encodeBundle(bundle, true);
        const BundleQuery q(bundle);
        const auto lookups = std::chrono::steady_clock::now();
        std::vector<float> soft(points.size());
        for (size_t i = 0; i < points.size(); ++i) soft[i] = q.softVisibility(0, points[i].point, points[i].normal);
        const double ns = secondsSince(lookups) * 1e9 / double(points.size());
        std::vector<double> baked, exact;
        for (size_t i = 0; i < points.size(); ++i) {
          baked.push_back(std::abs(soft[i] - truth[i]));
          exact.push_back(std::abs(testing::exactVplVisibility(rays, vpls, points[i].point, points[i].normal) - truth[i]));
        }
        std::printf("| %d | %s | %.2f | %.4f | %s | %s | %s | %.0f | %.4f | %.4f | %.4f | %.4f |\n", k, roll ? "rolled" : "world axes", bake, bake / k,
                    humanBytes(bundle.poolBytes).c_str(), humanBytes(bundle.pool->size() * 4).c_str(),
                    humanBytes(file.size()).c_str(), ns,
                    testing::meanOf(baked), testing::p99Of(baked), testing::meanOf(exact), testing::p99Of(exact));
      }
    }
  }
  std::printf("\nTargets (issue): K = 64 at 128^3 with mean error <= 0.02 and p99 <= 0.1; a 64-VPL bundle in <= 10 s on 2 cores\n");
  for (const std::string& n : notes) std::printf("\n%s\n", n.c_str());
  return 0;
}

}  // namespace
}  // namespace cpvs

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_area", cpvs::run, argc, argv); }
