#include "cpvs/dag/assemble_roots.h"

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "cpvs/dag/compress.h"
#include "cpvs/dag/node_order.h"

namespace cpvs {

Dag assembleRoots(Dag&& merged, HashKind hash, CompressMode mode) {
  Dag dag = std::move(merged);
  const int L = dag.log2Resolution;
  int t = dag.log2RootSize;
  struct Entry {
    uint64_t parentKey;
    int child;
    NodeRef ref;
  };
  std::vector<Dag::Root> current = dag.roots;
  dag.levels.resize(Dag::internalLevels(L));
  dag.levelHashes.resize(Dag::internalLevels(L));
  while (t < L) {
    uint64_t blocks = uint64_t(1) << (L - t);
    if (current.size() != blocks * blocks * blocks)
      throw std::invalid_argument("assembleRoots: " + std::to_string(current.size()) + " of " +
                                  std::to_string(blocks * blocks * blocks) + " blocks of size 2^" +
                                  std::to_string(t) + " present");
    std::vector<Entry> entries;
    entries.reserve(current.size());
    for (const auto& r : current) {
      uint64_t x = rootKeyX(r.key), y = rootKeyY(r.key), z = rootKeyZ(r.key);
      entries.push_back({rootKey(x / 2, y / 2, z / 2), octant(x, y, z), r.ref});
    }
    std::sort(entries.begin(), entries.end(), [](const Entry& p, const Entry& q) {
      return p.parentKey != q.parentKey ? p.parentKey < q.parentKey : p.child < q.child;
    });
    int level = t + 1 - 3;  // nodes of size 2^(t+1)
    const auto& belowHashes = dag.levelHashes[level - 1];
    // DAGs kept uncompressed carry no hashes; their new levels are not deduplicated.
    const bool haveHashes = belowHashes.size() == dag.levels[level - 1].size();
    InternalLevel fresh;
    std::vector<Hash128> freshHashes;
    std::vector<Dag::Root> parents;
    for (size_t i = 0; i < entries.size(); i += 8) {
      uint16_t codes = 0;
      uint32_t refs[8];
      Hash128 childHashes[8];
      int n = 0;
      bool allLit = true, allShadowed = true;
      for (int c = 0; c < 8; ++c) {
        const Entry& e = entries[i + c];
        if (e.parentKey != entries[i].parentKey || e.child != c)
          throw std::invalid_argument("assembleRoots: a block is missing or repeated");
        codes |= uint16_t(e.ref.code << (2 * c));
        allLit &= e.ref.code == kLit;
        allShadowed &= e.ref.code == kShadowed;
        if (e.ref.code == kRef) {
          childHashes[n] = haveHashes ? belowHashes[e.ref.index] : Hash128{};
          refs[n++] = e.ref.index;
        }
      }
      NodeRef ref{allLit ? kLit : kShadowed, 0};
      if (!allLit && !allShadowed) {
        ref = NodeRef{kRef, fresh.append(codes, refs)};
        freshHashes.push_back(hashInternal(codes, childHashes, n, hash));
      }
      parents.push_back({entries[i].parentKey, ref});
    }
    // Deduplicate the new level: sort by (hash, content), keep the first of equal runs.
    std::vector<uint32_t> order(fresh.size()), map(fresh.size());
    for (size_t i = 0; i < order.size(); ++i) order[i] = uint32_t(i);
    Dag tmp;
    tmp.levels.resize(level + 1);
    tmp.levels[level] = std::move(fresh);
    if (mode != CompressMode::None)
      std::sort(order.begin(), order.end(), [&](uint32_t p, uint32_t q) {
        if (freshHashes[p] != freshHashes[q]) return freshHashes[p] < freshHashes[q];
        return compareNodes(tmp, level, p, tmp, q) < 0;
      });
    InternalLevel& dst = dag.levels[level];
    dst.clear();
    dag.levelHashes[level].clear();
    for (size_t k = 0; k < order.size(); ++k) {
      uint32_t o = order[k];
      if (mode != CompressMode::None && k > 0 && freshHashes[order[k - 1]] == freshHashes[o] &&
          compareNodes(tmp, level, order[k - 1], tmp, o) == 0) {
        map[o] = map[order[k - 1]];
        continue;
      }
      const InternalLevel& src = tmp.levels[level];
      map[o] = dst.append(src.codes[o], &src.children[src.childBegin[o]]);
      dag.levelHashes[level].push_back(freshHashes[o]);
    }
    for (auto& p : parents)
      if (p.ref.code == kRef) p.ref.index = map[p.ref.index];
    current.swap(parents);
    ++t;
  }
  if (current.size() != 1) throw std::invalid_argument("assembleRoots: no single root");
  dag.roots = current;
  dag.log2RootSize = L;
  return dag;
}

}  // namespace cpvs
