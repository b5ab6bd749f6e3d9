// The packed layout's bytes, measured per scene: one DAG as layout 1 holds it (a word per
// code and per reference), as layout 2 did (the 8^3 nodes in half-words), and as today's
// layout 3 (half-words throughout, 16-bit references where what they name fits), with
// the levels that need 32-bit references and the lookup nanoseconds of today's walk.
#include <cstdio>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/eval/surface_sampling.h"
#include "cpvs/query/shadow_query.h"
#include "cpvs/raytrace/ray_scene.h"

namespace {

using namespace cpvs;
using namespace cpvs::bench;

constexpr Vec3 kPeerSun{0.505259, -0.379456, 0.775066};
constexpr int kPeerDepthSlices = 4096;

// The levels whose references take two half-words, as "0-3" or "none".
std::string wideLevels(uint32_t mask) {
  std::string s;
  for (int l = 0; l < 32; ++l)
    if ((mask >> l) & 1) s += (s.empty() ? "" : ",") + std::to_string(l);
  return s.empty() ? "none" : s;
}

int run(int argc, char** argv) {
  CommonArgs args;
  args.scenes = {"peercity", "city", "shouse", "maisons", "bunny"};
  args.log2Resolutions = {12, 14};
  uint64_t lookups = 200000;
  parseBenchArgs(argc, argv, args, [&](const std::string& option, const std::string& value) {
    if (option != "--lookups") return false;
    lookups = uint64_t(parsePositive(value, option));
    return true;
  });
  if (args.help) {
    std::printf(
        "bench_layout [--scenes peercity,city,shouse,maisons,bunny] [--resolutions 4K,16K] [--sun-dir X,Y,Z] [--lookups N]\n"
        "  One DAG per scene, grid and receivers (everywhere; surfaces with PCF up to 9) in each packed layout:\n"
        "  bytes, the levels of 32-bit references, and ns per lookup (binary, 9x9) of today's walk at the\n"
        "  receivers' points. The peer's city takes its own sun, and above 4K also its grid of 4,096 slices.\n");
    return 0;
  }
  std::vector<std::string> notes;
  std::printf("CPU: %s, %s; %s\n\n", cpuModel().c_str(), rasterInstructionSet(), now().c_str());
  std::printf("| scene | R | depth slices | receivers | layout 1 | layout 2 | layout 3 | 3 / 2 | 3 / 1 | levels of 32-bit "
              "references | ns 1 | ns 9x9 |\n");
  std::printf("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |\n");
  for (const std::string& spec : args.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, "bench_layout", notes);
    if (!s) continue;
    const bool peer = spec == "peercity";
    const Vec3 sun = peer ? kPeerSun : args.sunDir;
    for (const int log2R : args.log2Resolutions) {
      std::vector<int> depths{0};
      if (peer && log2R > 12) depths.push_back(kPeerDepthSlices);
      for (const int depth : depths) {
        const OrthoGrid grid = makeGrid(s->scene, LightFrame::fromDirection(sun), log2R, depth);
        const RayScene rays(s->scene, grid.origin);
        for (const ReceiverKind kind : {ReceiverKind::Everywhere, ReceiverKind::Surfaces}) {
          ReceiverDeclaration declaration;
          declaration.kind = kind;
          BakeOptions options;
          options.receivers = kind;
          options.receiverPcf = uint8_t(declaration.maxPcf);
          Dag dag;
          {
            const BakeScene prepared(s->scene, grid, Renderer::Raster, args.threads, declaration);
            dag = bakeGrid(prepared, options);
          }
          const uint64_t b1 = dag.bytes(1), b3 = dag.bytes();
          const bool fits2 = dag.leaves.size() <= kMaxNarrowRefTargets;  // layout 2 names leaves by 16 bits
          const uint64_t b2 = fits2 ? dag.bytes(2) : 0;
          const ShadowQuery query(grid, PackedDag(dag));
          const uint32_t wide = query.dag().header().wideRefs;
          std::vector<Vec3> points, normals;
          for (const SurfaceSample& p : sampleReceivers(s->scene, rays, options.closed, grid.frame.dir, declaration, lookups, 1)) {
            points.push_back(p.point);
            normals.push_back(p.normal);
          }
          std::printf("| %s | %s | %s | %s | %s | %s | %s | %s | %s | %s | %.0f | %.0f |\n", s->label.c_str(),
                      resolutionLabel(log2R).c_str(), depth ? std::to_string(depth).c_str() : "cubic",
                      kind == ReceiverKind::Everywhere ? "everywhere" : "surfaces, PCF <= 9", humanBytes(b1).c_str(),
                      fits2 ? humanBytes(b2).c_str() : "(> 65,536 leaves)", humanBytes(b3).c_str(),
                      fits2 ? format("%.3f", ratio(double(b3), double(b2))).c_str() : "-",
                      format("%.3f", ratio(double(b3), double(b1))).c_str(), wideLevels(wide).c_str(),
                      lookupNs(query, points, normals, 1), lookupNs(query, points, normals, 9));
          std::fflush(stdout);
        }
      }
    }
  }
  for (const std::string& n : notes) std::printf("\nnote: %s", n.c_str());
  std::printf("\nBytes: the DAG's node data in each packed layout (the same nodes; 8 per leaf, 2 per half-word). Layout 2 "
              "named leaves by 16-bit index and holds at most 65,536. Lookups: batched on all cores, best of three.\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_layout", run, argc, argv); }
