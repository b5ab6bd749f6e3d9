// DAG-MH (seed 001) against the CPVS on the same scene, sun, grid and receivers: bytes
// (and a 32-bit float map's), bake seconds, lookup nanoseconds at the receivers' points.
// The paper's anchors: DAG-MH at 0.18-0.34x the voxel DAG (Table 1), build 1.04x the DAG
// at 256K (Table 2), 3x3 PCF about half as fast as the voxel DAG's.
#include <chrono>
#include <cstdio>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_dag_mh.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/base/error.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/query/dag_mh_query.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"

namespace {

using namespace cpvs;
using namespace cpvs::bench;
using Clock = std::chrono::steady_clock;

constexpr Vec3 kPeerSun{0.505259, -0.379456, 0.775066};

struct Receivers {
  std::string label;
  ReceiverDeclaration declaration;
};

int run(int argc, char** argv) {
  CommonArgs args;
  args.scenes = {"peercity", "city", "shouse", "maisons"};
  args.log2Resolutions = {12, 14};
  uint64_t lookups = 200000;
  parseBenchArgs(argc, argv, args, [&](const std::string& option, const std::string& value) {
    if (option != "--lookups") return false;
    lookups = uint64_t(parsePositive(value, option));
    return true;
  });
  if (args.help) {
    std::printf(
        "bench_dag_mh [--scenes peercity,city,shouse,maisons] [--resolutions 4K,16K] [--sun-dir X,Y,Z] [--lookups N]\n"
        "  DAG-MH against the CPVS of the same receivers (everywhere; surfaces with PCF up to 9 and 1): bytes,\n"
        "  bake seconds, lookup ns (binary, 3x3, 9x9) at the receivers' points. The peer's city takes its own sun.\n");
    return 0;
  }
  std::vector<std::string> notes;
  std::printf("CPU: %s, %s; %s\n\n", cpuModel().c_str(), rasterInstructionSet(), now().c_str());
  std::printf("| scene | R | receivers | CPVS | DAG-MH | DAG-MH / CPVS | DAG-MH / CPVS everywhere | float map / DAG-MH "
              "| CPVS s | DAG-MH s | DAG-MH s / CPVS s | ns 1 (CPVS, DAG-MH) | ns 3x3 | ns 9x9 |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const std::string& spec : args.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_dag_mh", notes);
    if (!s) continue;
    const Vec3 sun = spec == "peercity" ? kPeerSun : args.sunDir;
    for (const int log2R : args.log2Resolutions) {
      if (log2R > kMaxLog2DagMhResolution) {
        notes.push_back("skipped " + resolutionLabel(log2R) + ": a DAG-MH is baked up to 16K");
        continue;
      }
      const OrthoGrid grid = makeGrid(s->scene, LightFrame::fromDirection(sun), log2R);
      std::vector<Receivers> kinds(3);
      kinds[0].label = "everywhere";
      kinds[1].label = "surfaces, PCF <= 9";
      kinds[1].declaration.kind = ReceiverKind::Surfaces;
      kinds[2].label = "surfaces, PCF 1";
      kinds[2].declaration.kind = ReceiverKind::Surfaces;
      kinds[2].declaration.maxPcf = 1;
      uint64_t everywhereCpvs = 0;
      const RayScene rays(s->scene, grid.origin);
      for (const Receivers& k : kinds) {
        BakeOptions options;
        options.receivers = k.declaration.kind;
        options.receiverPcf = uint8_t(k.declaration.maxPcf);
        auto start = Clock::now();
        PackedDag packed;
        {
          const BakeScene prepared(s->scene, grid, Renderer::Raster, args.threads, k.declaration);
          packed = PackedDag(bakeGrid(prepared, options));
        }
        const double cpvsSeconds = secondsSince(start);
        start = Clock::now();
        DagMh dag;
        try {
          dag = bakeDagMh(s->scene, grid, options, k.declaration, args.threads);
        } catch (const InputError& e) {  // more values than a DAG-MH holds: said in the row
          std::printf("| %s | %s | %s | %s | refused: %s | | | | %.2f | | | | | |\n", s->label.c_str(),
                      resolutionLabel(log2R).c_str(), k.label.c_str(), humanBytes(packed.bytes()).c_str(), e.what(),
                      cpvsSeconds);
          if (k.declaration.kind == ReceiverKind::Everywhere) everywhereCpvs = packed.bytes();
          continue;
        }
        const double dagMhSeconds = secondsSince(start);
        const uint64_t cpvsBytes = packed.bytes(), dagMhBytes = dag.bytes();
        if (k.declaration.kind == ReceiverKind::Everywhere) everywhereCpvs = cpvsBytes;
        const ShadowQuery cpvs(grid, std::move(packed));
        const DagMhQuery dagMh(grid, std::move(dag));
        const std::vector<SurfaceSample> samples =
            sampleReceivers(s->scene, rays, options.closed, grid.frame.dir, k.declaration, lookups, 1);
        std::vector<Vec3> points, normals;
        for (const SurfaceSample& p : samples) {
          points.push_back(p.point);
          normals.push_back(p.normal);
        }
        std::string ns[3];
        const int widths[3] = {1, 3, 9};
        for (int w = 0; w < 3; ++w) {
          if (widths[w] > k.declaration.maxPcf) {
            ns[w] = "-";
            continue;
          }
          ns[w] = format("%.0f", lookupNs(cpvs, points, normals, widths[w])) + ", " +
                  format("%.0f", lookupNs(dagMh, points, normals, widths[w]));
        }
        const double floatMap = double(grid.resolution()) * double(grid.resolution()) * 4;
        std::printf("| %s | %s | %s | %s | %s | %s | %s | %s | %.2f | %.2f | %s | %s | %s | %s |\n", s->label.c_str(),
                    resolutionLabel(log2R).c_str(), k.label.c_str(), humanBytes(cpvsBytes).c_str(),
                    humanBytes(dagMhBytes).c_str(), format("%.3f", ratio(double(dagMhBytes), double(cpvsBytes))).c_str(),
                    format("%.3f", ratio(double(dagMhBytes), double(everywhereCpvs))).c_str(),
                    times(ratio(floatMap, double(dagMhBytes))).c_str(), cpvsSeconds, dagMhSeconds,
                    times(ratio(dagMhSeconds, cpvsSeconds)).c_str(), ns[0].c_str(), ns[1].c_str(), ns[2].c_str());
        std::fflush(stdout);
      }
    }
  }
  for (const std::string& n : notes) std::printf("\nnote: %s", n.c_str());
  std::printf("\nBytes: the packed CPVS DAG and the DAG-MH's structure, values and skip list (not the files, which zstd "
              "compresses further). Seconds: the bake from the scene, on all cores; lookups: batched on all cores.\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_dag_mh", run, argc, argv); }
