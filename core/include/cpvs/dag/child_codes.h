// The child codes of an internal node and the arithmetic on them: the one definition
// that the builder, the readers, the level and packed walks and the GPU shader share.
// Every function is constexpr and branch-free where it sits in a lookup's inner loop.
#pragma once

#include <bit>
#include <cstdint>

namespace cpvs {

/// 2-bit child codes of an internal node; child c of a node lives in bits 2c..2c+1 of
/// its 16-bit code word.
enum ChildCode : uint32_t {
  kLit = 0,       // the child's volume is entirely lit
  kShadowed = 1,  // entirely shadowed
  kRef = 2,       // a node one level down describes it
  // 3 is not a code: readers reject it.
};

constexpr int kChildren = 8;
/// The bits of the code word that hold codes: 2 per child.
constexpr uint32_t kCodeWordMask = 0xFFFFu;
/// The low bit of every child's code (01 repeated).
constexpr uint32_t kLowCodeBits = 0x5555u;

/// The code of child c.
constexpr uint32_t childCode(uint32_t codes, int child) { return (codes >> (2 * child)) & 3u; }

/// One bit per child whose code is kRef (binary 10: high bit set, low bit clear), at
/// the child's low bit position.
constexpr uint32_t refBits(uint32_t codes) { return (codes >> 1) & ~codes & kLowCodeBits; }

/// How many children of the node are kRef: the node's reference count.
constexpr int refCount(uint32_t codes) { return std::popcount(refBits(codes & kCodeWordMask)); }

/// Rank of child c among the node's kRef children (how many come before it): the
/// position of its reference after the code word.
constexpr int refRank(uint32_t codes, int child) {
  return std::popcount(refBits(codes & ((1u << (2 * child)) - 1)));
}

/// True when every code of the word is one of kLit, kShadowed, kRef (no 3).
constexpr bool validCodes(uint32_t codes) { return (codes & (codes >> 1) & kLowCodeBits) == 0; }

/// The octree child index of a block at block coordinates (x, y, z) inside its parent:
/// c = dz * 4 + dy * 2 + dx, from the lowest bit of each coordinate.
constexpr int octant(uint64_t x, uint64_t y, uint64_t z) { return int((z & 1) << 2 | (y & 1) << 1 | (x & 1)); }

/// The child of a node of level `level` (size 2^(level + 3)) that holds voxel (x, y, z):
/// for level 0 the depth slice z mod 8 (its children are 8x8x1 leaves), above it the
/// octant of the voxel's half-size block.
constexpr int childOfVoxel(int level, uint64_t x, uint64_t y, uint64_t z) {
  const int shift = level + 2;
  return level == 0 ? int(z & 7) : octant(x >> shift, y >> shift, z >> shift);
}

/// The bit of voxel (x, y) in its 8x8 leaf mask (bit ty * 8 + tx).
constexpr int leafBit(uint64_t x, uint64_t y) { return int((y & 7) * 8 + (x & 7)); }

static_assert(refCount(0xAAAAu) == 8 && refCount(0x5555u) == 0 && refCount(0x0002u) == 1);
static_assert(refRank(0x0A0Au, 5) == 3 && refRank(0x0A0Au, 0) == 0);
static_assert(validCodes(0x6996u) && !validCodes(0x0003u) && !validCodes(0xC000u));
static_assert(childOfVoxel(0, 5, 6, 13) == 5 && childOfVoxel(1, 0, 8, 0) == 2 && childOfVoxel(1, 8, 0, 8) == 5);

}  // namespace cpvs
