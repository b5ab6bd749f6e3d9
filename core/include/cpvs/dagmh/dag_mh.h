// DAG-MH (seed 001): an MH's shape stored as a DAG that merges equal subtree shapes
// whatever their values, its lowest four levels as 85-bit treelets, and its values apart,
// in preorder, chunked (value_chunks.h). Layouts: NOTES §2.2.3-§2.2.6, words the same on
// disk and on the GPU.
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "cpvs/dagmh/mh.h"
#include "cpvs/dagmh/value_chunks.h"

namespace cpvs {

/// What an inner node's child is (2 bits per child in its first word).
enum DagMhChild : uint32_t { kDagMhAbsent = 0, kDagMhEmptyInner = 1, kDagMhFullInner = 2, kDagMhTreelet = 3 };

/// A treelet: the node and the three levels below it (1 + 4 + 16 + 64 nodes), one bit per
/// node that stores a value, in preorder; the node at depth n on the path l0, l1, l2 is bit
/// n + 21 l0 + 5 l1 + l2 (l_i = 0 for i >= n). Bits 85..95 are zero.
constexpr uint32_t kTreeletWords = 3;
constexpr int kTreeletLevels = 4;
inline uint32_t treeletBit(int depth, uint32_t l0, uint32_t l1, uint32_t l2) {
  return uint32_t(depth) + 21 * (depth > 0 ? l0 : 0) + 5 * (depth > 1 ? l1 : 0) + (depth > 2 ? l2 : 0);
}

/// A skip-list entry (3 words): the node at the skip level, where a lookup starts.
struct DagMhSkip {
  uint32_t typePtr = 0;  // bits 0..1: DagMhChild; bits 2..31: the node's word offset
  uint32_t first = 0;    // index of the node's first value (its own when full)
  uint32_t last = 0;     // the value index a lookup holds above it
};
static_assert(sizeof(DagMhSkip) == 12);

/// The largest skip level, and how many levels above the treelets it stays.
constexpr int kDagMhSkipLevel = 6;

/// A complete DAG-MH of a 2^log2Side map.
///
/// Inner node (words): w0 bits 2c..2c+1 = the type of child c; w1 = the values strictly
/// below the node; then per child present, in order: its pointer (a word offset in `nodes`
/// for an inner child, a treelet index for a treelet) and, except for the first, the
/// values below the node before that child's subtree. Nodes lie level by level from the
/// root, each level in the order its parents first name them, so every pointer leads
/// forward and the layout is a function of the shape alone.
struct DagMh {
  int log2Side = 0;
  uint32_t rootType = kDagMhFullInner;  // kDagMhFullInner (at nodes[0]) or kDagMhTreelet (treelet 0)
  std::vector<uint32_t> nodes;
  std::vector<uint32_t> treelets;  // kTreeletWords per treelet
  ValueChunks values;
  int skipLevel = 0;  // 0: no skip list
  std::vector<DagMhSkip> skip;

  /// Where the value of texel (x, y) is in the value list.
  uint32_t valueIndex(uint64_t x, uint64_t y) const;
  /// The depth stored for texel (x, y): inside its interval.
  float depth(uint64_t x, uint64_t y) const { return values.value(valueIndex(x, y)); }
  /// The depths of the texels [x0, x0 + width) x [y0, y0 + height) (inside the map, at
  /// most 1024 of them: a filter's footprint), row by row into `out`: one descent shared by all of them (a filter's footprint reads the
  /// nodes above it once), each value decoded once per run of equal indices.
  void depths(uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, float* out) const;

  uint64_t innerNodeCount() const;
  uint64_t treeletCount() const { return treelets.size() / kTreeletWords; }
  /// Bytes of each part as stored (seed 001's Tables 3 and 4).
  uint64_t structureBytes() const { return (nodes.size() + treelets.size()) * 4; }
  uint64_t skipBytes() const { return skip.size() * sizeof(DagMhSkip); }
  uint64_t bytes() const { return structureBytes() + values.bytes() + skipBytes(); }
};

/// The values of a hierarchy's full nodes in preorder (children in mhChild order), as
/// their intervals: what encodeValueChunks chooses within.
void mhValueIntervals(const Mh& mh, std::vector<float>& lo, std::vector<float>& hi);

/// One tile's part of a DAG-MH on its own, what a farm worker sends (NOTES §2.5): the
/// unique shapes of the tile's inner levels and treelets, whose pointers name the tile's
/// own shapes; its root's shape, interval and values; its values' intervals in preorder.
struct DagMhTile {
  int log2Side = 0, log2TileSide = 0;  // the map's and the tile's
  uint64_t tileX = 0, tileY = 0;
  /// Per local level 0 .. (the treelets' level - 1) the tile's unique inner nodes, words
  /// one after another (as DagMh::nodes, a pointer naming a node of the level below or a
  /// treelet by its place in that list).
  std::vector<std::vector<uint32_t>> levels;
  std::vector<uint32_t> treelets;  // kTreeletWords each
  uint32_t root = 0;               // the root's place in levels[0] (in treelets when none)
  uint64_t valuesBelow = 0;        // values strictly below the root
  float lo = 0, hi = 0;            // the root's interval
  bool hasFull = false;            // whether anything below the root stores a value
  std::vector<float> valueLo, valueHi;  // the intervals of those values, in preorder

  /// The number of local inner levels a tile of this map has.
  int innerLevels() const;
};

/// The part of tile (tileX, tileY) of a 2^log2Side map, from the tile's hierarchy.
/// InputError for a tile smaller than 16 texels a side in a map of more than one tile.
DagMhTile dagMhTile(int log2Side, uint64_t tileX, uint64_t tileY, const Mh& tile);

/// Checks everything DagMhBuilder::addTile trusts of a part that came from elsewhere:
/// sizes, child types (inner nodes above, treelets at the treelets' level), pointers to
/// shapes that exist, value counts and prefixes, treelet padding, the root, as many
/// finite, ordered value intervals as the root has values below it. FormatError naming
/// `source` otherwise.
void validateDagMhTile(const DagMhTile& tile, const std::string& source);

/// The unique shapes of a map or a tile (dag_mh.cpp's).
struct DagMhShapes;

/// Builds a DAG-MH tile by tile: a node's subtree depends only on what lies below it
/// (mh.h), so each tile's hierarchy is built and its shapes merged on its own, and the
/// hierarchy above the tiles is built from their roots at the end (NOTES §2.5). The bytes
/// depend neither on the tile size nor on the order tiles are added in: the same as
/// encodeDagMh of the whole map's hierarchy.
class DagMhBuilder {
 public:
  /// A map of 2^log2Side texels a side in tiles of 2^log2TileSide (at least 16 texels
  /// when there is more than one tile; InputError otherwise).
  DagMhBuilder(int log2Side, int log2TileSide);
  ~DagMhBuilder();
  DagMhBuilder(const DagMhBuilder&) = delete;
  DagMhBuilder& operator=(const DagMhBuilder&) = delete;

  int log2Side() const { return log2Side_; }
  int log2TileSide() const { return log2TileSide_; }
  /// Merges a tile's part in: its shapes into the map's by content. InputError for a part
  /// of another map or tile size, or a tile added before (validateDagMhTile first for a
  /// part from elsewhere).
  void addTile(DagMhTile&& tile);
  /// Merges tile (tileX, tileY)'s hierarchy (of the tile's side) in.
  void addTile(uint64_t tileX, uint64_t tileY, const Mh& tile) { addTile(dagMhTile(log2Side_, tileX, tileY, tile)); }
  /// Bytes held so far: the shapes and the tiles' value intervals (a farm's merge memory).
  uint64_t heldBytes() const { return held_; }
  /// Whether tile (tileX, tileY) is in.
  bool hasTile(uint64_t tileX, uint64_t tileY) const;
  /// The DAG-MH, once every tile is in (InputError otherwise): the levels above the tiles,
  /// the layout, the values in preorder chunked, the skip list.
  DagMh finish();

 private:
  struct Tile {
    bool added = false;
    uint32_t node = 0;         // the root's shape: a pool index at the tiles' level
    uint64_t valuesBelow = 0;  // values strictly below the root
    float lo = 0, hi = 0;      // the root's interval
    bool hasFull = false;      // whether anything below it stores a value
    std::vector<float> valueLo, valueHi;  // the intervals of those values, in preorder
  };
  int log2Side_, log2TileSide_, tileLevel_, treeletLevel_;
  std::unique_ptr<DagMhShapes> pools_;
  std::vector<Tile> tiles_;
  uint64_t held_ = 0;
};

/// Encodes a hierarchy: shapes merged, treelets, values chunked, the skip list.
DagMh encodeDagMh(const Mh& mh);

/// Checks everything a lookup trusts (NOTES §2.4.5): child types and pointers in range and
/// leading forward to node starts, the counts and prefixes, treelet padding bits, the root,
/// the chunks' widths and offsets within the factor stream, the skip list against a fresh
/// descent. Throws FormatError naming `source` and the word.
void validateDagMh(const DagMh& dag, const std::string& source);

}  // namespace cpvs
