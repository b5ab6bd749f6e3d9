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

std::vector<PackedLevelForm> packedLevelForms(const std::vector<InternalLevel>& levels, uint64_t leafCount,
                                              uint32_t version) {
  CPVS_CHECK(version >= 1 && version <= kPackedLayoutVersion);
  CPVS_CHECK(version != 2 || leafCount <= kMaxNarrowRefTargets);
  std::vector<PackedLevelForm> forms(levels.size());
  uint64_t below = leafCount;  // what level l's references name: leaves, then half-words
  for (size_t l = 0; l < levels.size(); ++l) {
    if (version >= 3)
      forms[l] = {1, wideRefsInto(below) ? 2u : 1u, false};
    else if (l == 0 && version == 2)
      forms[l] = {1, 1, true};
    else
      forms[l] = {2, 2, true};
    below = packedLevelHalves(levels[l], forms[l]);
  }
  return forms;
}

uint64_t packedLevelHalves(const InternalLevel& level, PackedLevelForm form) {
  if (!form.wordAligned) return form.codeHalves * uint64_t(level.size()) + form.refHalves * uint64_t(level.children.size());
  uint64_t halves = 0;
  for (size_t i = 0; i < level.size(); ++i) halves += form.nodeHalves(level.refCount(i));
  return halves;
}

uint64_t Dag::levelBytes(int level, uint32_t version) const {
  if (level < 0) return 8 * uint64_t(leaves.size());
  return 2 * packedLevelHalves(levels[size_t(level)], packedLevelForms(levels, leaves.size(), version)[size_t(level)]);
}

uint64_t Dag::bytes(uint32_t version) const {
  const std::vector<PackedLevelForm> forms = packedLevelForms(levels, leaves.size(), version);
  uint64_t b = levelBytes(-1);
  for (size_t l = 0; l < levels.size(); ++l) b += 2 * packedLevelHalves(levels[l], forms[l]);
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
