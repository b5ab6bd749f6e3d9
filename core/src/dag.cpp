#include "cpvs/dag.h"

#include <bit>
#include <cassert>

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
  // Rank of child c among the kRef children: count kRef codes below it.
  // A code is kRef (binary 10) when its high bit is set and its low bit is clear.
  uint32_t below = cs & ((1u << (2 * c)) - 1);
  int rank = std::popcount((below >> 1) & ~below & 0x5555u);
  return {kRef, children[childBegin[i] + rank]};
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

uint64_t Dag::levelBytes(int level) const {
  if (level < 0) return 8 * uint64_t(leaves.size());
  return 4 * uint64_t(levels[level].size()) + 4 * uint64_t(levels[level].children.size());
}

uint64_t Dag::bytes() const {
  uint64_t b = levelBytes(-1);
  for (int i = 0; i < int(levels.size()); ++i) b += levelBytes(i);
  return b;
}

bool lookupVoxel(const Dag& dag, uint64_t x, uint64_t y, uint64_t z) {
  assert(dag.roots.size() == 1 && dag.log2RootSize == dag.log2Resolution);
  NodeRef ref = dag.roots.front().ref;
  for (int level = int(dag.levels.size()) - 1; level >= 0; --level) {
    if (ref.code != kRef) return ref.code == kShadowed;
    int shift = level + 2;  // children of a level-`level` node have size 2^(level+2)
    int c = level == 0 ? int(z & 7)
                       : int(((z >> shift) & 1) << 2 | ((y >> shift) & 1) << 1 | ((x >> shift) & 1));
    ref = dag.levels[level].child(ref.index, c);
  }
  if (ref.code != kRef) return ref.code == kShadowed;
  return (dag.leaves[ref.index] >> ((y & 7) * 8 + (x & 7))) & 1;
}

}  // namespace cpvs
