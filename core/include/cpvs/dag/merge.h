// Merging sub-DAGs (§4.3) and building the levels above the tile roots.
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "cpvs/dag/dag.h"
#include "cpvs/dag/compress.h"

namespace cpvs {

/// Merges two compressed DAGs with equal resolution and root size, holding roots of
/// different blocks, into the compressed DAG of both: each pair of hash-sorted levels is
/// merged in one sweep from the leaves up, equal nodes collapse, and the parents' child
/// indices are rewritten through the sweep's index maps. Canonical: the result does not
/// depend on which DAG is `a` and which is `b`, nor on earlier merge orders. Throws
/// std::invalid_argument when both hold the same root key or the shapes differ.
/// With CompressMode::None the DAGs are concatenated instead (duplicates remain).
Dag mergeDags(const Dag& a, const Dag& b, CompressMode mode = CompressMode::TopDown);

/// Merges sub-DAGs as they arrive, in the pattern of a binary counter: two partial DAGs of
/// equal rank merge as soon as both exist, so the work is O(n log N) and only about log N
/// partial DAGs are held at once.
class StreamingMerger {
 public:
  explicit StreamingMerger(CompressMode mode = CompressMode::TopDown) : mode_(mode) {}
  void add(Dag&& subDag);
  /// Merges what is held, smallest first, and returns it (empty optional when nothing).
  std::optional<Dag> finish();
  uint64_t heldBytes() const;

 private:
  CompressMode mode_;
  std::vector<std::pair<int, Dag>> stack_;  // (rank, dag), ranks strictly decreasing
};

/// Builds the levels above the roots of a merged DAG whose roots cover every block of
/// size 2^log2RootSize in the grid, up to one root of the whole grid. A parent whose 8
/// children are all lit (all shadowed) is lit (shadowed), exactly as an untiled build
/// decides, so the result does not depend on the tile size. New levels are deduplicated
/// (except with CompressMode::None). Throws std::invalid_argument for a missing block.
Dag assembleRoots(Dag&& merged, HashKind hash, CompressMode mode = CompressMode::TopDown);

}  // namespace cpvs
