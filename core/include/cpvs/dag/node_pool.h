// The nodes of several complete DAGs shared by content: a light bundle's one pool, where
// a node two lights' shadows have in common is stored once (seed 000 §6.1).
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/dag/dag.h"

namespace cpvs {

/// Leaves and levels as Dag holds them (level l: nodes of 2^(l+3) voxels a side, whatever
/// the resolution of the DAG they came from), with one root per DAG.
struct NodePool {
  struct Root {
    int log2Resolution = 0;  // the DAG's grid; its root node lies in level log2Resolution - 3
    NodeRef ref;
    /// Levels its packed pointer grid answers in one read (seed 000 §6.3), 0 (none: a
    /// walk starts at the root) to packedGridLevels(log2Resolution); -1: that most.
    int gridLevels = -1;
  };
  std::vector<uint64_t> leaves;
  std::vector<InternalLevel> levels;  // as many as the finest DAG has
  std::vector<Root> roots;

  /// Bytes of the node data, as Dag::bytes() counts them, in packed layout `version`.
  uint64_t bytes(uint32_t version = kPackedLayoutVersion) const;
};

/// The union of complete DAGs (one root each; any resolutions): leaves and nodes equal in
/// content are stored once, bottom-up (a node's children are merged before it), each in
/// the order it is first met, DAG after DAG. Deterministic for the same DAGs in the same
/// order.
NodePool shareNodes(const std::vector<const Dag*>& dags);

/// Bytes of the nodes root `root` reaches: what its DAG alone would hold, compressed, in
/// the pool's layout of `version` (its references as wide as the whole pool's need).
uint64_t reachableBytes(const NodePool& pool, size_t root, uint32_t version = kPackedLayoutVersion);

}  // namespace cpvs
