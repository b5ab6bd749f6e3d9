// Merging two sub-DAGs (§4.3).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "cpvs/dag/dag.h"
#include "cpvs/dag/compress.h"

namespace cpvs {

/// The nodes of a level that one core merges (mergeDags): large enough that a part's
/// work outweighs handing it to a thread.
inline constexpr size_t kMergePartNodes = size_t(1) << 16;

/// Merges two compressed DAGs with equal resolution and root size, holding roots of
/// different blocks, into the compressed DAG of both: each pair of hash-sorted levels is
/// merged in one sweep from the leaves up, equal nodes collapse, and the parents' child
/// indices are rewritten through the sweep's index maps. Canonical: the result does not
/// depend on which DAG is `a` and which is `b`, nor on earlier merge orders. Throws
/// std::invalid_argument when both hold the same root key or the shapes differ.
/// With CompressMode::None the DAGs are concatenated instead (duplicates remain).
///
/// A level of at least twice `partNodes` nodes is cut into ranges of hashes of about that
/// many nodes each, merged on every core; the bytes do not depend on it.
Dag mergeDags(const Dag& a, const Dag& b, CompressMode mode = CompressMode::TopDown,
              size_t partNodes = kMergePartNodes);

}  // namespace cpvs
