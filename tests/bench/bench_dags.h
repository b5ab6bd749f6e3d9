// The DAGs that the layout, symmetry and unread-block benchmarks measure: one per scene,
// resolution, grid depth and receivers, baked in this process.
#pragma once

#include <functional>
#include <string>
#include <vector>

#include "bench_common.h"
#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/dag/dag.h"

namespace cpvs::bench {

/// The peer's sun over its own city, and the depth of its grid at every resolution.
constexpr Vec3 kPeerSun{0.505259, -0.379456, 0.775066};
constexpr int kPeerDepthSlices = 4096;

/// One baked DAG and what it was baked from.
struct BenchDag {
  const BenchScene& scene;
  int log2R;
  int depthSlices;  // 0: a cubic grid
  ReceiverKind kind;
  const OrthoGrid& grid;
  const BakeScene& prepared;
  const BakeOptions& options;
  const ReceiverDeclaration& declaration;
  const Dag& dag;
};

/// For each of args.scenes (an absent one noted and skipped), resolution, grid and
/// receivers (everywhere; surfaces with PCF up to 9), bakes the DAG and calls `fn`. The
/// grids are cubic under args.sunDir, but the peer's city ("peercity") takes its own sun,
/// and above 4K also the peer's grid of 4,096 slices.
void forEachBenchDag(const CommonArgs& args, const std::string& program, std::vector<std::string>& notes,
                     const std::function<void(const BenchDag&)>& fn);

/// The first cells of a table row for the DAG: "scene | R | depth slices | receivers".
std::string benchDagCells(const BenchDag& d);

}  // namespace cpvs::bench
