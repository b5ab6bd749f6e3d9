// Content hashes of DAG nodes and compression to the optimal DAG (§4.1, §4.2).
#pragma once

#include <cstdint>

#include "cpvs/dag.h"

namespace cpvs {

/// Hash functions for node content. Weak exists so tests can force collisions: every
/// algorithm must stay correct when different nodes share a hash.
enum class HashKind : uint8_t { Xxh3 = 0, WeakForTests = 1 };

enum class CompressMode : uint8_t {
  TopDown = 0,   // §4.2: dedupe from the roots down, never visiting subtrees of duplicates
  BottomUp = 1,  // §4.1: sort and dedupe every level from the leaves up
  None = 2,      // keep the DAG as inserted (duplicates remain; not canonical)
};

/// Fills leafHashes and levelHashes bottom-up: XXH3-128 of a leaf's mask; of an internal
/// node's codes and its kRef children's hashes. Equal subtrees get equal hashes.
void computeHashes(Dag& dag, HashKind kind);

/// The hash of one leaf, and of one internal node from its codes and the hashes of its
/// kRef children in child order (what computeHashes uses).
Hash128 hashLeaf(uint64_t mask, HashKind kind);
Hash128 hashInternal(uint16_t codes, const Hash128* childHashes, int count, HashKind kind);

/// Compresses a DAG with hashes (computeHashes) to the optimal DAG of the same voxels:
/// no two nodes of a level equal, every level sorted by (hash, content) where content is
/// the mask, or the codes then the child indices. Equal hashes are merged only after the
/// subtrees are confirmed equal, so a hash collision never merges different subtrees.
/// The result is canonical: any DAG of the same voxels compresses to the same bytes.
/// Unreferenced nodes are dropped. CompressMode::None returns the input unchanged.
Dag compressDag(Dag&& dag, CompressMode mode);

/// Orders content of two nodes of the same level, for tests and merging.
bool sameNodeContent(const Dag& a, int level, uint32_t ia, const Dag& b, uint32_t ib);

}  // namespace cpvs
