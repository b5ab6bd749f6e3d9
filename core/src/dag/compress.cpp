#include "cpvs/dag/compress.h"

#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <xxhash.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <utility>

#include "cpvs/base/error.h"
#include "cpvs/dag/invariants.h"
#include "cpvs/dag/node_order.h"

namespace cpvs {

namespace {

Hash128 finish(XXH128_hash_t h, HashKind kind) {
  if (kind == HashKind::WeakForTests) return Hash128{h.low64 & 7u, 0};  // 8 values: collisions galore
  return Hash128{h.low64, h.high64};
}

}  // namespace

Hash128 hashLeaf(uint64_t mask, HashKind kind) {
  return finish(XXH3_128bits(&mask, sizeof(uint64_t)), kind);
}

Hash128 hashInternal(uint16_t codes, const Hash128* childHashes, int count, HashKind kind) {
  // codes (2 bytes) then 16 bytes per referenced child's hash
  unsigned char buf[2 + 8 * 16];
  std::memcpy(buf, &codes, 2);
  size_t n = 2;
  for (int k = 0; k < count; ++k, n += 16) {
    std::memcpy(buf + n, &childHashes[k].lo, 8);
    std::memcpy(buf + n + 8, &childHashes[k].hi, 8);
  }
  return finish(XXH3_128bits(buf, n), kind);
}

void computeHashes(Dag& dag, HashKind kind) {
  dag.leafHashes.resize(dag.leaves.size());
  tbb::parallel_for(size_t(0), dag.leaves.size(),
                    [&](size_t i) { dag.leafHashes[i] = hashLeaf(dag.leaves[i], kind); });
  dag.levelHashes.resize(dag.levels.size());
  for (size_t l = 0; l < dag.levels.size(); ++l) {
    const InternalLevel& lv = dag.levels[l];
    const std::vector<Hash128>& below = l == 0 ? dag.leafHashes : dag.levelHashes[l - 1];
    auto& out = dag.levelHashes[l];
    out.resize(lv.size());
    tbb::parallel_for(size_t(0), lv.size(), [&](size_t i) {
      Hash128 childHashes[8];
      int n = 0;
      for (uint32_t k = lv.childBegin[i]; k < lv.childBegin[i + 1]; ++k) childHashes[n++] = below[lv.children[k]];
      out[i] = hashInternal(lv.codes[i], childHashes, n, kind);
    });
  }
}


namespace {

// Emits the given nodes of one level, in the given order, into `out`, rewriting child
// references through `childMap` (old index in the level below -> new index).
void emitLevel(const Dag& in, int level, const std::vector<uint32_t>& order,
               const std::vector<uint32_t>& childMap, Dag& out) {
  if (level < 0) {
    out.leaves.resize(order.size());
    out.leafHashes.resize(order.size());
    for (size_t i = 0; i < order.size(); ++i) {
      out.leaves[i] = in.leaves[order[i]];
      out.leafHashes[i] = in.leafHashes[order[i]];
    }
    return;
  }
  const InternalLevel& src = in.levels[level];
  InternalLevel& dst = out.levels[level];
  dst.clear();
  dst.codes.reserve(order.size());
  dst.childBegin.reserve(order.size() + 1);
  out.levelHashes[level].resize(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    uint32_t o = order[i];
    dst.codes.push_back(src.codes[o]);
    for (uint32_t k = src.childBegin[o]; k < src.childBegin[o + 1]; ++k)
      dst.children.push_back(childMap[src.children[k]]);
    dst.childBegin.push_back(uint32_t(dst.children.size()));
    out.levelHashes[level][i] = in.levelHashes[level][o];
  }
}

// Sorts `order` (old indices of one level, whose children are already emitted in `out`
// at the level below via childMap) by (hash, content after remapping) and drops equal
// content. Returns the unique order and fills map[old] = new index for every old index.
void sortUnique(const Dag& in, int level, std::vector<uint32_t>& order,
                const std::vector<uint32_t>& childMap, std::vector<uint32_t>& map) {
  auto hashOf = [&](uint32_t i) { return level < 0 ? in.leafHashes[i] : in.levelHashes[level][i]; };
  auto contentLess = [&](uint32_t a, uint32_t b) {
    return compareRemapped(in, level, a, b, childMap) < 0;
  };
  tbb::parallel_sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    Hash128 ha = hashOf(a), hb = hashOf(b);
    if (ha != hb) return ha < hb;
    return contentLess(a, b);
  });
  std::vector<uint32_t> unique;
  unique.reserve(order.size());
  for (size_t i = 0; i < order.size(); ++i) {
    uint32_t o = order[i];
    if (!unique.empty()) {
      uint32_t u = unique.back();
      if (hashOf(u) == hashOf(o) && compareRemapped(in, level, u, o, childMap) == 0) {
        map[o] = uint32_t(unique.size() - 1);
        continue;
      }
    }
    map[o] = uint32_t(unique.size());
    unique.push_back(o);
  }
  order.swap(unique);
}

Dag compressBottomUp(const Dag& in) {
  Dag out;
  out.reset(in.log2Resolution, in.log2RootSize);
  std::vector<uint32_t> childMap, map;
  // Leaves.
  std::vector<uint32_t> order(in.leaves.size());
  std::iota(order.begin(), order.end(), 0u);
  map.assign(in.leaves.size(), 0);
  sortUnique(in, -1, order, childMap, map);
  emitLevel(in, -1, order, childMap, out);
  for (int l = 0; l < int(in.levels.size()); ++l) {
    childMap.swap(map);
    order.resize(in.levels[l].size());
    std::iota(order.begin(), order.end(), 0u);
    map.assign(in.levels[l].size(), 0);
    sortUnique(in, l, order, childMap, map);
    emitLevel(in, l, order, childMap, out);
  }
  for (const auto& r : in.roots)
    out.roots.push_back({r.key, r.ref.code == kRef ? NodeRef{kRef, map[r.ref.index]} : r.ref});
  return out;
}

// Subtree equality of node a and node b of one level, confirmed down to the leaves.
// Confirmed classes are kept as a union-find per level: in a DAG the same pair is reached
// along many paths, and a flat parent array is far cheaper than a set of pairs.
class SubtreeEquality {
 public:
  explicit SubtreeEquality(const Dag& dag) : dag_(dag), parent_(dag.levels.size()) {}

  bool equal(int level, uint32_t a, uint32_t b) {
    if (a == b) return true;
    if (level < 0) return dag_.leaves[a] == dag_.leaves[b];
    uint32_t ra = find(level, a), rb = find(level, b);
    if (ra == rb) return true;
    const InternalLevel& lv = dag_.levels[level];
    if (lv.codes[a] != lv.codes[b]) return false;
    const auto& below = level == 0 ? dag_.leafHashes : dag_.levelHashes[level - 1];
    uint32_t ka = lv.childBegin[a], kb = lv.childBegin[b], n = lv.refCount(a);
    for (uint32_t k = 0; k < n; ++k) {
      uint32_t ca = lv.children[ka + k], cb = lv.children[kb + k];
      if (below[ca] != below[cb] || !equal(level - 1, ca, cb)) return false;
    }
    parent_[size_t(level)][rb] = ra;
    return true;
  }

 private:
  uint32_t find(int level, uint32_t a) {
    auto& p = parent_[size_t(level)];
    if (p.empty()) {
      p.resize(dag_.levels[size_t(level)].size());
      std::iota(p.begin(), p.end(), 0u);
    }
    while (p[a] != a) {
      p[a] = p[p[a]];  // path halving
      a = p[a];
    }
    return a;
  }

  const Dag& dag_;
  std::vector<std::vector<uint32_t>> parent_;
};

Dag compressTopDown(const Dag& in) {
  const int levels = int(in.levels.size());
  // Phase 1, from the roots down: the nodes referenced by survivors, sorted by hash;
  // within a run of equal hashes, one representative per class of equal subtrees.
  // rep[l][old] = representative (old index); survivors[l] = representatives in hash order.
  std::vector<std::vector<uint32_t>> rep(levels + 1), survivors(levels + 1);
  SubtreeEquality eq(in);
  std::vector<uint32_t> current;
  std::vector<uint8_t> seen;
  std::vector<std::pair<Hash128, uint32_t>> keyed;
  for (const auto& r : in.roots)
    if (r.ref.code == kRef) current.push_back(r.ref.index);
  for (int l = levels - 1; l >= -1; --l) {
    size_t count = l < 0 ? in.leaves.size() : in.levels[l].size();
    const auto& hashes = l < 0 ? in.leafHashes : in.levelHashes[l];
    // The distinct nodes referenced, each once, sorted by (hash, index) with their hashes
    // beside them: equal hashes end up adjacent. (Sorting the references would sort every
    // repeat too, through an indirection per comparison.)
    seen.assign(count, 0);
    keyed.clear();
    for (const uint32_t o : current)
      if (!seen[o]) {
        seen[o] = 1;
        keyed.push_back({hashes[o], o});
      }
    tbb::parallel_sort(keyed.begin(), keyed.end());
    current.resize(keyed.size());
    for (size_t k = 0; k < keyed.size(); ++k) current[k] = keyed[k].second;
    auto& rp = rep[l + 1];
    rp.assign(count, UINT32_MAX);
    auto& sv = survivors[l + 1];
    for (size_t i = 0; i < current.size();) {
      size_t j = i;
      while (j < current.size() && hashes[current[j]] == hashes[current[i]]) ++j;
      size_t firstRep = sv.size();
      for (size_t k = i; k < j; ++k) {
        uint32_t o = current[k];
        uint32_t found = UINT32_MAX;
        for (size_t s = firstRep; s < sv.size() && found == UINT32_MAX; ++s)
          if (eq.equal(l, sv[s], o)) found = sv[s];
        if (found == UINT32_MAX) {
          sv.push_back(o);
          found = o;
        }
        rp[o] = found;
      }
      i = j;
    }
    if (l < 0) break;
    std::vector<uint32_t> next;
    const InternalLevel& lv = in.levels[l];
    for (uint32_t o : sv)
      for (uint32_t k = lv.childBegin[o]; k < lv.childBegin[o + 1]; ++k) next.push_back(lv.children[k]);
    current.swap(next);
  }

  // Phase 2, from the leaves up: emit the survivors. They are in hash order already; only
  // runs of equal hashes (distinct subtrees that collide) need ordering by content, which
  // needs the level below in its final order.
  Dag out;
  out.reset(in.log2Resolution, in.log2RootSize);
  std::vector<uint32_t> childMap, map;
  for (int l = -1; l < levels; ++l) {
    auto& sv = survivors[l + 1];
    size_t count = l < 0 ? in.leaves.size() : in.levels[l].size();
    const auto& hashes = l < 0 ? in.leafHashes : in.levelHashes[l];
    for (size_t i = 0; i < sv.size();) {
      size_t j = i + 1;
      while (j < sv.size() && hashes[sv[j]] == hashes[sv[i]]) ++j;
      if (j - i > 1)
        std::sort(sv.begin() + i, sv.begin() + j, [&](uint32_t a, uint32_t b) {
          return compareRemapped(in, l, a, b, childMap) < 0;
        });
      i = j;
    }
    // map: old index -> new index, through the representative.
    std::vector<uint32_t> newIndex(count, UINT32_MAX);
    for (size_t i = 0; i < sv.size(); ++i) newIndex[sv[i]] = uint32_t(i);
    map.assign(count, UINT32_MAX);
    const auto& rp = rep[l + 1];
    for (size_t o = 0; o < count; ++o)
      if (rp[o] != UINT32_MAX) map[o] = newIndex[rp[o]];
    emitLevel(in, l, sv, childMap, out);
    childMap.swap(map);
  }
  for (const auto& r : in.roots)
    out.roots.push_back({r.key, r.ref.code == kRef ? NodeRef{kRef, childMap[r.ref.index]} : r.ref});
  return out;
}

}  // namespace

Dag compressDag(Dag&& dag, CompressMode mode) {
  if (mode == CompressMode::None) return std::move(dag);
  Dag out = mode == CompressMode::BottomUp ? compressBottomUp(dag) : compressTopDown(dag);
  CPVS_DCHECK(dagInvariantsHold(out, true));
  return out;
}

}  // namespace cpvs
