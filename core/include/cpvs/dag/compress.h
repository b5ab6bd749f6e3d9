// Content hashes of DAG nodes and compression to the optimal DAG (§4.1, §4.2).
#pragma once

#include <cstdint>

#include "cpvs/bake/options.h"
#include "cpvs/dag/dag.h"

namespace cpvs {

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

}  // namespace cpvs
