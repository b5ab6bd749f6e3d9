// A complete DAG flattened for lookups: the layout the CPU queries walk and the one a GPU
// buffer takes as it is.
#pragma once

#include <cstdint>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/dag/child_codes.h"
#include "cpvs/dag/dag.h"

namespace cpvs {

/// Every internal node is one word of child codes (bits 0..15, as InternalLevel::codes)
/// followed by the word offsets of its kRef children in `words` (for a node of size 8,
/// whose children are leaves: their indices in `leaves`). A lookup then reads one array,
/// one node after another, usually one cache line per level, where Dag's levels spread a
/// node over three arrays (codes, childBegin, children).
class PackedDag {
 public:
  PackedDag() = default;
  /// Flattens a complete DAG (one root of the grid's size). InputError when it holds
  /// more than 2^32 words (16 GiB).
  explicit PackedDag(const Dag& dag);

  int log2Resolution() const { return log2Resolution_; }
  uint64_t bytes() const { return words_.size() * 4 + leaves_.size() * 8; }

  /// The 8x8 shadow mask (bit ty*8+tx set = shadowed) of the leaf slice holding voxel
  /// (x, y, z), each < 2^log2Resolution; all ones or zeros inside a homogeneous node. One
  /// walk answers 64 voxels of one depth, which is what a filtered lookup needs: a 9x9
  /// footprint touches at most 4 slices instead of 81 walks (PCF 9x9 on the bunny, 1K-16K:
  /// 1.4-2.5 us per lookup with one walk per texel, 0.14-0.28 us with this).
  uint64_t leafSliceMask(uint64_t x, uint64_t y, uint64_t z) const {
    uint32_t code = rootCode_, at = rootAt_;
    for (int level = internalLevels_ - 1; level >= 0 && code == kRef; --level) {
      CPVS_DCHECK(at < words_.size());
      const uint32_t codes = words_[at];
      const int c = childOfVoxel(level, x, y, z);
      code = childCode(codes, c);
      if (code != kRef) break;
      at = words_[at + 1 + uint32_t(refRank(codes, c))];
    }
    CPVS_DCHECK(code != kRef || at < leaves_.size());
    if (code == kRef) return leaves_[at];
    return code == kShadowed ? ~uint64_t{0} : 0;
  }
  /// Shadow value of one voxel: true = shadowed.
  bool voxelShadowed(uint64_t x, uint64_t y, uint64_t z) const {
    return (leafSliceMask(x, y, z) >> leafBit(x, y)) & 1;
  }

  const std::vector<uint32_t>& words() const { return words_; }
  const std::vector<uint64_t>& leaves() const { return leaves_; }

 private:
  std::vector<uint32_t> words_;
  std::vector<uint64_t> leaves_;
  uint32_t rootCode_ = kLit, rootAt_ = 0;
  int internalLevels_ = 0, log2Resolution_ = 0;
};

}  // namespace cpvs
