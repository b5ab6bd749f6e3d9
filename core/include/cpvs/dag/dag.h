// The shadow DAG as it is built, compressed and merged: flat, index-based levels, the
// layout written to disk and sent between processes. Queries walk its packed form
// (packed_dag.h).
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "cpvs/base/hash.h"
#include "cpvs/base/limits.h"
#include "cpvs/dag/child_codes.h"
#include "cpvs/dag/packed_layout.h"

namespace cpvs {

/// A child or root: a code, and for kRef the index of the node in its level.
struct NodeRef {
  uint32_t code = kLit;
  uint32_t index = 0;
  constexpr bool operator==(const NodeRef&) const = default;
};

/// One level of internal nodes. Node i has 8 child codes (child c in bits 2c..2c+1 of
/// codes[i]) and its kRef children, in child order, at children[childBegin[i] ..
/// childBegin[i+1]). Octree children are ordered c = dz*4 + dy*2 + dx; the children of a
/// node of size 8 are its 8 depth slices (leaves).
struct InternalLevel {
  std::vector<uint16_t> codes;
  std::vector<uint32_t> childBegin{0};
  std::vector<uint32_t> children;

  size_t size() const { return codes.size(); }
  uint32_t refCount(size_t i) const { return childBegin[i + 1] - childBegin[i]; }
  /// Appends a node; `refs` holds one index per kRef code, in child order.
  uint32_t append(uint16_t nodeCodes, const uint32_t* refs);
  /// The reference of child c of node i.
  NodeRef child(size_t i, int c) const;
  void clear() {
    codes.clear();
    childBegin.assign(1, 0);
    children.clear();
  }
};

/// A DAG of the voxel grid, or of part of it (the sub-DAG of a tile, a partial merge).
/// Leaves are 64-bit masks of 8x8x1 voxels (bit ty*8+tx set = shadowed). levels[i] holds
/// the nodes of size 2^(i+3) voxels a side. `roots` are nodes of size 2^log2RootSize,
/// keyed by their block position; a complete DAG has one root with key 0 and
/// log2RootSize == log2Resolution.
///
/// Hashes (leafHashes, levelHashes) are kept while a DAG is built, compressed or merged;
/// a compressed DAG has every level sorted by (hash, content) and free of duplicates.
struct Dag {
  struct Root {
    uint64_t key = 0;
    NodeRef ref;
    constexpr bool operator==(const Root&) const = default;
  };

  int log2Resolution = 0;
  int log2RootSize = 0;
  std::vector<uint64_t> leaves;
  std::vector<InternalLevel> levels;
  std::vector<Hash128> leafHashes;
  std::vector<std::vector<Hash128>> levelHashes;
  std::vector<Root> roots;

  /// Number of internal levels for roots of size 2^log2RootSize (sizes 8 .. root).
  static int internalLevels(int log2RootSize) { return log2RootSize - 2; }
  /// Resets to an empty DAG with the right number of levels.
  void reset(int log2Res, int log2Root);
  size_t nodeCount() const;
  /// Bytes of the node data as a packed array of layout `version` holds them
  /// (packed_layout.h): 8 per leaf, and per node 2 for its codes and 2 or 4 per child
  /// reference (a level's padding to a word is not node data).
  uint64_t bytes(uint32_t version = kPackedLayoutVersion) const;
  uint64_t levelBytes(int level, uint32_t version = kPackedLayoutVersion) const;  // -1 = leaves
};

/// The form of each level of `levels` (level 0 first) in a packed array of layout `version`
/// whose pool holds `leafCount` leaves: in version 3 a level's references are 16-bit when
/// the level below (or the leaves) fits them (wideRefsInto).
std::vector<PackedLevelForm> packedLevelForms(const std::vector<InternalLevel>& levels, uint64_t leafCount,
                                              uint32_t version = kPackedLayoutVersion);
/// Half-words of the nodes of `level` in `form`.
uint64_t packedLevelHalves(const InternalLevel& level, PackedLevelForm form);

/// Packs a root block position into a key (kRootKeyBits = 21 bits each; positions < 2^21).
constexpr uint64_t kRootKeyAxisMask = (uint64_t(1) << kRootKeyBits) - 1;
constexpr uint64_t rootKey(uint64_t bx, uint64_t by, uint64_t bz) {
  return (bx << (2 * kRootKeyBits)) | (by << kRootKeyBits) | bz;
}
constexpr uint64_t rootKeyX(uint64_t key) { return key >> (2 * kRootKeyBits); }
constexpr uint64_t rootKeyY(uint64_t key) { return (key >> kRootKeyBits) & kRootKeyAxisMask; }
constexpr uint64_t rootKeyZ(uint64_t key) { return key & kRootKeyAxisMask; }

/// Shadow value of voxel (x, y, z) (each < 2^log2Resolution) in a complete DAG: true =
/// shadowed. The reference walk that every other lookup is checked against.
bool dagVoxelShadowed(const Dag& dag, uint64_t x, uint64_t y, uint64_t z);

}  // namespace cpvs
