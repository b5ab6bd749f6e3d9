// The fixed geometry of the grid and of the DAG's keys, checked against each other.
#pragma once

namespace cpvs {

/// Smallest and largest supported log2 of the grid resolution R (R = 2^k voxels a side).
constexpr int kMinLog2Resolution = 3;
constexpr int kMaxLog2Resolution = 20;

/// A leaf is 8 x 8 texels of one depth slice: 2^3 a side.
constexpr int kLog2LeafSide = 3;
static_assert(kMinLog2Resolution >= kLog2LeafSide, "a grid holds at least one leaf");

/// Root keys pack a block position in 21 bits per axis (see dag/dag.h).
constexpr int kRootKeyBits = 21;
static_assert(kMaxLog2Resolution - kLog2LeafSide < kRootKeyBits,
              "every block position of the largest grid fits a root key");

}  // namespace cpvs
