#include "bench_dags.h"

namespace cpvs::bench {

void forEachBenchDag(const CommonArgs& args, const std::string& program, std::vector<std::string>& notes,
                     const std::function<void(const BenchDag&)>& fn) {
  for (const std::string& spec : args.scenes) {
    std::optional<BenchScene> s = openBenchScene(spec, program, notes);
    if (!s) continue;
    const bool peer = spec == "peercity";
    const Vec3 sun = peer ? kPeerSun : args.sunDir;
    for (const int log2R : args.log2Resolutions) {
      std::vector<int> depths{0};
      if (peer && log2R > 12) depths.push_back(kPeerDepthSlices);
      for (const int depth : depths) {
        const OrthoGrid grid = makeGrid(s->scene, LightFrame::fromDirection(sun), log2R, depth);
        for (const ReceiverKind kind : {ReceiverKind::Everywhere, ReceiverKind::Surfaces}) {
          ReceiverDeclaration declaration;
          declaration.kind = kind;
          BakeOptions options;
          options.receivers = kind;
          options.receiverPcf = uint8_t(declaration.maxPcf);
          const BakeScene prepared(s->scene, grid, Renderer::Raster, args.threads, declaration);
          const Dag dag = bakeGrid(prepared, options);
          fn(BenchDag{*s, log2R, depth, kind, grid, prepared, options, declaration, dag});
          std::fflush(stdout);
        }
      }
    }
  }
}

std::string benchDagCells(const BenchDag& d) {
  return d.scene.label + " | " + resolutionLabel(d.log2R) + " | " +
         (d.depthSlices ? std::to_string(d.depthSlices) : std::string("cubic")) + " | " +
         (d.kind == ReceiverKind::Everywhere ? "everywhere" : "surfaces, PCF <= 9");
}

}  // namespace cpvs::bench
