#include "cpvs/dag/merge.h"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "cpvs/base/error.h"
#include "cpvs/dag/invariants.h"
#include "cpvs/dag/node_order.h"

namespace cpvs {

namespace {

void checkShapes(const Dag& a, const Dag& b) {
  if (a.log2Resolution != b.log2Resolution || a.log2RootSize != b.log2RootSize ||
      a.levels.size() != b.levels.size())
    throw std::invalid_argument("mergeDags: sub-DAGs of different shapes (resolution 2^" +
                                std::to_string(a.log2Resolution) + " vs 2^" +
                                std::to_string(b.log2Resolution) + ", roots 2^" +
                                std::to_string(a.log2RootSize) + " vs 2^" +
                                std::to_string(b.log2RootSize) + ")");
}

std::vector<Dag::Root> mergeRoots(const Dag& a, const std::vector<uint32_t>& mapA, const Dag& b,
                                  const std::vector<uint32_t>& mapB) {
  auto mapped = [](const Dag::Root& r, const std::vector<uint32_t>& m) {
    return Dag::Root{r.key, r.ref.code == kRef ? NodeRef{kRef, m[r.ref.index]} : r.ref};
  };
  std::vector<Dag::Root> out;
  out.reserve(a.roots.size() + b.roots.size());
  size_t i = 0, j = 0;
  while (i < a.roots.size() || j < b.roots.size()) {
    if (j == b.roots.size() || (i < a.roots.size() && a.roots[i].key < b.roots[j].key)) {
      out.push_back(mapped(a.roots[i++], mapA));
    } else if (i == a.roots.size() || b.roots[j].key < a.roots[i].key) {
      out.push_back(mapped(b.roots[j++], mapB));
    } else {
      throw std::invalid_argument("mergeDags: both sub-DAGs hold the root block (" +
                                  std::to_string(rootKeyX(a.roots[i].key)) + ", " +
                                  std::to_string(rootKeyY(a.roots[i].key)) + ", " +
                                  std::to_string(rootKeyZ(a.roots[i].key)) + ")");
    }
  }
  return out;
}

Dag concatenate(const Dag& a, const Dag& b) {
  Dag out = a;
  size_t leafOffset = a.leaves.size();
  out.leaves.insert(out.leaves.end(), b.leaves.begin(), b.leaves.end());
  out.leafHashes.insert(out.leafHashes.end(), b.leafHashes.begin(), b.leafHashes.end());
  size_t belowOffset = leafOffset;
  std::vector<uint32_t> mapA, mapB;
  for (size_t l = 0; l < b.levels.size(); ++l) {
    InternalLevel& dst = out.levels[l];
    const InternalLevel& src = b.levels[l];
    size_t offset = dst.size();
    for (size_t i = 0; i < src.size(); ++i) {
      dst.codes.push_back(src.codes[i]);
      for (uint32_t k = src.childBegin[i]; k < src.childBegin[i + 1]; ++k)
        dst.children.push_back(uint32_t(src.children[k] + belowOffset));
      dst.childBegin.push_back(uint32_t(dst.children.size()));
    }
    if (l < b.levelHashes.size())
      out.levelHashes[l].insert(out.levelHashes[l].end(), b.levelHashes[l].begin(), b.levelHashes[l].end());
    belowOffset = offset;
  }
  size_t top = a.levels.empty() ? a.leaves.size() : a.levels.back().size();
  mapA.resize(top);
  for (size_t i = 0; i < top; ++i) mapA[i] = uint32_t(i);
  size_t topB = b.levels.empty() ? b.leaves.size() : b.levels.back().size();
  mapB.resize(topB);
  for (size_t i = 0; i < topB; ++i) mapB[i] = uint32_t(i + belowOffset);
  out.roots = mergeRoots(a, mapA, b, mapB);
  return out;
}

}  // namespace

Dag mergeDags(const Dag& a, const Dag& b, CompressMode mode) {
  checkShapes(a, b);
  if (mode == CompressMode::None) return concatenate(a, b);
  Dag out;
  out.reset(a.log2Resolution, a.log2RootSize);
  std::vector<uint32_t> childA, childB, mapA, mapB;
  const int levels = int(a.levels.size());
  for (int l = -1; l < levels; ++l) {
    const auto& ha = l < 0 ? a.leafHashes : a.levelHashes[l];
    const auto& hb = l < 0 ? b.leafHashes : b.levelHashes[l];
    size_t na = l < 0 ? a.leaves.size() : a.levels[l].size();
    size_t nb = l < 0 ? b.leaves.size() : b.levels[l].size();
    mapA.assign(na, 0);
    mapB.assign(nb, 0);
    // Content order with children mapped into the merged level below; each input stays
    // sorted under it because the maps are monotone.
    const auto intoA = [&](uint32_t k) { return childA[k]; };
    const auto intoB = [&](uint32_t k) { return childB[k]; };
    auto compare = [&](uint32_t i, uint32_t j) -> int {
      if (ha[i] != hb[j]) return ha[i] < hb[j] ? -1 : 1;
      return compareNodesMapped(a, l, i, intoA, b, j, intoB);
    };
    auto emit = [&](const Dag& src, uint32_t i, const std::vector<uint32_t>& childMap,
                    const Hash128& h) -> uint32_t {
      if (l < 0) {
        out.leaves.push_back(src.leaves[i]);
        out.leafHashes.push_back(h);
        return uint32_t(out.leaves.size() - 1);
      }
      const InternalLevel& sl = src.levels[l];
      InternalLevel& dl = out.levels[l];
      dl.codes.push_back(sl.codes[i]);
      for (uint32_t k = sl.childBegin[i]; k < sl.childBegin[i + 1]; ++k) dl.children.push_back(childMap[sl.children[k]]);
      dl.childBegin.push_back(uint32_t(dl.children.size()));
      out.levelHashes[l].push_back(h);
      return uint32_t(dl.size() - 1);
    };
    if (l >= 0) {
      out.levels[l].codes.reserve(na + nb);
      out.levelHashes[l].reserve(na + nb);
    }
    size_t i = 0, j = 0;
    while (i < na || j < nb) {
      int c = i == na ? 1 : (j == nb ? -1 : compare(uint32_t(i), uint32_t(j)));
      if (c < 0) {
        mapA[i] = emit(a, uint32_t(i), childA, ha[i]);
        ++i;
      } else if (c > 0) {
        mapB[j] = emit(b, uint32_t(j), childB, hb[j]);
        ++j;
      } else {
        mapA[i] = mapB[j] = emit(a, uint32_t(i), childA, ha[i]);
        ++i;
        ++j;
      }
    }
    childA.swap(mapA);
    childB.swap(mapB);
  }
  out.roots = mergeRoots(a, childA, b, childB);
  CPVS_DCHECK(dagInvariantsHold(out, true));
  return out;
}

}  // namespace cpvs
