// The packed DAG as one flat array of 32-bit words: the layout that a lookup walks on the
// CPU, that the .cpvs file stores and that a GPU buffer holds as it is. Everything a walk
// needs sits in the array; the shader include (runtime/shaders) is generated from this
// header and child_codes.h, so the two cannot drift.
//
//   [PackedHeader][pointer grid: 8^gridLevels words][nodes, top level first][leaves]
//
// Layout version 3 (what is written): the nodes are 16-bit half-words. A node is its codes
// (child_codes.h) in one half-word, then one reference per kRef child, in child order: the
// child's half-word offset from the start of the level below, or below level 0 its leaf's
// index. A level's references take one half-word when what they name fits 16 bits (the
// level below holds at most 65,536 half-words, or there are at most 65,536 leaves), else
// two, low half first (header field wideRefs, a bit per level); each level starts at a word.
// Most levels of a real DAG name a level below of more than 65,536 half-words, so the
// gain over a word per code and per reference is the code's half-word and, near the top
// and at level 0 of smaller pools, half of every reference.
// A leaf is two words, the low and high halves of its 8x8 mask, at an even offset, so
// that a GPU binding of an even number of words never splits one. The pointer grid
// answers the top `gridLevels` levels in one read (seed 000 §6.3): entry (cx, cy, cz)
// holds the half-word offset, in level cellLevel(), of the node that covers cell
// (cx, cy, cz), or kGridLit / kGridShadowed.
//
// Versions 1 and 2 (arrays written before version 3; read, and packed again as version 3):
// a code word and one word per reference, the child's word offset in the array (below
// level 0 its leaf's word); version 2 names level 0's leaves by 16-bit index in half-words,
// each node padded to a word.
#pragma once

#include <cstddef>
#include <cstdint>

#include "cpvs/base/limits.h"

namespace cpvs {

/// Levels of internal nodes a complete DAG of the largest grid has (sizes 8 .. 2^20).
constexpr int kMaxInternalLevels = kMaxLog2Resolution - 2;
/// How many levels the pointer grid replaces at most: 32^3 entries, 128 KiB.
constexpr int kMaxGridLevels = 5;
/// The version of this layout that is written, in every header (an older reader refuses
/// it by its version). Versions 1 and 2 are read (packPool writes them for tests).
constexpr uint32_t kPackedLayoutVersion = 3;
/// Pointer-grid entries for cells that are homogeneous (above or at the cell level).
constexpr uint32_t kGridLit = 0xFFFFFFFFu;
constexpr uint32_t kGridShadowed = 0xFFFFFFFEu;

/// Word 0 of the array. Plain 32-bit words only, so that a shader reads field k as word k.
struct PackedHeader {
  uint32_t layoutVersion;   // kPackedLayoutVersion (1 or 2 in an older array)
  uint32_t log2Resolution;  // the grid is 2^log2Resolution voxels a side
  uint32_t internalLevels;  // L = log2Resolution - 2: levels 0 (8^3 nodes) .. L-1 (the root)
  uint32_t gridLevels;      // G = min(kMaxGridLevels, L - 1): the grid is 2^G cells a side
  uint32_t gridWord;        // first word of the pointer grid (8^G entries, x fastest)
  uint32_t leafWord;        // first word of the leaves (even)
  uint32_t leafCount;
  uint32_t wordCount;       // words of the whole array, header included (even)
  uint32_t rootCode;        // the root: kLit, kShadowed, or kRef at rootWord
  uint32_t rootWord;        // the root's half-word offset in level L - 1 (before version 3: its word)
  // First word and node count of level l, for every level of the pool, the same in every
  // header of a pool (before version 3: the header's own levels l < L only); 0 beyond.
  uint32_t levelWord[kMaxInternalLevels];
  uint32_t levelNodes[kMaxInternalLevels];
  // Bit l set: level l names its children by two half-words (wideRefsInto). Before version
  // 3: 1 in version 2 (level 0 names leaves by 16-bit index), 0 in version 1.
  uint32_t wideRefs;
  uint32_t reserved;        // zero

  /// The level of the nodes the grid points at: their size is the cell's.
  constexpr int cellLevel() const { return int(internalLevels) - 1 - int(gridLevels); }
};

constexpr uint32_t kPackedHeaderWords = 48;
static_assert(sizeof(PackedHeader) == kPackedHeaderWords * 4, "the header is 48 words");
static_assert(offsetof(PackedHeader, levelWord) == 40 && offsetof(PackedHeader, levelNodes) == 112,
              "the shader include reads the header by these word offsets");

/// The most half-words a level (or leaves) may hold for the references into it to be 16-bit.
constexpr uint64_t kMaxNarrowRefTargets = 65536;
/// Whether references into `targets` half-words of a level (or `targets` leaves) take two
/// half-words.
constexpr bool wideRefsInto(uint64_t targets) { return targets > kMaxNarrowRefTargets; }

/// How one level of a packed array holds its nodes, in half-words: the codes, then
/// refHalves per reference; before version 3 each node is whole words.
struct PackedLevelForm {
  uint32_t codeHalves = 1;  // 2 before version 3: a code word
  uint32_t refHalves = 1;   // 1 or 2
  bool wordAligned = false;
  constexpr uint64_t nodeHalves(uint64_t refs) const {
    const uint64_t h = codeHalves + refs * refHalves;
    return wordAligned ? h + (h & 1) : h;
  }
};

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

static_assert(PackedLevelForm{}.nodeHalves(8) == 9 && PackedLevelForm{1, 2, false}.nodeHalves(3) == 7 &&
              PackedLevelForm{1, 1, true}.nodeHalves(2) == 4 && PackedLevelForm{2, 2, true}.nodeHalves(1) == 4);
static_assert(!wideRefsInto(65536) && wideRefsInto(65537));
static_assert(packedGridLevels(3) == 0 && packedGridLevels(8) == 5 && packedGridLevels(20) == 5);
static_assert(gridCell(12, 5, 4095, 0, 128) == (1u << 10) + 31);

}  // namespace cpvs
