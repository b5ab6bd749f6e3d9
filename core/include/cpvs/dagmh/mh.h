// The multiresolution hierarchy (MH) of a dual-depth map: a quadtree whose nodes carry one
// depth that every covered descendant inherits [SBE16a], built bottom-up by the rule
// NOTES §2.2.2 states (seed 001 describes it only in words).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "cpvs/dagmh/texel_intervals.h"

namespace cpvs {

/// What a node is to a lookup: it stores its own value (Full: its parent does not cover
/// it), it only leads to nodes that do (Empty), or nothing below it stores one (Absent:
/// dropped, a lookup keeps the value it has).
enum class MhState : uint8_t { Absent = 0, Empty = 1, Full = 2 };

/// Child c of a node at level l (children at level l + 1) is the one holding texel (x, y)
/// when c = (((y >> s) & 1) << 1) | ((x >> s) & 1), s = log2Side - l - 1: the order of the
/// CPU, the GPU and the value list's preorder.
inline uint32_t mhChild(uint64_t x, uint64_t y, int shift) {
  return uint32_t(((y >> shift) & 1) << 1 | ((x >> shift) & 1));
}

/// The hierarchy over a map of 2^L x 2^L texels: level 0 is the root, level L the texels.
/// A node's interval is where its value may lie: the intersection of the intervals of the
/// children it covers. Its subtree depends only on its own children, never on what lies
/// above, which is what lets tiles be built apart (NOTES §2.5).
class Mh {
 public:
  /// Builds the hierarchy of `texels` (side a power of two; InputError for an interval
  /// that is not finite or has lo > hi). `bottomHasFull`, when not empty, says per bottom
  /// node that something below it stores a value: the bottom level is then the roots of
  /// tiles built apart, not texels.
  explicit Mh(TexelIntervals texels, std::vector<uint8_t> bottomHasFull = {});
  Mh() = default;
  /// The same, in this hierarchy's storage: `texels` gets back buffers of its size whose
  /// contents are unspecified, for the next tile of the same side.
  void rebuild(TexelIntervals& texels, std::vector<uint8_t> bottomHasFull = {});

  int log2Side() const { return log2Side_; }
  uint32_t side(int level) const { return 1u << level; }

  float lo(int level, uint64_t x, uint64_t y) const { return levels_[size_t(level)].lo[at(level, x, y)]; }
  float hi(int level, uint64_t x, uint64_t y) const { return levels_[size_t(level)].hi[at(level, x, y)]; }
  /// The value a full node stores: the middle of its interval.
  float value(int level, uint64_t x, uint64_t y) const;
  /// Bit c: the node covers child c (its value lies in the child's interval).
  uint8_t covered(int level, uint64_t x, uint64_t y) const { return levels_[size_t(level)].covered[at(level, x, y)]; }
  /// Whether some node strictly below this one stores a value.
  bool hasFull(int level, uint64_t x, uint64_t y) const { return levels_[size_t(level)].hasFull[at(level, x, y)] != 0; }
  /// The node's state; the root is always Full. (Inline: the hierarchy's walks call it
  /// for every node.)
  MhState state(int level, uint64_t x, uint64_t y) const {
    if (level == 0) return MhState::Full;
    if (!(covered(level - 1, x / 2, y / 2) >> mhChild(x, y, 0) & 1)) return MhState::Full;
    return hasFull(level, x, y) ? MhState::Empty : MhState::Absent;
  }

  /// The value a lookup of texel (x, y) finds: that of the last full node on its path.
  float lookup(uint64_t x, uint64_t y) const;

 private:
  struct Level {
    std::vector<float> lo, hi;
    std::vector<uint8_t> covered, hasFull;  // covered: none at the bottom level
  };
  size_t at(int level, uint64_t x, uint64_t y) const { return size_t(y) * side(level) + size_t(x); }

  int log2Side_ = 0;
  std::vector<Level> levels_;  // [0] the root ... [L] the bottom
};

}  // namespace cpvs
