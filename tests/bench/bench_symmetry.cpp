// Subtrees equal up to a reflection or an inversion, counted per scene: how many bytes a
// DAG whose references could name a node reflected (x, y, z) or inverted (lit <-> shadowed)
// would keep, against today's packed layout, before any format carries such references.
#include <cstdio>
#include <string>
#include <vector>

#include "bench_dags.h"
#include "cpvs/dag/symmetry.h"

namespace {

using namespace cpvs;
using namespace cpvs::bench;

struct Generators {
  const char* name;
  uint32_t bits;
};
constexpr Generators kSets[] = {{"x, y", kReflectX | kReflectY},
                                {"x, y, z", kReflectX | kReflectY | kReflectZ},
                                {"inversion", kInvert},
                                {"z + inversion", kReflectZ | kInvert},
                                {"all four", kAllSymmetries}};

int run(int argc, char** argv) {
  CommonArgs args;
  args.scenes = {"peercity", "city", "shouse", "maisons", "bunny"};
  args.log2Resolutions = {12, 14};
  parseBenchArgs(argc, argv, args, [](const std::string&, const std::string&) { return false; });
  if (args.help) {
    std::printf(
        "bench_symmetry [--scenes peercity,city,shouse,maisons,bunny] [--resolutions 4K,16K] [--sun-dir X,Y,Z]\n"
        "  One DAG per scene, grid and receivers (everywhere; surfaces with PCF up to 9): its bytes in today's\n"
        "  layout, and the bytes and distinct nodes it would keep if references named nodes up to reflections\n"
        "  along x, y, z and/or inversion (lit <-> shadowed), each reference carrying the transform's bits.\n"
        "  The peer's city takes its own sun, and above 4K also its grid of 4,096 slices.\n");
    return 0;
  }
  std::vector<std::string> notes;
  std::printf("CPU: %s; %s\n\n", cpuModel().c_str(), now().c_str());
  std::printf("| scene | R | depth slices | receivers | nodes + leaves | bytes | leaf bytes |");
  for (const Generators& g : kSets) std::printf(" %s: classes | bytes |", g.name);
  std::printf("\n| --- | --- | --- | --- | --- | --- | --- |");
  for (size_t i = 0; i < std::size(kSets); ++i) std::printf(" --- | --- |");
  std::printf("\n");
  forEachBenchDag(args, "bench_symmetry", notes, [](const BenchDag& b) {
    const Dag& dag = b.dag;
    const uint64_t nodes = dag.nodeCount();  // internal nodes and leaves
    std::printf("| %s | %s | %s | %.2f |", benchDagCells(b).c_str(), std::to_string(nodes).c_str(),
                humanBytes(dag.bytes()).c_str(), ratio(double(dag.levelBytes(-1)), double(dag.bytes())));
    for (const Generators& g : kSets) {
      const SymmetryCensus c = symmetryCensus(dag, g.bits);
      uint64_t classes = 0;
      for (const uint64_t n : c.classes) classes += n;
      std::printf(" %.3f (leaves %.3f) | %.3f |", ratio(double(classes), double(nodes)),
                  ratio(double(c.classes[0]), double(c.nodes[0])), ratio(double(c.symmetricBytes), double(c.plainBytes)));
    }
    std::printf("\n");
  });
  for (const std::string& n : notes) std::printf("\nnote: %s", n.c_str());
  std::printf("\nnodes + leaves: the DAG's (every level free of duplicates); bytes: its node data in today's packed layout. "
              "Per set of transforms: classes and bytes as fractions of those; the bytes keep one node per class, "
              "references as wide as today's rule gives for the classes below, and each node's transforms other than "
              "the identity (the set's bits each, marked by the unused child code 3) in whole half-words after them.\n");
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cpvs::bench::benchMain("bench_symmetry", run, argc, argv); }
