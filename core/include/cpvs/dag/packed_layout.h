// The packed DAG as one flat array of 32-bit words: the layout that a lookup walks on the
// CPU, that the .cpvs file stores (format version 2) and that a GPU buffer holds as it
// is. Everything a walk needs sits in the array, addressed by word offsets from its
// start; the shader include (runtime/shaders) is generated from this header and
// child_codes.h, so the two cannot drift.
//
//   [PackedHeader][pointer grid: 8^gridLevels words][nodes, top level first][leaves]
//
// An internal node is its code word (child_codes.h) followed by one word per kRef child:
// the word offset of that child (a node one level down; for level 0, a leaf). In a pool of
// at most kMaxCompactLeaves leaves (header field leafRefs = 1) a level-0 node is 16-bit
// half-words instead: its codes in the low half of its first word, then the index of each
// kRef child's leaf, low half first, the last word padded with zero; its 8 slices
// mostly differ, and the half-words halve the level that holds most of a DAG's bytes. A leaf is
// two words, the low and high halves of its 8x8 mask, at an even offset, so that a GPU
// binding of an even number of words never splits one. The pointer grid answers the top
// `gridLevels` levels in one read (seed 000 §6.3): entry (cx, cy, cz) holds the node of
// level cellLevel() that covers cell (cx, cy, cz), or kGridLit / kGridShadowed.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cpvs/base/limits.h"

namespace cpvs {

/// Levels of internal nodes a complete DAG of the largest grid has (sizes 8 .. 2^20).
constexpr int kMaxInternalLevels = kMaxLog2Resolution - 2;
/// How many levels the pointer grid replaces at most: 32^3 entries, 128 KiB.
constexpr int kMaxGridLevels = 5;
/// The newest version of this layout, in every header: 2 for arrays whose level 0 names
/// leaves by 16-bit index (leafRefs = 1), 1 for the older layout every other array keeps
/// (an older reader reads those, and refuses the others by their version).
constexpr uint32_t kPackedLayoutVersion = 2;
/// Pointer-grid entries for cells that are homogeneous (above or at the cell level).
constexpr uint32_t kGridLit = 0xFFFFFFFFu;
constexpr uint32_t kGridShadowed = 0xFFFFFFFEu;

/// Word 0 of the array. Plain 32-bit words only, so that a shader reads field k as word k.
struct PackedHeader {
  uint32_t layoutVersion;   // 2 when leafRefs, else 1 (kPackedLayoutVersion)
  uint32_t log2Resolution;  // the grid is 2^log2Resolution voxels a side
  uint32_t internalLevels;  // L = log2Resolution - 2: levels 0 (8^3 nodes) .. L-1 (the root)
  uint32_t gridLevels;      // G = min(kMaxGridLevels, L - 1): the grid is 2^G cells a side
  uint32_t gridWord;        // first word of the pointer grid (8^G entries, x fastest)
  uint32_t leafWord;        // first word of the leaves (even)
  uint32_t leafCount;
  uint32_t wordCount;       // words of the whole array, header included (even)
  uint32_t rootCode;        // the root: kLit, kShadowed, or kRef at rootWord
  uint32_t rootWord;
  uint32_t levelWord[kMaxInternalLevels];   // first word of level l (l < L; 0 beyond)
  uint32_t levelNodes[kMaxInternalLevels];  // nodes of level l
  uint32_t leafRefs;        // 1: level-0 nodes name leaves by 16-bit index (compactLeafRefs); 0: by word offset
  uint32_t reserved;        // zero

  /// The level of the nodes the grid points at: their size is the cell's.
  constexpr int cellLevel() const { return int(internalLevels) - 1 - int(gridLevels); }
};

constexpr uint32_t kPackedHeaderWords = 48;
static_assert(sizeof(PackedHeader) == kPackedHeaderWords * 4, "the header is 48 words");
static_assert(offsetof(PackedHeader, levelWord) == 40 && offsetof(PackedHeader, levelNodes) == 112,
              "the shader include reads the header by these word offsets");

/// The most leaves a pool may hold for its level-0 nodes to name them by 16-bit index.
constexpr uint64_t kMaxCompactLeaves = 65536;
constexpr bool compactLeafRefs(uint64_t leafCount) { return leafCount <= kMaxCompactLeaves; }
/// Words of an internal node of `level` with `refs` kRef children: one code word and one
/// word per child, or at level 0 of a compact pool one half-word each.
constexpr uint32_t packedNodeWords(int level, uint32_t refs, bool compact) {
  return level == 0 && compact ? (refs + 2) / 2 : 1 + refs;
}
/// The word offset of the leaf that kRef child `rank` of the level-0 node at word `at`
/// names in a compact pool whose leaves start at leafWord.
constexpr uint32_t compactLeafWord(const uint32_t* w, uint32_t at, uint32_t rank, uint32_t leafWord) {
  const uint32_t half = 1 + rank;
  return leafWord + 2 * ((w[at + half / 2] >> (16 * (half & 1))) & 0xFFFFu);
}

/// Pointer-grid levels for a grid of 2^log2Resolution.
constexpr int packedGridLevels(int log2Resolution) {
  const int levels = log2Resolution - 2;
  return levels - 1 < kMaxGridLevels ? levels - 1 : kMaxGridLevels;
}

/// The pointer-grid entry of voxel (x, y, z): cells are 2^(log2Resolution - G) voxels.
constexpr uint32_t gridCell(int log2Resolution, int gridLevels, uint64_t x, uint64_t y, uint64_t z) {
  const int shift = log2Resolution - gridLevels;
  return uint32_t((((z >> shift) << gridLevels | (y >> shift)) << gridLevels) | (x >> shift));
}

static_assert(packedNodeWords(0, 1, true) == 1 && packedNodeWords(0, 2, true) == 2 && packedNodeWords(0, 8, true) == 5 &&
              packedNodeWords(0, 8, false) == 9 && packedNodeWords(1, 8, true) == 9);
static_assert(packedGridLevels(3) == 0 && packedGridLevels(8) == 5 && packedGridLevels(20) == 5);
static_assert(gridCell(12, 5, 4095, 0, 128) == (1u << 10) + 31);

}  // namespace cpvs
