// Helpers shared by the DAG tests: synthetic texel depths, the dense brute-force voxel
// reference, and structural comparison of DAGs.
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <optional>

#include <cstdint>
#include <random>
#include <vector>

#include "cpvs/bake/bake.h"
#include "cpvs/dag/dag.h"
#include "cpvs/bake/insert_tile.h"
#include "cpvs/dag/compress.h"
#include "cpvs/dag/assemble_roots.h"
#include "cpvs/dag/merge.h"
#include "cpvs/dag/streaming_merger.h"
#include "cpvs/bake/column_masks.h"

namespace cpvs::testing {

/// Texel depths of a synthetic scene: axis-aligned boxes over a floor, seen from above.
/// Closed boxes get an interior (hi > lo); open ones do not. Some boxes overlap and some
/// are one texel wide, so masks, transitions and culling all get exercised.
TexelSlices syntheticSlices(uint32_t R, bool closed, uint32_t seed);

/// The sub-block [x0, x0+T) x [y0, y0+T) of row-major depths of width R.
TexelSlices cropSlices(const TexelSlices& d, uint32_t R, uint32_t x0, uint32_t y0, uint32_t T);

/// Inserts (and compresses) one tile of the depths.
Dag buildTile(const TexelSlices& all, int log2R, int log2T, uint32_t tx, uint32_t ty,
                     UndefinedRule rule, bool cull, CompressMode mode, HashKind hash);

/// Whole-grid DAG of the depths built from tiles of 2^log2T, merged in `order`.
Dag buildTiled(const TexelSlices& all, int log2R, int log2T, UndefinedRule rule, bool cull,
                      CompressMode mode, HashKind hash, const std::vector<uint32_t>* order = nullptr);

/// Compares every voxel with the dense reference: lit below lo, shadowed from hi on,
/// either inside [lo, hi). Returns the number of mismatching defined voxels.
uint64_t countReferenceMismatches(const Dag& dag, const TexelSlices& d, uint32_t R,
                                         uint64_t* undefinedShadowed = nullptr);

void expectSameDag(const Dag& a, const Dag& b);

/// No two nodes of a level have the same content (children already canonical).
void expectOptimal(const Dag& dag);

/// Shadow value of voxel (x, y, z) in a sub-DAG (a tile's: roots of size 2^log2RootSize
/// keyed by block position); nullopt when no root holds it.
std::optional<bool> subDagVoxelShadowed(const Dag& dag, uint64_t x, uint64_t y, uint64_t z);

}  // namespace cpvs::testing
