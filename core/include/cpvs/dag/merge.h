// Merging two sub-DAGs (§4.3).
#pragma once

#include <cstdint>
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

}  // namespace cpvs
