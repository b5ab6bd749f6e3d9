// The levels above the roots of a merged DAG, up to one root of the whole grid.
#pragma once

#include "cpvs/bake/options.h"
#include "cpvs/dag/dag.h"

namespace cpvs {

/// Builds the levels above the roots of a merged DAG whose roots cover every block of
/// size 2^log2RootSize in the grid, up to one root of the whole grid. A parent whose 8
/// children are all lit (all shadowed) is lit (shadowed), exactly as an untiled build
/// decides, so the result does not depend on the tile size. New levels are deduplicated
/// (except with CompressMode::None). Throws std::invalid_argument for a missing block.
Dag assembleRoots(Dag&& merged, HashKind hash, CompressMode mode = CompressMode::TopDown);

}  // namespace cpvs
