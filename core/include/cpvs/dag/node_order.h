// The content order of DAG nodes within a level: the tie-break after the hash that makes
// compressed levels canonical.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/dag/dag.h"

namespace cpvs {

/// Three-way comparison of the content of node a (of dag A) and node b (of dag B) in one
/// level (-1 = leaves): the mask, or the codes then the child indices, each child index
/// mapped through mapA or mapB first (children being renumbered by compression or a
/// merge). The one content order: compression, merging and the readers' canonical check
/// all use it.
template <class MapA, class MapB>
int compareNodesMapped(const Dag& A, int level, uint32_t a, const MapA& mapA, const Dag& B, uint32_t b,
                       const MapB& mapB) {
  if (level < 0) {
    const uint64_t ma = A.leaves[a], mb = B.leaves[b];
    return ma < mb ? -1 : (ma > mb ? 1 : 0);
  }
  const InternalLevel& la = A.levels[size_t(level)];
  const InternalLevel& lb = B.levels[size_t(level)];
  if (la.codes[a] != lb.codes[b]) return la.codes[a] < lb.codes[b] ? -1 : 1;
  const uint32_t ka = la.childBegin[a], kb = lb.childBegin[b], n = la.refCount(a);
  for (uint32_t k = 0; k < n; ++k) {
    const uint32_t ca = mapA(la.children[ka + k]), cb = mapB(lb.children[kb + k]);
    if (ca != cb) return ca < cb ? -1 : 1;
  }
  return 0;
}

/// Child indices as stored.
struct SameIndex {
  uint32_t operator()(uint32_t i) const { return i; }
};

/// The content order with child indices as stored.
inline int compareNodes(const Dag& A, int level, uint32_t a, const Dag& B, uint32_t b) {
  return compareNodesMapped(A, level, a, SameIndex{}, B, b, SameIndex{});
}

/// The content order of two nodes of one DAG whose child indices are mapped through
/// `childMap` first.
inline int compareRemapped(const Dag& D, int level, uint32_t a, uint32_t b, const std::vector<uint32_t>& childMap) {
  const auto map = [&](uint32_t i) { return childMap[i]; };
  return compareNodesMapped(D, level, a, map, D, b, map);
}

}  // namespace cpvs
