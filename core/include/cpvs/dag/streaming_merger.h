// Merging sub-DAGs as they arrive, in the pattern of a binary counter.
#pragma once

#include <cstdint>
#include <optional>
#include <utility>
#include <vector>

#include "cpvs/bake/options.h"
#include "cpvs/dag/dag.h"

namespace cpvs {

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

}  // namespace cpvs
