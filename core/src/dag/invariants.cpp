#include "cpvs/dag/invariants.h"

#include "cpvs/dag/node_order.h"

namespace cpvs {

std::string dagInvariantViolation(const Dag& dag, bool canonical) {
  const int levels = int(dag.levels.size());
  if (levels != Dag::internalLevels(dag.log2RootSize)) return "level count does not match the root size";
  const bool hashed = !dag.leafHashes.empty() || dag.leaves.empty();
  if (hashed && dag.leafHashes.size() != dag.leaves.size()) return "leaf hashes do not match the leaves";
  for (int l = 0; l < levels; ++l) {
    const InternalLevel& lv = dag.levels[size_t(l)];
    const std::string where = "level " + std::to_string(l);
    if (lv.childBegin.size() != lv.size() + 1 || lv.childBegin.front() != 0 || lv.childBegin.back() != lv.children.size())
      return where + ": child ranges do not cover the children";
    const size_t below = l == 0 ? dag.leaves.size() : dag.levels[size_t(l - 1)].size();
    for (size_t i = 0; i < lv.size(); ++i) {
      if (!validCodes(lv.codes[i])) return where + " node " + std::to_string(i) + ": invalid child code";
      if (lv.refCount(i) != uint32_t(refCount(lv.codes[i])))
        return where + " node " + std::to_string(i) + ": references do not match its codes";
    }
    for (uint32_t c : lv.children)
      if (c >= below) return where + ": a child index is outside the level below";
    if (hashed && (size_t(l) >= dag.levelHashes.size() || dag.levelHashes[size_t(l)].size() != lv.size()))
      return where + ": hashes do not match the nodes";
  }
  const size_t top = levels == 0 ? dag.leaves.size() : dag.levels.back().size();
  for (size_t i = 0; i < dag.roots.size(); ++i) {
    const NodeRef& r = dag.roots[i].ref;
    if (r.code > kRef || (r.code == kRef && r.index >= top)) return "root " + std::to_string(i) + " is invalid";
    if (i > 0 && dag.roots[i - 1].key >= dag.roots[i].key) return "roots are not in increasing key order";
  }
  if (!canonical || !hashed) return "";
  for (int l = -1; l < levels; ++l) {
    const auto& hashes = l < 0 ? dag.leafHashes : dag.levelHashes[size_t(l)];
    for (size_t i = 1; i < hashes.size(); ++i) {
      const bool ordered = hashes[i - 1] < hashes[i] ||
                           (hashes[i - 1] == hashes[i] && compareNodes(dag, l, uint32_t(i - 1), dag, uint32_t(i)) < 0);
      if (!ordered)
        return (l < 0 ? std::string("leaves") : "level " + std::to_string(l)) + " are not in canonical order at node " +
               std::to_string(i);
    }
  }
  return "";
}

}  // namespace cpvs
