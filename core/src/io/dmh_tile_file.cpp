#include "cpvs/io/dmh_tile_file.h"

#include <algorithm>
#include <cstring>

#include "cpvs/base/error.h"
#include "io/bake_fields.h"
#include "io/container.h"

namespace cpvs {
namespace {

constexpr uint32_t kDmhTileFormatVersion = 1;
constexpr ContainerKind kDmhTileKind{{'D', 'G', 'M', 'T'}, kDmhTileFormatVersion, kDmhTileFormatVersion, "DAG-MH tile"};
// More parts than a farm tile holds of the bake's tiles (4K / 512 = 8 a side).
constexpr uint32_t kMaxParts = uint32_t(1) << 16;
// The largest part a reader takes: a whole map of 64K, the largest a DAG-MH is baked at
// (a part's words are bounded by its side).
constexpr uint32_t kMaxLog2PartSide = 16;

std::vector<uint32_t> wordsOf(const std::vector<float>& v) {
  std::vector<uint32_t> w(v.size());
  if (!v.empty()) std::memcpy(w.data(), v.data(), v.size() * 4);
  return w;
}

std::vector<float> floatsOf(const std::vector<uint32_t>& w) {
  std::vector<float> v(w.size());
  if (!w.empty()) std::memcpy(v.data(), w.data(), w.size() * 4);
  return v;
}

}  // namespace

std::vector<uint8_t> encodeDagMhTiles(const std::vector<DagMhTile>& tiles, bool zstd) {
  CPVS_CHECK(tiles.size() <= kMaxParts);
  ByteWriter w;
  beginContainer(w, kDmhTileKind, zstd ? kContainerZstd : 0);
  w.put<uint32_t>(uint32_t(tiles.size()));
  for (const DagMhTile& t : tiles) {
    w.put<uint32_t>(uint32_t(t.log2Side));
    w.put<uint32_t>(uint32_t(t.log2TileSide));
    w.put<uint64_t>(t.tileX);
    w.put<uint64_t>(t.tileY);
    w.put<uint32_t>(uint32_t(t.levels.size()));
    w.put<uint32_t>(t.root);
    w.put<uint64_t>(t.valuesBelow);
    w.put<float>(t.lo);
    w.put<float>(t.hi);
    w.put<uint32_t>(t.hasFull ? 1 : 0);
    for (const std::vector<uint32_t>& level : t.levels) putWordSection(w, level, zstd);
    putWordSection(w, t.treelets, zstd);
    putWordSection(w, wordsOf(t.valueLo), zstd);
    putWordSection(w, wordsOf(t.valueHi), zstd);
  }
  return sealContainer(std::move(w));
}

std::vector<DagMhTile> decodeDagMhTiles(const uint8_t* data, size_t size, const std::string& source,
                                        const DagMhTileShape* expected) {
  uint32_t flags = 0, version = 0;
  ByteReader h = openContainer(data, size, source, kDmhTileKind, kContainerZstd, flags, version);
  const bool zstd = (flags & kContainerZstd) != 0;
  const uint32_t count = h.get<uint32_t>("header");
  if (count == 0 || count > kMaxParts || (expected && count != expected->parts))
    h.fail(std::to_string(count) + " tiles" + (expected ? " where " + std::to_string(expected->parts) + " are expected" : ""));
  std::vector<DagMhTile> tiles(count);
  for (DagMhTile& t : tiles) {
    // The sides as stored, checked before they are used.
    const uint32_t side = h.get<uint32_t>("tile header"), tileSide = h.get<uint32_t>("tile header");
    if (side > 20 || tileSide > side || tileSide > kMaxLog2PartSide ||
        (expected && (int(side) != expected->log2Side || int(tileSide) != expected->log2TileSide)))
      h.fail("a tile of 2^" + std::to_string(tileSide) + " in a map of 2^" + std::to_string(side));
    t.log2Side = int(side);
    t.log2TileSide = int(tileSide);
    t.tileX = h.get<uint64_t>("tile header");
    t.tileY = h.get<uint64_t>("tile header");
    const uint32_t levels = h.get<uint32_t>("tile header");
    if (levels != uint32_t(std::max(0, t.innerLevels()))) h.fail(std::to_string(levels) + " inner levels in a tile");
    t.root = h.get<uint32_t>("tile header");
    t.valuesBelow = h.get<uint64_t>("tile header");
    t.lo = h.get<float>("tile header");
    t.hi = h.get<float>("tile header");
    const uint32_t hasFull = h.get<uint32_t>("tile header");
    if (hasFull > 1) h.fail("a tile flag of " + std::to_string(hasFull));
    t.hasFull = hasFull != 0;
    // No more words than the part's geometry holds: local level l has at most 4^l nodes
    // of at most 9 words, the treelets' level 4^levels treelets, the tile a value a node.
    t.levels.resize(levels);
    for (uint32_t l = 0; l < levels; ++l)
      t.levels[l] = getWordSection(h, zstd, 0, "a tile's inner nodes", 9 * (uint64_t(1) << (2 * l)));
    t.treelets = getWordSection(h, zstd, 0, "a tile's treelets", kTreeletWords * (uint64_t(1) << (2 * levels)));
    const uint64_t maxValues = ((uint64_t(1) << (2 * (tileSide + 1))) - 1) / 3;
    t.valueLo = floatsOf(getWordSection(h, zstd, 0, "a tile's value intervals", maxValues));
    t.valueHi = floatsOf(getWordSection(h, zstd, 0, "a tile's value intervals", maxValues));
    validateDagMhTile(t, source);
  }
  if (h.remaining() != 0) h.fail(std::to_string(h.remaining()) + " unexpected bytes after the payload");
  return tiles;
}

}  // namespace cpvs
