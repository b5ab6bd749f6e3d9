#include "cpvs/dag/packed_dag.h"

#include <string>

namespace cpvs {

PackedDag::PackedDag(const Dag& dag)
    : leaves_(dag.leaves), internalLevels_(int(dag.levels.size())), log2Resolution_(dag.log2Resolution) {
  if (dag.roots.size() != 1 || dag.log2RootSize != dag.log2Resolution)
    throw InputError("packing a DAG for lookups: it is not complete (" + std::to_string(dag.roots.size()) + " roots)");
  // Word offset of every node, level by level from the top, so that a walk moves forward.
  std::vector<std::vector<uint32_t>> offset(dag.levels.size());
  uint64_t total = 0;
  for (int l = internalLevels_ - 1; l >= 0; --l) {
    const InternalLevel& level = dag.levels[size_t(l)];
    offset[size_t(l)].resize(level.size());
    for (size_t i = 0; i < level.size(); ++i) {
      offset[size_t(l)][i] = uint32_t(total);
      total += 1 + level.refCount(i);
      if (total > UINT32_MAX)
        throw InputError("packing a DAG for lookups: more than 2^32 words (" + std::to_string(dag.bytes()) + " bytes)");
    }
  }
  words_.reserve(total);
  for (int l = internalLevels_ - 1; l >= 0; --l) {
    const InternalLevel& level = dag.levels[size_t(l)];
    for (size_t i = 0; i < level.size(); ++i) {
      words_.push_back(level.codes[i]);
      for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k)
        words_.push_back(l == 0 ? level.children[k] : offset[size_t(l) - 1][level.children[k]]);
    }
  }
  const NodeRef root = dag.roots.front().ref;
  rootCode_ = root.code;
  rootAt_ = root.code != kRef ? 0 : internalLevels_ > 0 ? offset.back()[root.index] : root.index;
}

}  // namespace cpvs
