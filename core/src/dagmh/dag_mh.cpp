#include "cpvs/dagmh/dag_mh.h"

#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>
#include <array>
#include <bit>
#include <unordered_map>

#include "cpvs/base/error.h"
#include "dagmh/bit_count.h"

namespace cpvs {

namespace {

// The level of the treelets' roots: the lowest four levels, or the whole map when it has
// fewer.
int treeletLevel(int log2Side) { return std::max(0, log2Side - (kTreeletLevels - 1)); }

// A skip list where it pays (NOTES §2.2.6): a level near the root, above the treelets,
// at most 1/4^7 of the texels, so that it stays a small part of the structure.
int skipLevelFor(int log2Side) { return std::clamp(log2Side - 7, 0, kDagMhSkipLevel); }

// Words an inner node of w0 `types` takes: two, then a pointer per child present and a
// prefix count per child after the first.
uint32_t innerWords(uint32_t types) {
  uint32_t present = 0;
  for (int c = 0; c < 4; ++c) present += ((types >> (2 * c)) & 3) != kDagMhAbsent;
  return present == 0 ? 2 : 2 * present + 1;
}
uint32_t pointerWord(uint32_t k) { return k == 0 ? 2 : 2 * k + 1; }
uint32_t prefixWord(uint32_t k) { return 2 * k + 2; }

uint32_t treeletValues(const uint32_t* t) {
  return uint32_t(bitCount(t[0]) + bitCount(t[1]) + bitCount(t[2]));
}
// Set bits of the treelet before bit i.
uint32_t treeletRank(const uint32_t* t, uint32_t i) {
  uint32_t n = 0;
  for (uint32_t w = 0; w < i / 32; ++w) n += uint32_t(bitCount(t[w]));
  if (i % 32) n += uint32_t(bitCount(t[i / 32] & ((1u << (i % 32)) - 1)));
  return n;
}
bool treeletHas(const uint32_t* t, uint32_t i) { return t[i / 32] >> (i % 32) & 1; }

// Where a lookup stands: the node it is at and the value indices it holds.
struct Descent {
  uint32_t type = kDagMhAbsent, ptr = 0;
  uint32_t first = 0;  // the node's first value index
  uint32_t last = 0;   // the value a lookup returns if nothing below stores one
  int level = 0;
};

Descent rootDescent(const DagMh& dag) {
  Descent d;
  d.type = dag.rootType;
  return d;
}

// Descends inner nodes towards texel (x, y) down to `stopLevel`, or to a treelet or an
// absent child. The loop is bounded by the levels, whatever the words say.
void descend(const DagMh& dag, Descent& d, uint64_t x, uint64_t y, int stopLevel) {
  while (d.level < stopLevel && (d.type == kDagMhFullInner || d.type == kDagMhEmptyInner)) {
    uint32_t base = d.first;
    if (d.type == kDagMhFullInner) {
      d.last = d.first;
      ++base;
    }
    const uint32_t* node = dag.nodes.data() + d.ptr;
    const uint32_t c = mhChild(x, y, dag.log2Side - d.level - 1);
    const uint32_t type = (node[0] >> (2 * c)) & 3;
    ++d.level;
    d.type = type;
    if (type == kDagMhAbsent) {
      d.ptr = d.first = 0;
      return;
    }
    uint32_t k = 0;
    for (uint32_t o = 0; o < c; ++o) k += ((node[0] >> (2 * o)) & 3) != kDagMhAbsent;
    d.ptr = node[pointerWord(k)];
    d.first = base + (k == 0 ? 0 : node[prefixWord(k)]);
  }
}

// The value index of texel (x, y) once the descent has stopped.
uint32_t finish(const DagMh& dag, const Descent& d, uint64_t x, uint64_t y) {
  if (d.type == kDagMhAbsent) return d.last;
  if (d.type != kDagMhTreelet) return d.type == kDagMhFullInner ? d.first : d.last;
  const uint32_t* t = dag.treelets.data() + size_t(d.ptr) * kTreeletWords;
  const int below = dag.log2Side - d.level;
  uint32_t l[3] = {0, 0, 0};
  for (int n = 0; n < below; ++n) l[n] = mhChild(x, y, below - n - 1);
  for (int n = below; n >= 0; --n) {
    const uint32_t i = treeletBit(n, l[0], l[1], l[2]);
    if (treeletHas(t, i)) return d.first + treeletRank(t, i);
  }
  return d.last;
}

struct WordsHash {
  size_t operator()(const std::vector<uint32_t>& w) const {
    uint64_t h = 0x9E3779B97F4A7C15ull;
    for (uint32_t v : w) h = (h ^ v) * 0x100000001B3ull + (h >> 29);
    return size_t(h);
  }
};
struct TreeletHash {
  size_t operator()(const std::array<uint32_t, 3>& t) const {
    return size_t((uint64_t(t[0]) * 0x9E3779B97F4A7C15ull) ^ (uint64_t(t[1]) * 0xC2B2AE3D27D4EB4Full) ^
                  (uint64_t(t[2]) * 0x165667B19E3779F9ull));
  }
};

// A node as its parent sees it.
struct ChildRef {
  uint32_t type = kDagMhAbsent;
  uint32_t id = 0;      // a pool index (before the final layout)
  uint32_t values = 0;  // in its subtree, its own included
};

// The unique shapes of one level of inner nodes, their pointers still pool indices.
struct LevelPool {
  std::vector<std::vector<uint32_t>> nodes;
  std::unordered_map<std::vector<uint32_t>, uint32_t, WordsHash> index;
  uint32_t add(std::vector<uint32_t>&& words) {
    const auto [it, added] = index.try_emplace(words, uint32_t(nodes.size()));
    if (added) nodes.push_back(std::move(words));
    return it->second;
  }
};

uint32_t checkedValues(uint64_t v) {
  if (v > UINT32_MAX) throw InputError("a DAG-MH holds at most 2^32 - 1 values");
  return uint32_t(v);
}

// The inner nodes of level l of a hierarchy from the refs of the level below (children
// of node (x, y) at (2x + (c & 1), 2y + (c >> 1))): each present node's words merged into
// `pool`, naming its children by pool index, and its ref as its parent sees it.
std::vector<ChildRef> innerLevel(const Mh& mh, int l, const std::vector<ChildRef>& below, LevelPool& pool) {
  const uint32_t n = mh.side(l);
  std::vector<ChildRef> up(size_t(n) * n);
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      const MhState s = mh.state(l, x, y);
      if (s == MhState::Absent) continue;
      std::vector<uint32_t> words{0, 0};
      uint64_t values = 0;
      for (uint32_t c = 0; c < 4; ++c) {
        const ChildRef& ch = below[size_t(2 * y + (c >> 1)) * (2 * n) + 2 * x + (c & 1)];
        if (ch.type == kDagMhAbsent) continue;
        words[0] |= ch.type << (2 * c);
        words.push_back(ch.id);
        if (words.size() > 3) words.push_back(uint32_t(values));
        values += ch.values;
      }
      words[1] = checkedValues(values);
      up[size_t(y) * n + x] = {s == MhState::Full ? kDagMhFullInner : kDagMhEmptyInner, pool.add(std::move(words)),
                               checkedValues(values + (s == MhState::Full))};
    }
  return up;
}

}  // namespace

uint32_t DagMh::valueIndex(uint64_t x, uint64_t y) const {
  Descent d = rootDescent(*this);
  if (skipLevel > 0) {
    const int shift = log2Side - skipLevel;
    const DagMhSkip& e = skip[size_t(y >> shift) << skipLevel | size_t(x >> shift)];
    d.type = e.typePtr & 3;
    d.ptr = e.typePtr >> 2;
    d.first = e.first;
    d.last = e.last;
    d.level = skipLevel;
  }
  descend(*this, d, x, y, log2Side);
  return finish(*this, d, x, y);
}

namespace {

// Fills the value indices of the rectangle's texels under the node a descent stands at
// (its square: side 2^(L - level) from (nx, ny)), recursing into the children that overlap.
struct RectFill {
  const DagMh& dag;
  uint64_t x0, y0, x1, y1;  // the rectangle, exclusive ends
  uint32_t* out;
  uint32_t width;

  void visit(const Descent& d, uint64_t nx, uint64_t ny) const {
    const uint64_t size = uint64_t(1) << (dag.log2Side - d.level);
    const uint64_t ax = std::max(nx, x0), ay = std::max(ny, y0), bx = std::min(nx + size, x1), by = std::min(ny + size, y1);
    if (d.type == kDagMhAbsent) {
      for (uint64_t y = ay; y < by; ++y)
        for (uint64_t x = ax; x < bx; ++x) out[(y - y0) * width + (x - x0)] = d.last;
      return;
    }
    if (d.type == kDagMhTreelet) {
      // The treelet's bits in registers, each texel's path read from them.
      const uint32_t* t = dag.treelets.data() + size_t(d.ptr) * kTreeletWords;
      const uint64_t low = uint64_t(t[1]) << 32 | t[0];
      const uint32_t high = t[2];
      const int below = dag.log2Side - d.level;
      if (below == kTreeletLevels - 1 && (bx - ax) * (by - ay) >= 12) {
        // Many of its 8 x 8 texels: every texel's index in one preorder walk of the 85
        // nodes (a node's rank is how many set bits come before it), then read.
        uint32_t index[64];
        uint32_t rank = 0;
        auto take = [&](uint32_t i, uint32_t inherited) {
          return (i < 64 ? (low >> i & 1) : (high >> (i - 64) & 1)) ? d.first + rank++ : inherited;
        };
        const uint32_t v0 = take(0, d.last);
        for (uint32_t l0 = 0; l0 < 4; ++l0) {
          const uint32_t v1 = take(treeletBit(1, l0, 0, 0), v0);
          for (uint32_t l1 = 0; l1 < 4; ++l1) {
            const uint32_t v2 = take(treeletBit(2, l0, l1, 0), v1);
            for (uint32_t l2 = 0; l2 < 4; ++l2) {
              const uint32_t tx = (l0 & 1) << 2 | (l1 & 1) << 1 | (l2 & 1), ty = (l0 >> 1) << 2 | (l1 >> 1) << 1 | (l2 >> 1);
              index[ty * 8 + tx] = take(treeletBit(3, l0, l1, l2), v2);
            }
          }
        }
        for (uint64_t y = ay; y < by; ++y)
          for (uint64_t x = ax; x < bx; ++x) out[(y - y0) * width + (x - x0)] = index[(y & 7) * 8 + (x & 7)];
        return;
      }
      for (uint64_t y = ay; y < by; ++y)
        for (uint64_t x = ax; x < bx; ++x) {
          uint32_t l[3] = {0, 0, 0};
          for (int n = 0; n < below; ++n) l[n] = mhChild(x, y, below - n - 1);
          uint32_t index = d.last;
          for (int n = below; n >= 0; --n) {
            const uint32_t i = treeletBit(n, l[0], l[1], l[2]);
            if (i < 64 ? (low >> i & 1) : (high >> (i - 64) & 1)) {
              const uint64_t before = i < 64 ? low & ((uint64_t(1) << i) - 1) : low;
              index = d.first + bitCount(uint32_t(before)) + bitCount(uint32_t(before >> 32)) +
                      (i > 64 ? bitCount(high & ((1u << (i - 64)) - 1)) : 0);
              break;
            }
          }
          out[(y - y0) * width + (x - x0)] = index;
        }
      return;
    }
    const uint64_t half = size / 2;
    for (uint32_t c = 0; c < 4; ++c) {
      const uint64_t cx = nx + (c & 1) * half, cy = ny + (c >> 1) * half;
      if (cx >= bx || cy >= by || cx + half <= ax || cy + half <= ay) continue;
      Descent child = d;
      descend(dag, child, cx, cy, d.level + 1);
      visit(child, cx, cy);
    }
  }
};

}  // namespace

void DagMh::depths(uint64_t x0, uint64_t y0, uint32_t width, uint32_t height, float* out) const {
  const uint64_t side = uint64_t(1) << log2Side;
  CPVS_CHECK(x0 + width <= side && y0 + height <= side && uint64_t(width) * height <= 1024);
  uint32_t indices[1024];
  // Down to the smallest node holding the whole rectangle (through the skip list when it
  // lies within one of its nodes), then one visit of what lies below.
  int level = 0;
  while (level < log2Side) {
    const int shift = log2Side - level - 1;
    if ((x0 >> shift) != ((x0 + width - 1) >> shift) || (y0 >> shift) != ((y0 + height - 1) >> shift)) break;
    ++level;
  }
  Descent d = rootDescent(*this);
  if (skipLevel > 0 && level >= skipLevel) {
    const int shift = log2Side - skipLevel;
    const DagMhSkip& e = skip[size_t(y0 >> shift) << skipLevel | size_t(x0 >> shift)];
    d = {e.typePtr & 3, e.typePtr >> 2, e.first, e.last, skipLevel};
  }
  descend(*this, d, x0, y0, level);
  const int shift = log2Side - d.level;
  RectFill{*this, x0, y0, x0 + width, y0 + height, indices, width}.visit(d, (x0 >> shift) << shift, (y0 >> shift) << shift);
  uint32_t lastIndex = UINT32_MAX;
  float lastDepth = 0;
  for (uint32_t i = 0; i < width * height; ++i) {
    if (indices[i] != lastIndex) {
      lastIndex = indices[i];
      lastDepth = values.value(lastIndex);
    }
    out[i] = lastDepth;
  }
}

uint64_t DagMh::innerNodeCount() const {
  uint64_t n = 0;
  for (size_t at = 0; at < nodes.size(); at += innerWords(nodes[at])) ++n;
  return n;
}

void mhValueIntervals(const Mh& mh, std::vector<float>& lo, std::vector<float>& hi) {
  lo.clear();
  hi.clear();
  struct Item {
    int level;
    uint32_t x, y;
  };
  std::vector<Item> stack{{0, 0, 0}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const MhState s = mh.state(it.level, it.x, it.y);
    if (s == MhState::Absent) continue;
    if (s == MhState::Full) {
      lo.push_back(mh.lo(it.level, it.x, it.y));
      hi.push_back(mh.hi(it.level, it.x, it.y));
    }
    if (it.level == mh.log2Side() || !mh.hasFull(it.level, it.x, it.y)) continue;
    for (int c = 3; c >= 0; --c)
      stack.push_back({it.level + 1, 2 * it.x + uint32_t(c & 1), 2 * it.y + uint32_t(c >> 1)});
  }
}

// Unique shapes: inner nodes per level, treelets.
struct DagMhShapes {
  std::vector<LevelPool> levels;
  std::unordered_map<std::array<uint32_t, 3>, uint32_t, TreeletHash> treeletIndex;
  std::vector<std::array<uint32_t, 3>> treeletPool;

  uint32_t addTreelet(const std::array<uint32_t, 3>& bits) {
    const auto [it, added] = treeletIndex.try_emplace(bits, uint32_t(treeletPool.size()));
    if (added) treeletPool.push_back(bits);
    return it->second;
  }
};

namespace {

// The level of the tiles' roots in a map of 2^log2Side in tiles of 2^log2TileSide; tiles
// of more than one treelet level, so that a tile root is an inner node.
int checkedTileLevel(int log2Side, int log2TileSide) {
  const int tileLevel = log2Side - log2TileSide;
  if (tileLevel > 0 && tileLevel >= treeletLevel(log2Side))
    throw InputError("DAG-MH tiles of 2^" + std::to_string(log2TileSide) + " texels are too small: at least 16 a side");
  return tileLevel;
}

}  // namespace

int DagMhTile::innerLevels() const { return treeletLevel(log2Side) - (log2Side - log2TileSide); }

DagMhTile dagMhTile(int log2Side, uint64_t tileX, uint64_t tileY, const Mh& mh) {
  CPVS_CHECK(log2Side >= 0 && log2Side <= 20 && mh.log2Side() <= log2Side);
  DagMhTile part;
  part.log2Side = log2Side;
  part.log2TileSide = mh.log2Side();
  part.tileX = tileX;
  part.tileY = tileY;
  const int tileLevel = checkedTileLevel(log2Side, part.log2TileSide);
  CPVS_CHECK((tileX >> tileLevel) == 0 && (tileY >> tileLevel) == 0);
  // Local level l of the tile is level tileLevel + l of the map.
  const int t = part.innerLevels(), below = log2Side - treeletLevel(log2Side);

  // Treelets: every node at level t that is not absent, its bits in preorder.
  const uint32_t tside = mh.side(t);
  std::vector<std::array<uint32_t, 3>> bits(size_t(tside) * tside);
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, tside, std::max(1u, 256u / tside)), [&](const auto& rows) {
    for (uint32_t y = rows.begin(); y != rows.end(); ++y)
      for (uint32_t x = 0; x < tside; ++x) {
        std::array<uint32_t, 3>& b = bits[size_t(y) * tside + x];
        b = {0, 0, 0};
        if (mh.state(t, x, y) == MhState::Absent) continue;
        // Depth n holds 4^n nodes; node j of depth n has path digits j's base-4 digits.
        for (int n = 0; n <= below; ++n)
          for (uint32_t j = 0; j < (1u << (2 * n)); ++j) {
            uint32_t l[3] = {0, 0, 0}, nx = x, ny = y;
            for (int d = 0; d < n; ++d) {
              l[d] = (j >> (2 * (n - 1 - d))) & 3;
              nx = 2 * nx + (l[d] & 1);
              ny = 2 * ny + (l[d] >> 1);
            }
            if (mh.state(t + n, nx, ny) == MhState::Full) {
              const uint32_t i = treeletBit(n, l[0], l[1], l[2]);
              b[i / 32] |= 1u << (i % 32);
            }
          }
      }
  });
  DagMhShapes pools;
  std::vector<ChildRef> refs(bits.size());
  for (uint32_t y = 0; y < tside; ++y)
    for (uint32_t x = 0; x < tside; ++x) {
      const size_t i = size_t(y) * tside + x;
      if (mh.state(t, x, y) == MhState::Absent) continue;
      refs[i] = {kDagMhTreelet, pools.addTreelet(bits[i]), treeletValues(bits[i].data())};
    }
  for (const auto& b : pools.treeletPool) part.treelets.insert(part.treelets.end(), b.begin(), b.end());

  // Inner levels bottom-up; local level 0 is Full in the tile's own hierarchy, so its ref
  // counts its own value (the map decides the root's state).
  pools.levels.resize(size_t(t));
  for (int l = t - 1; l >= 0; --l) refs = innerLevel(mh, l, refs, pools.levels[size_t(l)]);
  part.levels.resize(size_t(t));
  for (int l = 0; l < t; ++l)
    for (const std::vector<uint32_t>& w : pools.levels[size_t(l)].nodes)
      part.levels[size_t(l)].insert(part.levels[size_t(l)].end(), w.begin(), w.end());
  part.root = refs[0].id;
  part.valuesBelow = refs[0].values - 1;
  part.lo = mh.lo(0, 0, 0);
  part.hi = mh.hi(0, 0, 0);
  part.hasFull = mh.hasFull(0, 0, 0);
  mhValueIntervals(mh, part.valueLo, part.valueHi);
  part.valueLo.erase(part.valueLo.begin());  // the root's own, always first
  part.valueHi.erase(part.valueHi.begin());
  return part;
}

void validateDagMhTile(const DagMhTile& part, const std::string& source) {
  auto fail = [&](const std::string& what) {
    throw FormatError(source + ": invalid DAG-MH tile " + std::to_string(part.tileX) + "," + std::to_string(part.tileY) +
                      ": " + what);
  };
  if (part.log2Side < 0 || part.log2Side > 20 || part.log2TileSide < 0 || part.log2TileSide > part.log2Side)
    fail("a tile of 2^" + std::to_string(part.log2TileSide) + " in a map of 2^" + std::to_string(part.log2Side));
  int tileLevel = 0;
  try {
    tileLevel = checkedTileLevel(part.log2Side, part.log2TileSide);
  } catch (const InputError& e) {
    fail(e.what());
  }
  if ((part.tileX >> tileLevel) != 0 || (part.tileY >> tileLevel) != 0) fail("the tile lies outside the map");
  const int t = part.innerLevels();
  if (part.levels.size() != size_t(t))
    fail(std::to_string(part.levels.size()) + " inner levels where " + std::to_string(t) + " are");
  if (part.treelets.size() % kTreeletWords != 0) fail("a partial treelet");
  // Values in (and below) each shape, bottom-up: a treelet's its bits; an inner node's
  // its w1, checked against its children's.
  std::vector<uint64_t> below;
  for (size_t i = 0; i < part.treelets.size(); i += kTreeletWords) {
    if (part.treelets[i + 2] >> (85 - 64)) fail("treelet " + std::to_string(i / kTreeletWords) + " has padding bits set");
    // A treelet stands for a node that is not absent: something in it stores a value.
    if (treeletValues(&part.treelets[i]) == 0) fail("treelet " + std::to_string(i / kTreeletWords) + " stores nothing");
    below.push_back(treeletValues(&part.treelets[i]));
  }
  for (int l = t - 1; l >= 0; --l) {
    const std::vector<uint32_t>& words = part.levels[size_t(l)];
    std::vector<uint64_t> here;
    for (size_t at = 0; at < words.size();) {
      const auto node = [&] { return "level " + std::to_string(l) + " word " + std::to_string(at); };
      const uint32_t types = words[at];
      if (types >> 8) fail(node() + ": child types 0x" + std::to_string(types));
      const uint32_t n = innerWords(types);
      if (at + n > words.size()) fail(node() + ": runs past the level's words");
      uint64_t values = 0;
      for (uint32_t k = 0, c = 0; c < 4; ++c) {
        const uint32_t type = (types >> (2 * c)) & 3;
        if (type == kDagMhAbsent) continue;
        if ((type == kDagMhTreelet) != (l == t - 1)) fail(node() + ": child " + std::to_string(c) + " of the wrong kind");
        if (k > 0 && words[at + prefixWord(k)] != values) fail(node() + ": a wrong prefix count");
        const uint32_t p = words[at + pointerWord(k++)];
        if (p >= below.size()) fail(node() + ": child " + std::to_string(c) + " names a shape that is not there");
        values += below[p] + (type == kDagMhFullInner);
      }
      if (words[at + 1] != values) fail(node() + ": a wrong value count");
      here.push_back(values);
      at += n;
    }
    below = std::move(here);
  }
  if (part.root >= below.size()) fail("the root names a shape that is not there");
  const uint64_t rootBelow = below[part.root] - (t == 0 ? 1 : 0);  // a treelet counts its own root
  if (t == 0 && !(part.treelets[kTreeletWords * part.root] & 1)) fail("the root treelet stores no value of its own");
  if (part.valuesBelow != rootBelow || part.valueLo.size() != rootBelow || part.valueHi.size() != rootBelow)
    fail(std::to_string(part.valueLo.size()) + " value intervals where the shapes hold " + std::to_string(rootBelow));
  if (part.hasFull != (rootBelow > 0)) fail("the root says it has values below it and has none, or the reverse");
  auto interval = [&](float lo, float hi) { return std::isfinite(lo) && std::isfinite(hi) && lo <= hi; };
  if (!interval(part.lo, part.hi)) fail("the root's interval is not one");
  for (size_t k = 0; k < part.valueLo.size(); ++k)
    if (!interval(part.valueLo[k], part.valueHi[k])) fail("value " + std::to_string(k) + "'s interval is not one");
}

DagMhBuilder::DagMhBuilder(int log2Side, int log2TileSide)
    : log2Side_(log2Side), log2TileSide_(std::min(log2Side, log2TileSide)),
      tileLevel_(checkedTileLevel(log2Side, std::min(log2Side, log2TileSide))), treeletLevel_(treeletLevel(log2Side)),
      pools_(std::make_unique<DagMhShapes>()) {
  CPVS_CHECK(log2Side >= 0 && log2Side <= 20 && log2TileSide >= 0);
  pools_->levels.resize(size_t(treeletLevel_));
  tiles_.resize(size_t(1) << (2 * tileLevel_));
}

DagMhBuilder::~DagMhBuilder() = default;

bool DagMhBuilder::hasTile(uint64_t tileX, uint64_t tileY) const {
  const uint64_t tilesPerSide = uint64_t(1) << tileLevel_;
  return tileX < tilesPerSide && tileY < tilesPerSide && tiles_[size_t(tileY * tilesPerSide + tileX)].added;
}

void DagMhBuilder::addTile(DagMhTile&& part) {
  const uint64_t tilesPerSide = uint64_t(1) << tileLevel_;
  const std::string name = "DAG-MH tile " + std::to_string(part.tileX) + "," + std::to_string(part.tileY);
  if (part.log2Side != log2Side_ || part.log2TileSide != log2TileSide_ || part.tileX >= tilesPerSide ||
      part.tileY >= tilesPerSide || part.levels.size() != size_t(treeletLevel_ - tileLevel_))
    throw InputError(name + " of 2^" + std::to_string(part.log2TileSide) + " texels in a map of 2^" +
                     std::to_string(part.log2Side) + ", not of this one");
  Tile& tile = tiles_[size_t(part.tileY * tilesPerSide + part.tileX)];
  if (tile.added) throw InputError(name + " added twice");
  // The part's shapes into the map's, bottom-up, its pointers made the map's.
  std::vector<uint32_t> below(part.treelets.size() / kTreeletWords);
  for (size_t i = 0; i < below.size(); ++i)
    below[i] = pools_->addTreelet({part.treelets[3 * i], part.treelets[3 * i + 1], part.treelets[3 * i + 2]});
  for (int l = int(part.levels.size()) - 1; l >= 0; --l) {
    const std::vector<uint32_t>& words = part.levels[size_t(l)];
    LevelPool& pool = pools_->levels[size_t(tileLevel_ + l)];
    std::vector<uint32_t> ids;
    for (size_t at = 0; at < words.size();) {
      const uint32_t n = innerWords(words[at]);
      CPVS_CHECK(at + n <= words.size());
      std::vector<uint32_t> w(words.begin() + ptrdiff_t(at), words.begin() + ptrdiff_t(at + n));
      for (uint32_t k = 0, c = 0; c < 4; ++c)
        if (((w[0] >> (2 * c)) & 3) != kDagMhAbsent) {
          uint32_t& p = w[pointerWord(k++)];
          CPVS_CHECK(p < below.size());
          p = below[p];
        }
      ids.push_back(pool.add(std::move(w)));
      at += n;
    }
    below = std::move(ids);
  }
  CPVS_CHECK(part.root < below.size());
  held_ += 8 * part.valueLo.size() + 4 * part.treelets.size() + sizeof(Tile);
  for (const std::vector<uint32_t>& level : part.levels) held_ += 4 * level.size();
  tile.node = below[part.root];
  tile.valuesBelow = part.valuesBelow;
  tile.lo = part.lo;
  tile.hi = part.hi;
  tile.hasFull = part.hasFull;
  tile.valueLo = std::move(part.valueLo);
  tile.valueHi = std::move(part.valueHi);
  tile.added = true;
}

DagMh DagMhBuilder::finish() {
  for (size_t i = 0; i < tiles_.size(); ++i)
    if (!tiles_[i].added) throw InputError("DAG-MH tile " + std::to_string(i) + " was never added");
  const int L = log2Side_, t = treeletLevel_, T = tileLevel_;
  DagMh dag;
  dag.log2Side = L;

  // The hierarchy above the tiles, from their roots.
  const uint32_t tilesPerSide = 1u << T;
  TexelIntervals roots;
  roots.side = tilesPerSide;
  std::vector<uint8_t> rootsHaveFull;
  for (const Tile& tile : tiles_) {
    roots.lo.push_back(tile.lo);
    roots.hi.push_back(tile.hi);
    rootsHaveFull.push_back(tile.hasFull);
  }
  const Mh top(std::move(roots), std::move(rootsHaveFull));
  std::vector<ChildRef> refs(tiles_.size());
  for (uint32_t y = 0; y < tilesPerSide; ++y)
    for (uint32_t x = 0; x < tilesPerSide; ++x) {
      const Tile& tile = tiles_[size_t(y) * tilesPerSide + x];
      const MhState s = top.state(T, x, y);
      if (s == MhState::Absent) continue;
      const bool full = s == MhState::Full;
      refs[size_t(y) * tilesPerSide + x] = {T == t ? kDagMhTreelet : full ? kDagMhFullInner : kDagMhEmptyInner, tile.node,
                                            checkedValues(tile.valuesBelow + full)};
    }
  for (int l = T - 1; l >= 0; --l) refs = innerLevel(top, l, refs, pools_->levels[size_t(l)]);
  const uint32_t rootId = refs[0].id;

  // The final layout: level by level from the root, each in the order of first mention.
  if (t == 0) {
    dag.rootType = kDagMhTreelet;
    dag.treelets.assign(pools_->treeletPool[rootId].begin(), pools_->treeletPool[rootId].end());
  } else {
    dag.rootType = kDagMhFullInner;
    std::vector<uint32_t> order{rootId};  // pool indices of the current level, in layout order
    std::vector<std::vector<uint32_t>> offsets{size_t(t)};  // per level: pool index -> word offset
    std::vector<uint32_t> treeletOrder(pools_->treeletPool.size(), UINT32_MAX);
    uint32_t treelets = 0;
    uint64_t at = 0;
    for (int l = 0; l < t; ++l) {
      LevelPool& pool = pools_->levels[size_t(l)];
      offsets[size_t(l)].assign(pool.nodes.size(), UINT32_MAX);
      for (uint32_t id : order) {
        offsets[size_t(l)][id] = uint32_t(at);
        at += pool.nodes[id].size();
      }
      if (at >= (uint64_t(1) << 30)) throw InputError("a DAG-MH's inner nodes exceed 2^30 words");
      std::vector<uint32_t> next;
      std::vector<uint8_t> seen(l + 1 < t ? pools_->levels[size_t(l) + 1].nodes.size() : 0, 0);
      for (uint32_t id : order) {
        const std::vector<uint32_t>& w = pool.nodes[id];
        for (uint32_t k = 0, c = 0; c < 4; ++c) {
          const uint32_t type = (w[0] >> (2 * c)) & 3;
          if (type == kDagMhAbsent) continue;
          const uint32_t child = w[pointerWord(k++)];
          if (type == kDagMhTreelet) {
            if (treeletOrder[child] == UINT32_MAX) treeletOrder[child] = treelets++;
          } else if (!seen[child]) {
            seen[child] = 1;
            next.push_back(child);
          }
        }
      }
      order = std::move(next);
    }
    // Write the words with the pointers made final (shapes only tiles that lie under an
    // absent node named are left out).
    dag.nodes.reserve(size_t(at));
    for (int l = 0; l < t; ++l) {
      std::vector<std::pair<uint32_t, uint32_t>> byOffset;
      for (uint32_t id = 0; id < offsets[size_t(l)].size(); ++id)
        if (offsets[size_t(l)][id] != UINT32_MAX) byOffset.push_back({offsets[size_t(l)][id], id});
      std::sort(byOffset.begin(), byOffset.end());
      for (const auto& [offset, id] : byOffset) {
        CPVS_CHECK(offset == dag.nodes.size());
        std::vector<uint32_t> w = pools_->levels[size_t(l)].nodes[id];
        for (uint32_t k = 0, c = 0; c < 4; ++c) {
          const uint32_t type = (w[0] >> (2 * c)) & 3;
          if (type == kDagMhAbsent) continue;
          uint32_t& p = w[pointerWord(k++)];
          p = type == kDagMhTreelet ? treeletOrder[p] : offsets[size_t(l) + 1][p];
        }
        dag.nodes.insert(dag.nodes.end(), w.begin(), w.end());
      }
    }
    dag.treelets.resize(size_t(treelets) * kTreeletWords);
    for (size_t id = 0; id < pools_->treeletPool.size(); ++id)
      if (treeletOrder[id] != UINT32_MAX)
        std::copy(pools_->treeletPool[id].begin(), pools_->treeletPool[id].end(), dag.treelets.begin() + size_t(treeletOrder[id]) * kTreeletWords);
  }

  // The values in preorder: the hierarchy above the tiles, each tile's in its place.
  std::vector<float> lo, hi;
  struct Item {
    int level;
    uint32_t x, y;
  };
  std::vector<Item> stack{{0, 0, 0}};
  while (!stack.empty()) {
    const Item it = stack.back();
    stack.pop_back();
    const MhState s = top.state(it.level, it.x, it.y);
    if (s == MhState::Absent) continue;
    if (s == MhState::Full) {
      lo.push_back(top.lo(it.level, it.x, it.y));
      hi.push_back(top.hi(it.level, it.x, it.y));
    }
    if (it.level == T) {
      const Tile& tile = tiles_[size_t(it.y) * tilesPerSide + it.x];
      lo.insert(lo.end(), tile.valueLo.begin(), tile.valueLo.end());
      hi.insert(hi.end(), tile.valueHi.begin(), tile.valueHi.end());
      continue;
    }
    if (!top.hasFull(it.level, it.x, it.y)) continue;
    for (int c = 3; c >= 0; --c)
      stack.push_back({it.level + 1, 2 * it.x + uint32_t(c & 1), 2 * it.y + uint32_t(c >> 1)});
  }
  dag.values = encodeValueChunks(lo.data(), hi.data(), lo.size());

  dag.skipLevel = skipLevelFor(L);
  if (dag.skipLevel > 0) {
    const uint32_t n = 1u << dag.skipLevel;
    const int shift = L - dag.skipLevel;
    dag.skip.resize(size_t(n) * n);
    for (uint32_t y = 0; y < n; ++y)
      for (uint32_t x = 0; x < n; ++x) {
        Descent d = rootDescent(dag);
        descend(dag, d, uint64_t(x) << shift, uint64_t(y) << shift, dag.skipLevel);
        dag.skip[size_t(y) * n + x] = {d.ptr << 2 | d.type, d.first, d.last};
      }
  }
  return dag;
}

DagMh encodeDagMh(const Mh& mh) {
  DagMhBuilder builder(mh.log2Side(), mh.log2Side());
  builder.addTile(0, 0, mh);
  return builder.finish();
}

namespace {

[[noreturn]] void invalid(const std::string& source, const std::string& what) {
  throw FormatError(source + ": invalid DAG-MH: " + what);
}

}  // namespace

void validateDagMh(const DagMh& dag, const std::string& source) {
  const int L = dag.log2Side;
  if (L < 0 || L > 20) invalid(source, "resolution 2^" + std::to_string(L));
  const int t = treeletLevel(L);
  const size_t treeletCount = dag.treelets.size() / kTreeletWords;
  if (dag.treelets.size() % kTreeletWords) invalid(source, "a treelet pool of " + std::to_string(dag.treelets.size()) + " words");
  // Treelets: the padding bits and, near a small map's texels, the depths it lacks.
  const int below = L - t;
  for (size_t i = 0; i < treeletCount; ++i) {
    const uint32_t* tw = dag.treelets.data() + i * kTreeletWords;
    if (tw[2] >> (85 - 64)) invalid(source, "treelet " + std::to_string(i) + " sets bits beyond 85");
    if (treeletValues(tw) == 0) invalid(source, "treelet " + std::to_string(i) + " stores nothing");
    for (uint32_t b = 0; b < 85 && below < 3; ++b) {
      const int depth = b == 0 ? 0 : (b - 1) % 21 == 0 ? 1 : ((b - 1) % 21 - 1) % 5 == 0 ? 2 : 3;
      if (depth > below && treeletHas(tw, b)) invalid(source, "treelet " + std::to_string(i) + " sets a level below the texels");
    }
  }
  uint64_t total = 0;
  if (dag.rootType == kDagMhTreelet) {
    if (t != 0 || treeletCount != 1 || !dag.nodes.empty()) invalid(source, "a treelet root above four levels");
    if (!treeletHas(dag.treelets.data(), 0)) invalid(source, "the root stores no value");
    total = treeletValues(dag.treelets.data());
  } else {
    if (dag.rootType != kDagMhFullInner || t == 0 || dag.nodes.empty()) invalid(source, "root type " + std::to_string(dag.rootType));
    // Node starts, levels (pointers lead forward, so one pass in order sees every parent
    // before its child), then the counts from the bottom up.
    // A skip entry holds 30 bits of a node's offset, as the builder refuses more.
    if (dag.nodes.size() >= (size_t(1) << 30)) invalid(source, std::to_string(dag.nodes.size()) + " inner node words");
    // The level of each word a pointer names (-1: none names it; levels fit a byte), so
    // that a pointer into the middle of a node and a node at two levels are caught.
    std::vector<int8_t> level(dag.nodes.size(), -1);
    std::vector<uint8_t> treeletUsed(treeletCount, 0);
    std::vector<size_t> starts;
    level[0] = 0;
    for (size_t at = 0; at < dag.nodes.size();) {
      const uint32_t types = dag.nodes[at];
      if (types >> 8) invalid(source, "node word " + std::to_string(at) + " sets reserved bits");
      const uint32_t size = innerWords(types);
      if (at + size > dag.nodes.size()) invalid(source, "node word " + std::to_string(at) + " runs past the pool");
      if (level[at] < 0) invalid(source, "node word " + std::to_string(at) + " is not reached from the root");
      starts.push_back(at);
      for (uint32_t k = 0, c = 0; c < 4; ++c) {
        const uint32_t type = (types >> (2 * c)) & 3;
        if (type == kDagMhAbsent) continue;
        const uint32_t p = dag.nodes[at + pointerWord(k++)];
        const int childLevel = level[at] + 1;
        if (type == kDagMhTreelet) {
          if (childLevel != t || p >= treeletCount) invalid(source, "node word " + std::to_string(at) + " names a treelet out of place");
          treeletUsed[p] = 1;
        } else {
          if (childLevel >= t || p <= at || p >= dag.nodes.size() || (level[p] >= 0 && level[p] != childLevel))
            invalid(source, "node word " + std::to_string(at) + " names node " + std::to_string(p) + " out of place");
          level[p] = int8_t(childLevel);
        }
      }
      for (uint32_t w = 1; w < size; ++w)
        if (level[at + w] >= 0) invalid(source, "a pointer into node word " + std::to_string(at));
      at += size;
    }
    for (size_t i = 0; i < treeletCount; ++i)
      if (!treeletUsed[i]) invalid(source, "treelet " + std::to_string(i) + " is not reached from the root");
    // Values below each node, from the last node back (children lie after their parents);
    // a child is found among the starts by its offset.
    std::vector<uint64_t> below(starts.size(), 0);
    auto nodeIndex = [&](uint32_t p) { return size_t(std::lower_bound(starts.begin(), starts.end(), p) - starts.begin()); };
    for (size_t n = starts.size(); n-- > 0;) {
      const size_t at = starts[n];
      const uint32_t types = dag.nodes[at];
      uint64_t values = 0;
      for (uint32_t k = 0, c = 0; c < 4; ++c) {
        const uint32_t type = (types >> (2 * c)) & 3;
        if (type == kDagMhAbsent) continue;
        if (k > 0 && dag.nodes[at + prefixWord(k)] != values) invalid(source, "node word " + std::to_string(at) + ": a wrong prefix count");
        const uint32_t p = dag.nodes[at + pointerWord(k++)];
        values += type == kDagMhTreelet ? treeletValues(dag.treelets.data() + size_t(p) * kTreeletWords)
                                        : below[nodeIndex(p)] + (type == kDagMhFullInner);
      }
      if (values != dag.nodes[at + 1]) invalid(source, "node word " + std::to_string(at) + ": a wrong value count");
      below[n] = values;
    }
    total = below[0] + 1;
  }
  // Values: as many as the tree stores, chunk widths and factor bytes in the stream.
  const ValueChunks& v = dag.values;
  if (v.count != total) invalid(source, std::to_string(v.count) + " values for a tree of " + std::to_string(total));
  if (v.chunks.size() != (v.count + kValuesPerChunk - 1) / kValuesPerChunk) invalid(source, "the chunk count");
  if (v.factors.size() < kFactorStreamPadding) invalid(source, "a factor stream without its padding");
  const uint64_t streamBytes = v.factors.size() - kFactorStreamPadding;
  for (size_t i = 0; i < v.chunks.size(); ++i) {
    const ValueChunk& c = v.chunks[i];
    const uint64_t inChunk = std::min<uint64_t>(kValuesPerChunk, v.count - i * kValuesPerChunk);
    if (inChunk < 32 && c.bitmap >> inChunk) invalid(source, "chunk " + std::to_string(i) + " marks values past the end");
    const uint64_t bits = uint64_t(bitCount(c.bitmap)) * c.factorBits();
    if (c.factorByte() + (bits + 7) / 8 > streamBytes) invalid(source, "chunk " + std::to_string(i) + "'s factors run past the stream");
  }
  // The skip list is what a descent finds.
  if (dag.skipLevel != skipLevelFor(L)) invalid(source, "skip level " + std::to_string(dag.skipLevel));
  const uint32_t n = dag.skipLevel > 0 ? 1u << dag.skipLevel : 0;
  if (dag.skip.size() != size_t(n) * n) invalid(source, "the skip list's size");
  for (uint32_t y = 0; y < n; ++y)
    for (uint32_t x = 0; x < n; ++x) {
      Descent d = rootDescent(dag);
      const int shift = L - dag.skipLevel;
      descend(dag, d, uint64_t(x) << shift, uint64_t(y) << shift, dag.skipLevel);
      const DagMhSkip& e = dag.skip[size_t(y) * n + x];
      if (e.typePtr != (d.ptr << 2 | d.type) || e.first != d.first || e.last != d.last)
        invalid(source, "skip entry " + std::to_string(x) + "," + std::to_string(y));
    }
}

}  // namespace cpvs
