// The census of classes up to reflection and inversion, bottom-up: a node is named by its
// class and the transform that takes the class's canonical node to it, normalised modulo
// the transforms that leave the canonical node unchanged (its stabiliser), so that two
// equal subtrees always get the same name. A node's canonical form is the least key over
// the group of its transformed code word and its children's names.
#include "cpvs/dag/symmetry.h"

#include <algorithm>
#include <array>
#include <bit>
#include <numeric>

#include "cpvs/base/error.h"

namespace cpvs {
namespace {

constexpr int kGroupSize = 16;
using Stabiliser = uint16_t;  // bit t: transform t leaves the node as it is

// Every transform whose bits are among `generators`.
std::vector<uint32_t> groupOf(uint32_t generators) {
  std::vector<uint32_t> g;
  for (uint32_t t = 0; t < kGroupSize; ++t)
    if ((t & ~generators) == 0) g.push_back(t);
  return g;
}

// The least of the coset t + S: the one name of a transform modulo a stabiliser.
uint32_t reduce(uint32_t t, Stabiliser s) {
  uint32_t best = t;
  for (uint32_t u = 1; u < kGroupSize; ++u)
    if ((s >> u) & 1) best = std::min(best, t ^ u);
  return best;
}

// A node's name one level up: its class and its transform, packed for the parent's key.
struct Name {
  uint32_t cls = 0;
  uint32_t t = 0;
};

// Where child p of a transformed node of `level` comes from: level 0's children are its
// depth slices (only z reverses them), above that the octants (c = dz*4 + dy*2 + dx).
uint32_t childPermutation(int level, uint32_t t) { return level == 0 ? ((t & kReflectZ) ? 7u : 0u) : (t & 7u); }

using Key = std::array<uint32_t, 1 + kChildren>;

// Groups keys into classes: the canonical key of every node, sorted; returns the class of
// each node, and the number of classes.
uint64_t classify(const std::vector<Key>& canonical, std::vector<Name>& names) {
  std::vector<uint32_t> order(canonical.size());
  std::iota(order.begin(), order.end(), 0u);
  std::sort(order.begin(), order.end(), [&](uint32_t a, uint32_t b) {
    return canonical[a] != canonical[b] ? canonical[a] < canonical[b] : a < b;
  });
  uint64_t classes = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    if (k == 0 || canonical[order[k]] != canonical[order[k - 1]]) ++classes;
    names[order[k]].cls = uint32_t(classes - 1);
  }
  return classes;
}

}  // namespace

uint64_t transformLeaf(uint64_t m, uint32_t t) {
  if (t & kReflectX) {  // reverse the bits of each byte (a row of 8 texels)
    m = ((m >> 1) & 0x5555555555555555ull) | ((m & 0x5555555555555555ull) << 1);
    m = ((m >> 2) & 0x3333333333333333ull) | ((m & 0x3333333333333333ull) << 2);
    m = ((m >> 4) & 0x0F0F0F0F0F0F0F0Full) | ((m & 0x0F0F0F0F0F0F0F0Full) << 4);
  }
  if (t & kReflectY) m = __builtin_bswap64(m);
  if (t & kInvert) m = ~m;
  return m;
}

SymmetryCensus symmetryCensus(const Dag& dag, uint32_t generators) {
  CPVS_CHECK((generators & ~kAllSymmetries) == 0);
  const std::vector<uint32_t> group = groupOf(generators);
  SymmetryCensus census;
  census.generators = generators;
  census.plainBytes = dag.bytes();

  // Leaves: the least mask over the group.
  std::vector<Name> below(dag.leaves.size());
  std::vector<Stabiliser> belowStabiliser;
  {
    std::vector<Key> canonical(dag.leaves.size(), Key{});
    std::vector<Stabiliser> stabiliser(dag.leaves.size());
    for (size_t i = 0; i < dag.leaves.size(); ++i) {
      uint64_t best = ~uint64_t{0};
      uint32_t bestT = 0;
      for (const uint32_t t : group) {
        const uint64_t m = transformLeaf(dag.leaves[i], t);
        if (t == 0 || m < best) best = m, bestT = t;
      }
      Stabiliser s = 0;
      for (const uint32_t t : group)
        if (transformLeaf(dag.leaves[i], t) == best) s |= Stabiliser(1u << (t ^ bestT));
      canonical[i][0] = uint32_t(best);
      canonical[i][1] = uint32_t(best >> 32);
      stabiliser[i] = s;
      below[i].t = reduce(bestT, s);
    }
    const uint64_t classes = classify(canonical, below);
    belowStabiliser.assign(classes, 0);
    for (size_t i = 0; i < below.size(); ++i) belowStabiliser[below[i].cls] = stabiliser[i];
    census.nodes.push_back(dag.leaves.size());
    census.classes.push_back(classes);
  }
  const int bits = std::popcount(generators);
  uint64_t belowTargets = census.classes.back();  // what the next level's references name
  census.symmetricBytes = 8 * belowTargets;

  for (size_t l = 0; l < dag.levels.size(); ++l) {
    const InternalLevel& level = dag.levels[l];
    CPVS_CHECK(census.classes.back() < (uint64_t{1} << 27));
    std::vector<Key> canonical(level.size());
    std::vector<Name> names(level.size());
    std::vector<Stabiliser> stabiliser(level.size());
    std::vector<Key> keys(group.size());
    for (size_t i = 0; i < level.size(); ++i) {
      const uint32_t codes = level.codes[i];
      size_t best = 0;
      for (size_t g = 0; g < group.size(); ++g) {
        const uint32_t t = group[g];
        const uint32_t perm = childPermutation(int(l), t);
        Key& key = keys[g];
        key.fill(0);
        uint32_t newCodes = 0;
        int refs = 0;
        for (int p = 0; p < kChildren; ++p) {
          const int from = int(uint32_t(p) ^ perm);
          uint32_t code = childCode(codes, from);
          if (code == kRef) {
            const Name child = below[level.child(i, from).index];
            key[size_t(1 + refs++)] = child.cls * kGroupSize + reduce(t ^ child.t, belowStabiliser[child.cls]) + 1;
          } else if (t & kInvert) {
            code ^= 1u;  // kLit <-> kShadowed
          }
          newCodes |= code << (2 * p);
        }
        key[0] = newCodes;
        if (g > 0 && key < keys[best]) best = g;
      }
      Stabiliser s = 0;
      for (size_t g = 0; g < group.size(); ++g)
        if (keys[g] == keys[best]) s |= Stabiliser(1u << (group[g] ^ group[best]));
      canonical[i] = keys[best];
      stabiliser[i] = s;
      names[i].t = reduce(group[best], s);
    }
    const uint64_t classes = classify(canonical, names);
    // One node per class: its code half-word and its references.
    const uint32_t refHalves = wideRefsInto(belowTargets) ? 2u : 1u;
    std::vector<uint8_t> seen(classes, 0);
    uint64_t halves = 0;
    belowStabiliser.assign(classes, 0);
    for (size_t i = 0; i < level.size(); ++i) {
      belowStabiliser[names[i].cls] = stabiliser[i];
      if (seen[names[i].cls]) continue;
      seen[names[i].cls] = 1;
      const uint32_t refs = level.refCount(i);
      uint32_t transformed = 0;  // references naming their class through a transform
      for (uint32_t r = 0; r < refs; ++r) transformed += (canonical[i][1 + r] - 1) % kGroupSize != 0;
      halves += 1 + refHalves * refs + (transformed * uint32_t(bits) + 15) / 16;
    }
    census.symmetricBytes += 2 * halves;
    belowTargets = halves;
    below = std::move(names);
    census.nodes.push_back(level.size());
    census.classes.push_back(classes);
  }
  return census;
}

}  // namespace cpvs
