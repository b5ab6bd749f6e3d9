#include "cpvs/dag/node_pool.h"

#include <algorithm>
#include <string>
#include <unordered_map>

#include "cpvs/base/error.h"
#include "cpvs/dag/packed_layout.h"

namespace cpvs {

namespace {

// A node's content in the pool: its codes and its children's pool indices.
struct NodeKey {
  uint16_t codes;
  std::vector<uint32_t> children;
  bool operator==(const NodeKey&) const = default;
};
struct NodeKeyHash {
  size_t operator()(const NodeKey& k) const {
    uint64_t h = k.codes * 0x9E3779B97F4A7C15ull;
    for (uint32_t c : k.children) h = (h ^ c) * 0xFF51AFD7ED558CCDull;
    return size_t(h ^ (h >> 29));
  }
};

}  // namespace

uint64_t NodePool::bytes(uint32_t version) const {
  const std::vector<PackedLevelForm> forms = packedLevelForms(levels, leaves.size(), version);
  uint64_t b = 8 * uint64_t(leaves.size());
  for (size_t l = 0; l < levels.size(); ++l) b += 2 * packedLevelHalves(levels[l], forms[l]);
  return b;
}

NodePool shareNodes(const std::vector<const Dag*>& dags) {
  NodePool pool;
  size_t levels = 0;
  for (const Dag* d : dags) {
    if (d->roots.size() != 1 || d->log2RootSize != d->log2Resolution)
      throw InputError("sharing nodes: a DAG is not complete (" + std::to_string(d->roots.size()) + " roots)");
    levels = std::max(levels, d->levels.size());
  }
  pool.levels.resize(levels);
  std::unordered_map<uint64_t, uint32_t> leafIndex;
  std::vector<std::unordered_map<NodeKey, uint32_t, NodeKeyHash>> nodeIndex(levels);
  std::vector<uint32_t> below, here;  // one DAG's index map for the level below and this one
  for (const Dag* d : dags) {
    below.resize(d->leaves.size());
    for (size_t i = 0; i < d->leaves.size(); ++i) {
      const auto [it, added] = leafIndex.try_emplace(d->leaves[i], uint32_t(pool.leaves.size()));
      if (added) pool.leaves.push_back(d->leaves[i]);
      below[i] = it->second;
    }
    for (size_t l = 0; l < d->levels.size(); ++l) {
      const InternalLevel& level = d->levels[l];
      InternalLevel& shared = pool.levels[l];
      here.resize(level.size());
      NodeKey key;
      for (size_t i = 0; i < level.size(); ++i) {
        key.codes = level.codes[i];
        key.children.clear();
        for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k) key.children.push_back(below[level.children[k]]);
        auto it = nodeIndex[l].find(key);
        if (it == nodeIndex[l].end()) it = nodeIndex[l].emplace(key, shared.append(key.codes, key.children.data())).first;
        here[i] = it->second;
      }
      below.swap(here);
    }
    NodeRef root = d->roots.front().ref;
    if (root.code == kRef) root.index = below[root.index];
    pool.roots.push_back({d->log2Resolution, root});
  }
  return pool;
}

uint64_t reachableBytes(const NodePool& pool, size_t root, uint32_t version) {
  const std::vector<PackedLevelForm> forms = packedLevelForms(pool.levels, pool.leaves.size(), version);
  const NodePool::Root& r = pool.roots.at(root);
  if (r.ref.code != kRef) return 0;
  // Level by level from the root: the nodes reached, each counted once.
  std::vector<uint32_t> reached{r.ref.index}, next;
  uint64_t bytes = 0;
  for (int l = r.log2Resolution - 3; l >= 0; --l) {
    const InternalLevel& level = pool.levels[size_t(l)];
    next.clear();
    for (uint32_t i : reached) {
      bytes += 2 * forms[size_t(l)].nodeHalves(level.refCount(i));
      next.insert(next.end(), level.children.begin() + level.childBegin[i], level.children.begin() + level.childBegin[i + 1]);
    }
    std::sort(next.begin(), next.end());
    next.erase(std::unique(next.begin(), next.end()), next.end());
    reached.swap(next);
  }
  return bytes + 8 * uint64_t(reached.size());
}

}  // namespace cpvs
