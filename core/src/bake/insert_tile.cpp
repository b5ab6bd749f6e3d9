#include "cpvs/bake/insert_tile.h"

#include <algorithm>
#include <stdexcept>

namespace cpvs {

namespace {

constexpr uint64_t kAllShadowed = ~uint64_t(0);

uint64_t mix(uint64_t z) {
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
  return z ^ (z >> 31);
}

// The nodes of one level of the tile, by content: a block equal to one built before
// takes its index instead of a copy. Exact: the content is compared, and children are
// compared by index, which names one subtree because the level below is shared the same
// way. Open addressing; a slot holds 32 bits of the content's hash (its place in the
// table follows from them, so the table can grow without the content) and the index + 1.
class UniqueTable {
 public:
  // The index of the node whose content `equal` recognises, or the one `add()` appends.
  template <class Equal, class Add>
  uint32_t find(uint64_t hash, const Equal& equal, const Add& add) {
    if ((count_ + 1) * 2 > slots_.size()) grow();
    const uint64_t key = hash >> 32, mask = slots_.size() - 1;
    for (uint64_t at = mix(key) & mask;; at = (at + 1) & mask) {
      const uint64_t slot = slots_[at];
      if (slot == 0) {
        const uint32_t index = add();
        slots_[at] = (key << 32) | (uint64_t(index) + 1);
        ++count_;
        return index;
      }
      if ((slot >> 32) == key && equal(uint32_t(slot) - 1)) return uint32_t(slot) - 1;
    }
  }

 private:
  void grow() {
    std::vector<uint64_t> old = std::move(slots_);
    slots_.assign(old.empty() ? 1024 : old.size() * 2, 0);
    const uint64_t mask = slots_.size() - 1;
    for (const uint64_t slot : old) {
      if (slot == 0) continue;
      uint64_t at = mix(slot >> 32) & mask;
      while (slots_[at] != 0) at = (at + 1) & mask;
      slots_[at] = slot;
    }
  }

  std::vector<uint64_t> slots_;
  size_t count_ = 0;
};

// The last block completed at each (level, x, y), for culling: its depth index, its
// reference, and a lower bound of the first mask transition strictly behind its start
// (over its footprint). The next block in depth is identical when that bound reaches the
// end of the next block.
struct LastBlock {
  int64_t bz = -1;
  NodeRef ref;
  uint32_t nextTransition = 0;
};

struct Result {
  NodeRef ref;
  uint32_t nextTransition;
};

class TileInserter {
 public:
  TileInserter(const ColumnMasks& masks, const MinMaxPyramid& pyramid, int log2Tile, bool cull,
               Dag& out, InsertStats& stats)
      : masks_(masks), pyramid_(pyramid), log2Tile_(log2Tile), cull_(cull), out_(out), stats_(stats),
        R_(masks.resolution) {
    if (cull_) {
      unique_.resize(size_t(log2Tile - 2));
      last_.resize(log2Tile + 1);
      for (int l = 3; l <= log2Tile; ++l) {
        const auto& lv = pyramid_.levels[l - 3];
        last_[l].assign(size_t(lv.width) * lv.height, LastBlock{});
      }
    }
  }

  Result build(int l, uint32_t bx, uint32_t by, uint32_t bz) {
    const auto& lv = pyramid_.levels[l - 3];
    size_t at = size_t(by) * lv.width + bx;
    uint64_t s = uint64_t(1) << l, z0 = uint64_t(bz) << l;
    Result r;
    if (z0 + s <= lv.minFirst[at]) {
      r = {NodeRef{kLit, 0}, lv.minFirst[at]};
    } else if (z0 >= lv.maxFull[at]) {
      r = {NodeRef{kShadowed, 0}, R_};
    } else {
      NodeRef prev;
      uint32_t prevNext = 0;
      if (cull_ && bz > 0 && findLast(l, bx, by, int64_t(bz) - 1, prev, prevNext) &&
          prevNext >= z0 + s) {
        ++stats_.culledNodes;
        r = {prev, prevNext};
      } else {
        r = l == 3 ? buildColumnNode(bx, by, bz) : buildOctreeNode(l, bx, by, bz);
      }
    }
    if (cull_) last_[l][at] = LastBlock{bz, r.ref, r.nextTransition};
    return r;
  }

 private:
  // The block (l, bx, by, bz) was completed, directly or as part of an ancestor that was
  // homogeneous or reused: find its reference and a lower bound of its next transition.
  bool findLast(int l, uint32_t bx, uint32_t by, int64_t bz, NodeRef& ref, uint32_t& next) const {
    const auto& e = last_[l][size_t(by) * pyramid_.levels[l - 3].width + bx];
    if (e.bz == bz) {
      ref = e.ref;
      next = e.nextTransition;
      return true;
    }
    if (l >= log2Tile_ || e.bz > bz) return false;
    NodeRef parent;
    if (!findLast(l + 1, bx / 2, by / 2, bz / 2, parent, next)) return false;
    if (parent.code != kRef) {
      ref = parent;  // a homogeneous parent has homogeneous children
      return true;
    }
    // A parent's bound holds for each child: a smaller footprint starting no nearer.
    int c = octant(bx, by, bz);
    ref = out_.levels[l + 1 - 3].child(parent.index, c);
    return true;
  }

  Result buildOctreeNode(int l, uint32_t bx, uint32_t by, uint32_t bz) {
    uint16_t codes = 0;
    uint32_t refs[8];
    int n = 0;
    uint32_t next = R_;
    for (int c = 0; c < 8; ++c) {
      uint32_t dx = c & 1, dy = (c >> 1) & 1, dz = c >> 2;
      Result cr = build(l - 1, 2 * bx + dx, 2 * by + dy, 2 * bz + dz);
      if (dz == 0) next = std::min(next, cr.nextTransition);
      codes |= uint16_t(cr.ref.code << (2 * c));
      if (cr.ref.code == kRef) refs[n++] = cr.ref.index;
    }
    return {NodeRef{kRef, appendNode(l, codes, refs, n)}, next};
  }

  // With reuse on (cull), a block equal to one built before in this tile shares its node:
  // the tile's DAG comes out with no repeated subtree, so compression has none to find.
  uint32_t appendNode(int l, uint16_t codes, const uint32_t* refs, int n) {
    InternalLevel& lv = out_.levels[size_t(l - 3)];
    const auto add = [&] {
      ++stats_.nodesCreated;
      return lv.append(codes, refs);
    };
    if (!cull_) return add();
    uint64_t h = mix(codes + 1);
    for (int k = 0; k < n; ++k) h = mix(h + refs[k]);
    return unique_[size_t(l - 3)].find(
        h,
        [&](uint32_t i) {
          return lv.codes[i] == codes && std::equal(refs, refs + n, lv.children.begin() + lv.childBegin[i]);
        },
        add);
  }

  uint32_t appendLeaf(uint64_t mask) {
    const auto add = [&] {
      ++stats_.leavesCreated;
      out_.leaves.push_back(mask);
      return uint32_t(out_.leaves.size() - 1);
    };
    if (!cull_) return add();
    return uniqueLeaves_.find(mix(mask), [&](uint32_t i) { return out_.leaves[i] == mask; }, add);
  }

  // A node of size 8: its children are the 8 depth slices of one 8x8 column.
  Result buildColumnNode(uint32_t cx, uint32_t cy, uint32_t bz) {
    size_t c = masks_.column(cx, cy);
    uint32_t z0 = bz * 8;
    auto first = masks_.slice.begin() + masks_.begin[c], last = masks_.slice.begin() + masks_.begin[c + 1];
    auto it = std::upper_bound(first, last, z0);  // first transition behind z0
    uint32_t next = it == last ? R_ : *it;
    uint64_t mask = it == first ? 0 : masks_.mask[size_t(it - masks_.slice.begin()) - 1];

    // The leaf of slice z0 - 1 is reused for slice z0 when no transition lies at z0.
    NodeRef prevLeaf{kLit, 0};
    bool prevSame = false;
    if (cull_ && bz > 0 && (it == first || *(it - 1) != z0)) {
      NodeRef prevNode;
      uint32_t unused;
      if (findLast(3, cx, cy, int64_t(bz) - 1, prevNode, unused) && prevNode.code == kRef) {
        prevLeaf = out_.levels[0].child(prevNode.index, 7);
        prevSame = true;
      }
    }
    uint16_t codes = 0;
    uint32_t refs[8];
    int n = 0;
    for (uint32_t k = z0; k < z0 + 8; ++k) {
      if (it != last && *it == k) {  // a transition: a new mask from this slice on
        mask = masks_.mask[size_t(it - masks_.slice.begin())];
        ++it;
        prevSame = false;
      }
      uint32_t code = mask == 0 ? kLit : (mask == kAllShadowed ? kShadowed : kRef);
      codes |= uint16_t(code << (2 * (k - z0)));
      if (code != kRef) {
        prevSame = false;
        continue;
      }
      if (cull_ && prevSame && prevLeaf.code == kRef) {
        refs[n++] = prevLeaf.index;
        ++stats_.culledLeaves;
      } else {
        const uint32_t index = appendLeaf(mask);
        refs[n++] = index;
        prevLeaf = NodeRef{kRef, index};
      }
      prevSame = true;
    }
    return {NodeRef{kRef, appendNode(3, codes, refs, n)}, next};
  }

  const ColumnMasks& masks_;
  const MinMaxPyramid& pyramid_;
  int log2Tile_;
  bool cull_;
  Dag& out_;
  InsertStats& stats_;
  uint32_t R_;
  std::vector<std::vector<LastBlock>> last_;
  std::vector<UniqueTable> unique_;  // per level, with reuse on
  UniqueTable uniqueLeaves_;
};

}  // namespace

void insertTile(const ColumnMasks& masks, const MinMaxPyramid& pyramid, int log2Resolution,
                int log2TileSize, uint64_t tileX, uint64_t tileY, bool cull, Dag& out,
                InsertStats* stats) {
  int t = std::min(log2TileSize, log2Resolution);
  if (t < 3) throw std::invalid_argument("insertTile: tile smaller than 8 texels");
  uint64_t T = uint64_t(1) << t;
  if (masks.columnsX != T / 8 || masks.columnsY != T / 8 || int(pyramid.levels.size()) != t - 2)
    throw std::invalid_argument("insertTile: masks do not match the tile size");
  out.reset(log2Resolution, t);
  InsertStats local;
  TileInserter inserter(masks, pyramid, t, cull, out, stats ? *stats : local);
  uint64_t stack = (uint64_t(1) << log2Resolution) / T;
  for (uint64_t bz = 0; bz < stack; ++bz) {
    Result r = inserter.build(t, 0, 0, uint32_t(bz));
    out.roots.push_back(Dag::Root{rootKey(tileX, tileY, bz), r.ref});
  }
}

}  // namespace cpvs
