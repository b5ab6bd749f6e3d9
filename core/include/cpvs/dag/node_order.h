// The content order of DAG nodes within a level: the tie-break after the hash that makes
// compressed levels canonical. Internal to the core.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/dag/dag.h"

namespace cpvs {

/// Three-way comparison of the content of node a (of dag A) and node b (of dag B) in one
/// level (-1 = leaves): the mask, or the codes then the child indices as stored.
inline int compareNodes(const Dag& A, int level, uint32_t a, const Dag& B, uint32_t b) {
  if (level < 0) {
    uint64_t ma = A.leaves[a], mb = B.leaves[b];
    return ma < mb ? -1 : (ma > mb ? 1 : 0);
  }
  const InternalLevel& la = A.levels[level];
  const InternalLevel& lb = B.levels[level];
  if (la.codes[a] != lb.codes[b]) return la.codes[a] < lb.codes[b] ? -1 : 1;
  uint32_t ka = la.childBegin[a], kb = lb.childBegin[b], n = la.refCount(a);
  for (uint32_t k = 0; k < n; ++k) {
    uint32_t ca = la.children[ka + k], cb = lb.children[kb + k];
    if (ca != cb) return ca < cb ? -1 : 1;
  }
  return 0;
}

/// The same order for two nodes of one DAG whose child indices are mapped through
/// `childMap` first (children being renumbered by compression).
inline int compareRemapped(const Dag& D, int level, uint32_t a, uint32_t b,
                           const std::vector<uint32_t>& childMap) {
  if (level < 0) return compareNodes(D, level, a, D, b);
  const InternalLevel& lv = D.levels[level];
  if (lv.codes[a] != lv.codes[b]) return lv.codes[a] < lv.codes[b] ? -1 : 1;
  uint32_t ka = lv.childBegin[a], kb = lv.childBegin[b], n = lv.refCount(a);
  for (uint32_t k = 0; k < n; ++k) {
    uint32_t ca = childMap[lv.children[ka + k]], cb = childMap[lv.children[kb + k]];
    if (ca != cb) return ca < cb ? -1 : 1;
  }
  return 0;
}

}  // namespace cpvs
