// Insertion of a tile's voxels into a DAG in Z-order, with culling of identical nodes (§3.2).
#pragma once

#include <cstdint>

#include "cpvs/dag/dag.h"
#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/min_max_pyramid.h"

namespace cpvs {

struct InsertStats {
  uint64_t nodesCreated = 0;   // internal nodes appended (with cull, distinct ones only)
  uint64_t leavesCreated = 0;  // leaves appended (with cull, distinct ones only)
  uint64_t culledNodes = 0;    // non-homogeneous blocks that reused the node closer to the light
  uint64_t culledLeaves = 0;
};

/// Inserts the tile column (tileX, tileY) of size 2^log2TileSize texels (the whole grid
/// when log2TileSize >= log2Resolution) into `out`, which is reset to hold the tile's
/// roots: R / T nodes of size T stacked in depth, keyed rootKey(tileX, tileY, z).
///
/// With `cull`, blocks are processed nearest to the light first and a non-homogeneous
/// block whose depth range, together with the previous block's, holds no mask transition
/// reuses the previous block's node: the voxels are identical, so the node would be too.
/// Every other block equal to one built before in the tile (found by its content, its
/// children compared by index) shares that block's node too, so the tile comes out with
/// no repeated subtree and compression has only the tiles' order to settle. Without
/// `cull`, every non-homogeneous block gets a node of its own (the baseline). Both
/// produce DAGs of identical voxels; compression makes them identical bytes.
/// Hashes are not computed here (see dag_compress.h).
void insertTile(const ColumnMasks& masks, const MinMaxPyramid& pyramid, int log2Resolution,
                int log2TileSize, uint64_t tileX, uint64_t tileY, bool cull, Dag& out,
                InsertStats* stats = nullptr);

}  // namespace cpvs
