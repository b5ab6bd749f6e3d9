// A complete DAG flattened for lookups (packed_layout.h): the layout the CPU queries
// walk, the .cpvs file stores and a GPU buffer takes as it is.
#pragma once

#include <bit>
#include <cstdint>
#include <cstring>
#include <memory>
#include <optional>
#include <vector>

#include "cpvs/base/error.h"
#include "cpvs/dag/child_codes.h"
#include "cpvs/dag/dag.h"
#include "cpvs/dag/node_pool.h"
#include "cpvs/dag/packed_layout.h"

namespace cpvs {

/// The packed layout of a pool of complete DAGs (node_pool.h): one header per root at
/// word 48 k, each root's pointer grid after the headers in root order, then the shared
/// nodes (top level first) and leaves. Every header lists the pool's levels; offsets are
/// into the whole array. One root gives exactly the layout of a single DAG. Each root's
/// pointer grid has its gridLevels levels (the most by default). `version` is
/// kPackedLayoutVersion but in tests of the older layouts (1, 2: their headers list their
/// own levels; 2 needs at most 65,536 leaves). InputError beyond 2^32 words (16 GiB).
std::vector<uint32_t> packPool(const std::vector<uint64_t>& leaves, const std::vector<InternalLevel>& levels,
                               const std::vector<NodePool::Root>& roots, uint32_t version = kPackedLayoutVersion);
/// The layout version of a packed array (its first header's; 0 for an array too short to
/// hold one).
uint32_t packedLayoutVersion(const std::vector<uint32_t>& words);
/// The pool that packPool packed into `words` for `rootCount` roots, in any layout version
/// it reads (1 to kPackedLayoutVersion), after checking every header, code, offset and grid
/// entry: packing it again in that version must give exactly `words`. InputError naming
/// what is wrong otherwise.
NodePool parsePackedPool(const std::vector<uint32_t>& words, size_t rootCount);

/// One array of 32-bit words: header, pointer grid, internal nodes (in half-words: the
/// codes, then each kRef child's offset in the level below, in one or two half-words),
/// leaves as word pairs. A lookup reads one array,
/// usually one cache line per level below the grid, where Dag's levels spread a node
/// over three arrays (codes, childBegin, children). A light bundle's DAGs share one
/// array (packPool), each with its own header.
static_assert(std::endian::native == std::endian::little, "the walk reads half-words by their byte offset");

class PackedDag {
 public:
  PackedDag() : PackedDag(emptyDag()) {}
  /// Flattens a complete DAG (one root of the grid's size). InputError when it holds
  /// more than 2^32 words (16 GiB).
  explicit PackedDag(const Dag& dag);
  /// DAG `root` of a packed pool (packPool's words, shared with the other roots' views),
  /// which holds `nodeBytes` of it (reachableBytes).
  PackedDag(std::shared_ptr<const std::vector<uint32_t>> pool, size_t root, uint64_t nodeBytes);

  /// Adopts the words of a packed section as they were read, after checking every field,
  /// code, offset and grid entry: the words must be exactly what packing the DAG they
  /// describe gives. An older layout (version 1 or 2) is packed again as today's. The DAG
  /// is returned in `dag` (levels as Dag holds them, no hashes). InputError naming what is
  /// wrong otherwise.
  static PackedDag fromWords(std::vector<uint32_t> words, Dag& dag);

  const PackedHeader& header() const { return header_; }
  int log2Resolution() const { return int(header_.log2Resolution); }
  /// Bytes of the node data (8 per leaf, 2 per node half-word), as Dag::bytes() counts them.
  uint64_t bytes() const { return nodeBytes_; }
  /// Bytes of the whole array, header and pointer grid included: what a GPU holds.
  uint64_t arrayBytes() const { return words_->size() * 4; }

  /// Where the walk to voxel (x, y, z) ends: a homogeneous block (a pointer-grid cell, or
  /// a node's lit or shadowed child) or the 8x8x1 leaf slice holding the voxel. The block
  /// is aligned: its corner is the voxel's coordinates with the low bits cleared.
  struct Block {
    uint64_t mask;  // the leaf slice's 8x8 shadow mask (bit ty*8+tx); all ones or zeros when homogeneous
    int log2Side;   // the block is 2^log2Side voxels in x and y ...
    int log2Depth;  // ... and 2^log2Depth in z (0 for a leaf slice and the slices of a level-0 node)
    bool homogeneous;
  };
  Block block(uint64_t x, uint64_t y, uint64_t z) const {
    const uint32_t* w = w_;
    uint32_t at = w[header_.gridWord + gridCell(log2Resolution(), int(header_.gridLevels), x, y, z)];
    if (at >= kGridShadowed) {
      const int side = log2Resolution() - int(header_.gridLevels);
      return {at == kGridShadowed ? ~uint64_t{0} : 0, side, side, true};
    }
    // `at` is a node's half-word offset in its level, then below level 0 a leaf's index.
    // Half-word h of a level lies at its byte 2h (little-endian words, low half first), so
    // a walk reads its codes and references with plain 16- and 32-bit loads, as it read
    // words before: no shift on the half-word's parity.
    for (int level = header_.cellLevel(); level >= 0; --level) {
      const LevelWalk& lw = levels_[level];
      CPVS_DCHECK(size_t(lw.nodes - w) + at / 2 < words_->size());
      const auto* bytes = reinterpret_cast<const unsigned char*>(lw.nodes);
      uint16_t codes;
      std::memcpy(&codes, bytes + 2 * uint64_t(at), 2);
      const int c = childOfVoxel(level, x, y, z);
      const uint32_t code = childCode(codes, c);
      // A node of level l is 2^(l+3) a side; its children half that, but level 0's are
      // its 8x8x1 depth slices.
      if (code != kRef) return {code == kShadowed ? ~uint64_t{0} : 0, level + 2 + (level == 0), level == 0 ? 0 : level + 2, true};
      // The reference: two half-words read at once, the second masked off when it is one.
      // A reference never lies in the array's last half-word (the leaves follow the nodes).
      const uint32_t p = at + 1 + (uint32_t(refRank(codes, c)) << lw.wide);
      uint32_t ref;
      std::memcpy(&ref, bytes + 2 * uint64_t(p), 4);
      at = ref & lw.mask;
    }
    const uint32_t* leaf = w + header_.leafWord + 2 * uint64_t(at);
    CPVS_DCHECK(header_.leafWord + 2 * uint64_t(at) + 1 < words_->size());
    return {uint64_t(leaf[0]) | uint64_t(leaf[1]) << 32, 3, 0, false};
  }
  /// The 8x8 shadow mask (bit ty*8+tx set = shadowed) of the leaf slice holding voxel
  /// (x, y, z), each < 2^log2Resolution; all ones or zeros inside a homogeneous node. One
  /// walk answers 64 voxels of one depth, which is what a filtered lookup needs: a 9x9
  /// footprint touches at most 4 slices instead of 81 walks (PCF 9x9 on the bunny, 1K-16K:
  /// 1.4-2.5 us per lookup with one walk per texel, 0.14-0.28 us with this).
  uint64_t leafSliceMask(uint64_t x, uint64_t y, uint64_t z) const { return block(x, y, z).mask; }
  /// Shadow value of one voxel: true = shadowed.
  bool voxelShadowed(uint64_t x, uint64_t y, uint64_t z) const {
    return (leafSliceMask(x, y, z) >> leafBit(x, y)) & 1;
  }

  /// The whole array (a bundle's: every root's), as a GPU takes it.
  const std::vector<uint32_t>& words() const { return *words_; }
  /// The word where this DAG's header starts (0 but in a bundle).
  uint32_t headerWord() const { return headerWord_; }

 private:
  static Dag emptyDag();

  std::shared_ptr<const std::vector<uint32_t>> words_;  // immutable: copies share it
  const uint32_t* w_ = nullptr;                         // words_->data()
  uint32_t headerWord_ = 0;
  PackedHeader header_{};  // a copy of the header, read without aliasing the array
  uint64_t nodeBytes_ = 0;
  // What a walk needs of each level, from the header: where its nodes start, and its
  // references' width (wide: 1 for two half-words) and mask.
  struct LevelWalk {
    const uint32_t* nodes = nullptr;
    uint32_t wide = 0;
    uint32_t mask = 0xFFFFu;
  };
  LevelWalk levels_[kMaxInternalLevels];
};

}  // namespace cpvs
