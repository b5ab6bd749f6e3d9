#include "cpvs/dag/dag.h"

#include "cpvs/base/error.h"
#include "cpvs/dag/packed_layout.h"

namespace cpvs {

uint32_t InternalLevel::append(uint16_t nodeCodes, const uint32_t* refs) {
  uint32_t index = static_cast<uint32_t>(codes.size());
  codes.push_back(nodeCodes);
  int n = 0;
  for (int c = 0; c < 8; ++c)
    if (childCode(nodeCodes, c) == kRef) children.push_back(refs[n++]);
  childBegin.push_back(static_cast<uint32_t>(children.size()));
  return index;
}

NodeRef InternalLevel::child(size_t i, int c) const {
  uint16_t cs = codes[i];
  uint32_t code = childCode(cs, c);
  if (code != kRef) return {code, 0};
  return {kRef, children[childBegin[i] + uint32_t(refRank(cs, c))]};
}

void Dag::reset(int log2Res, int log2Root) {
  log2Resolution = log2Res;
  log2RootSize = log2Root;
  leaves.clear();
  leafHashes.clear();
  roots.clear();
  levels.assign(internalLevels(log2Root), InternalLevel{});
  levelHashes.assign(internalLevels(log2Root), {});
}

size_t Dag::nodeCount() const {
  size_t n = leaves.size();
  for (const auto& l : levels) n += l.size();
  return n;
}

uint64_t Dag::levelBytes(int level, std::optional<bool> compact) const {
  if (level < 0) return 8 * uint64_t(leaves.size());
  const InternalLevel& l = levels[size_t(level)];
  if (level > 0 || !compact.value_or(compactLeafRefs(leaves.size()))) return 4 * (uint64_t(l.size()) + l.children.size());
  uint64_t words = 0;
  for (size_t i = 0; i < l.size(); ++i) words += packedNodeWords(0, l.refCount(i), true);
  return 4 * words;
}

uint64_t Dag::bytes(std::optional<bool> compact) const {
  uint64_t b = levelBytes(-1);
  for (int i = 0; i < int(levels.size()); ++i) b += levelBytes(i, compact);
  return b;
}

bool dagVoxelShadowed(const Dag& dag, uint64_t x, uint64_t y, uint64_t z) {
  CPVS_CHECK(dag.roots.size() == 1 && dag.log2RootSize == dag.log2Resolution);
  NodeRef ref = dag.roots.front().ref;
  for (int level = int(dag.levels.size()) - 1; level >= 0; --level) {
    if (ref.code != kRef) return ref.code == kShadowed;
    ref = dag.levels[level].child(ref.index, childOfVoxel(level, x, y, z));
  }
  if (ref.code != kRef) return ref.code == kShadowed;
  return (dag.leaves[ref.index] >> leafBit(x, y)) & 1;
}

}  // namespace cpvs
