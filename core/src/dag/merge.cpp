#include "cpvs/dag/merge.h"

#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

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

// One hash range of a level being merged: the inputs' nodes in it, merged on their own.
struct MergePart {
  size_t a0 = 0, a1 = 0, b0 = 0, b1 = 0;
  std::vector<uint64_t> picks;  // per node it gives: the input node copied (kFromB | index in b, or index in a)
  uint64_t children = 0;        // the child references of those nodes
  size_t nodeOffset = 0;        // where its nodes start in the merged level
  uint64_t childOffset = 0;     // where their references start
};

constexpr uint64_t kFromB = uint64_t(1) << 32;

// Merges level l (-1 = leaves) of a and b into `out`, their children already merged and
// renumbered through childA and childB; mapA and mapB receive where each input node went.
// Equal hashes never straddle two parts (each part is a range of hashes), so the parts
// merge apart and their outputs, laid end to end, are the one sweep's: the same bytes for
// any number of parts.
void mergeLevel(const Dag& a, const Dag& b, int l, const std::vector<uint32_t>& childA,
                const std::vector<uint32_t>& childB, size_t partNodes, Dag& out, std::vector<uint32_t>& mapA,
                std::vector<uint32_t>& mapB) {
  const auto& ha = l < 0 ? a.leafHashes : a.levelHashes[size_t(l)];
  const auto& hb = l < 0 ? b.leafHashes : b.levelHashes[size_t(l)];
  const size_t na = l < 0 ? a.leaves.size() : a.levels[size_t(l)].size();
  const size_t nb = l < 0 ? b.leaves.size() : b.levels[size_t(l)].size();
  mapA.assign(na, 0);
  mapB.assign(nb, 0);

  const size_t count = std::clamp<size_t>((na + nb) / std::max<size_t>(partNodes, 1), 1, 1024);
  std::vector<MergePart> parts(count);
  const auto& big = na >= nb ? ha : hb;
  for (size_t k = 0; k < count; ++k) {
    MergePart& p = parts[k];
    p.a0 = k == 0 ? 0 : parts[k - 1].a1;
    p.b0 = k == 0 ? 0 : parts[k - 1].b1;
    if (k + 1 == count) {
      p.a1 = na;
      p.b1 = nb;
    } else {
      const Hash128 pivot = big[big.size() * (k + 1) / count];
      p.a1 = size_t(std::lower_bound(ha.begin(), ha.end(), pivot) - ha.begin());
      p.b1 = size_t(std::lower_bound(hb.begin(), hb.end(), pivot) - hb.begin());
    }
  }

  const auto intoA = [&](uint32_t k) { return childA[k]; };
  const auto intoB = [&](uint32_t k) { return childB[k]; };
  const auto refs = [&](const Dag& src, size_t i) -> uint64_t { return l < 0 ? 0 : src.levels[size_t(l)].refCount(i); };
  // Content order with children mapped into the merged level below; each input stays
  // sorted under it because the maps are monotone.
  const auto sweep = [&](MergePart& p) {
    p.picks.reserve((p.a1 - p.a0) + (p.b1 - p.b0));
    size_t i = p.a0, j = p.b0;
    while (i < p.a1 || j < p.b1) {
      int c = i == p.a1 ? 1 : (j == p.b1 ? -1 : 0);
      if (c == 0) {
        c = ha[i] < hb[j] ? -1 : (hb[j] < ha[i] ? 1 : compareNodesMapped(a, l, uint32_t(i), intoA, b, uint32_t(j), intoB));
      }
      const uint32_t local = uint32_t(p.picks.size());
      if (c <= 0) {
        mapA[i] = local;
        p.picks.push_back(i);
        p.children += refs(a, i);
        if (c == 0) mapB[j++] = local;
        ++i;
      } else {
        mapB[j] = local;
        p.picks.push_back(kFromB | j);
        p.children += refs(b, j);
        ++j;
      }
    }
  };
  // Where each part's nodes go, then the nodes themselves.
  const auto write = [&](MergePart& p) {
    for (size_t i = p.a0; i < p.a1; ++i) mapA[i] += uint32_t(p.nodeOffset);
    for (size_t j = p.b0; j < p.b1; ++j) mapB[j] += uint32_t(p.nodeOffset);
    size_t n = p.nodeOffset;
    uint64_t c = p.childOffset;
    for (const uint64_t pick : p.picks) {
      const bool fromB = (pick & kFromB) != 0;
      const Dag& src = fromB ? b : a;
      const size_t i = size_t(pick & (kFromB - 1));
      if (l < 0) {
        out.leaves[n] = src.leaves[i];
        out.leafHashes[n] = src.leafHashes[i];
      } else {
        const InternalLevel& sl = src.levels[size_t(l)];
        InternalLevel& dl = out.levels[size_t(l)];
        const std::vector<uint32_t>& childMap = fromB ? childB : childA;
        dl.codes[n] = sl.codes[i];
        for (uint32_t k = sl.childBegin[i]; k < sl.childBegin[i + 1]; ++k) dl.children[c++] = childMap[sl.children[k]];
        dl.childBegin[n + 1] = uint32_t(c);
        out.levelHashes[size_t(l)][n] = src.levelHashes[size_t(l)][i];
      }
      ++n;
    }
  };
  const auto eachPart = [&](const auto& f) {
    if (count == 1) return f(parts[0]);
    // Isolated: a thread waiting here must not take up a tile baking beside the merge.
    tbb::this_task_arena::isolate([&] {
      tbb::parallel_for(size_t(0), count, [&](size_t k) { f(parts[k]); }, tbb::simple_partitioner());
    });
  };

  eachPart(sweep);
  size_t nodes = 0;
  uint64_t children = 0;
  for (MergePart& p : parts) {
    p.nodeOffset = nodes;
    p.childOffset = children;
    nodes += p.picks.size();
    children += p.children;
  }
  if (nodes > UINT32_MAX - 1 || children > UINT32_MAX)
    throw std::length_error("mergeDags: more than 2^32 nodes or child references in one level");
  if (l < 0) {
    out.leaves.resize(nodes);
    out.leafHashes.resize(nodes);
  } else {
    InternalLevel& dl = out.levels[size_t(l)];
    dl.codes.resize(nodes);
    dl.childBegin.assign(nodes + 1, 0);
    dl.children.resize(children);
    out.levelHashes[size_t(l)].resize(nodes);
  }
  eachPart(write);
}

}  // namespace

Dag mergeDags(const Dag& a, const Dag& b, CompressMode mode, size_t partNodes) {
  checkShapes(a, b);
  if (mode == CompressMode::None) return concatenate(a, b);
  Dag out;
  out.reset(a.log2Resolution, a.log2RootSize);
  std::vector<uint32_t> childA, childB, mapA, mapB;
  const int levels = int(a.levels.size());
  for (int l = -1; l < levels; ++l) {
    mergeLevel(a, b, l, childA, childB, partNodes, out, mapA, mapB);
    childA.swap(mapA);
    childB.swap(mapB);
  }
  out.roots = mergeRoots(a, childA, b, childB);
  CPVS_DCHECK(dagInvariantsHold(out, true));
  return out;
}

}  // namespace cpvs
