#include "cpvs/dag/packed_dag.h"

#include <algorithm>
#include <string>

namespace cpvs {

namespace {

[[noreturn]] void invalid(const std::string& what) { throw InputError("packed DAG: " + what); }

// The reference a cell or child holds in the array: kGridLit / kGridShadowed for a
// homogeneous one, else the word offset of its node (or, below level 0, its leaf).
uint32_t gridEntry(uint32_t code, uint32_t word) {
  return code == kRef ? word : code == kShadowed ? kGridShadowed : kGridLit;
}

}  // namespace

bool namesLeavesByIndex(const std::vector<uint32_t>& words) {
  return words.size() >= kPackedHeaderWords && words[offsetof(PackedHeader, leafRefs) / 4] == 1;
}

Dag PackedDag::emptyDag() {
  Dag dag;
  dag.reset(kMinLog2Resolution, kMinLog2Resolution);
  dag.roots.push_back({0, {kLit, 0}});
  return dag;
}

std::vector<uint32_t> packPool(const std::vector<uint64_t>& leaves, const std::vector<InternalLevel>& levels,
                               const std::vector<NodePool::Root>& roots, std::optional<bool> compactRefs) {
  CPVS_CHECK(!roots.empty());
  const bool compact = compactRefs.value_or(compactLeafRefs(leaves.size()));
  CPVS_CHECK(!compact || compactLeafRefs(leaves.size()));
  const int L = int(levels.size());
  CPVS_CHECK(L <= kMaxInternalLevels);
  const size_t N = roots.size();
  std::vector<PackedHeader> h(N, PackedHeader{});
  uint64_t total = uint64_t(kPackedHeaderWords) * N;
  uint64_t nodeWords = 2 * uint64_t(leaves.size());
  for (size_t l = 0; l < levels.size(); ++l)
    for (size_t i = 0; i < levels[l].size(); ++i) nodeWords += packedNodeWords(int(l), levels[l].refCount(i), compact);
  auto fits = [&] {
    if (total > UINT32_MAX - 2)
      throw InputError("packing a DAG for lookups: more than 2^32 words (" + std::to_string(4 * nodeWords) + " bytes)");
  };
  for (size_t k = 0; k < N; ++k) {
    const int log2R = roots[k].log2Resolution, Lk = Dag::internalLevels(log2R);
    CPVS_CHECK(Lk >= 1 && Lk <= L);
    h[k].layoutVersion = compact ? kPackedLayoutVersion : 1;  // version 1 arrays are exactly the older layout
    h[k].log2Resolution = uint32_t(log2R);
    h[k].internalLevels = uint32_t(Lk);
    const int G = roots[k].gridLevels < 0 ? packedGridLevels(log2R) : roots[k].gridLevels;
    CPVS_CHECK(G <= packedGridLevels(log2R));
    h[k].gridLevels = uint32_t(G);
    h[k].gridWord = uint32_t(total);
    total += uint64_t(1) << (3 * h[k].gridLevels);
    fits();
  }
  // Word offset of every node, level by level from the top, so that a walk moves forward.
  std::vector<std::vector<uint32_t>> offset(static_cast<size_t>(L));
  std::vector<uint32_t> levelWord(static_cast<size_t>(L));
  for (int l = L - 1; l >= 0; --l) {
    const InternalLevel& level = levels[size_t(l)];
    levelWord[size_t(l)] = uint32_t(total);
    offset[size_t(l)].resize(level.size());
    for (size_t i = 0; i < level.size(); ++i) {
      offset[size_t(l)][i] = uint32_t(total);
      total += packedNodeWords(l, level.refCount(i), compact);
      fits();
    }
  }
  total += total & 1;
  const uint32_t leafWord = uint32_t(total);
  total += 2 * uint64_t(leaves.size());
  fits();
  std::vector<uint32_t> w(total, 0);
  for (size_t k = 0; k < N; ++k) {
    const int Lk = int(h[k].internalLevels);
    for (int l = 0; l < Lk; ++l) {
      h[k].levelWord[l] = levelWord[size_t(l)];
      h[k].levelNodes[l] = uint32_t(levels[size_t(l)].size());
    }
    h[k].leafWord = leafWord;
    h[k].leafCount = uint32_t(leaves.size());
    h[k].leafRefs = compact ? 1 : 0;
    h[k].wordCount = uint32_t(total);
    const NodeRef root = roots[k].ref;
    h[k].rootCode = root.code;
    h[k].rootWord = root.code != kRef ? 0 : offset[size_t(Lk) - 1][root.index];
    std::memcpy(w.data() + kPackedHeaderWords * k, &h[k], sizeof h[k]);
  }
  for (int l = L - 1; l >= 0; --l) {
    const InternalLevel& level = levels[size_t(l)];
    uint32_t at = levelWord[size_t(l)];
    for (size_t i = 0; i < level.size(); ++i) {
      if (l == 0 && compact) {
        // Half-words: the codes, then each child's leaf index.
        uint32_t half = 0;
        auto put = [&](uint32_t v) { w[at + half / 2] |= v << (16 * (half & 1)), ++half; };
        put(level.codes[i]);
        for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k) put(level.children[k]);
        at += (half + 1) / 2;
        continue;
      }
      w[at++] = level.codes[i];
      for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k)
        w[at++] = l == 0 ? leafWord + 2 * level.children[k] : offset[size_t(l) - 1][level.children[k]];
    }
  }
  for (size_t i = 0; i < leaves.size(); ++i) {
    w[leafWord + 2 * i] = uint32_t(leaves[i]);
    w[leafWord + 2 * i + 1] = uint32_t(leaves[i] >> 32);
  }
  // Each root's grid: descend from the root to the cell level, one octant per level.
  for (size_t k = 0; k < N; ++k) {
    const int Lk = int(h[k].internalLevels), G = int(h[k].gridLevels), cellLevel = Lk - 1 - G;
    const uint32_t side = 1u << G;
    for (uint32_t cz = 0; cz < side; ++cz)
      for (uint32_t cy = 0; cy < side; ++cy)
        for (uint32_t cx = 0; cx < side; ++cx) {
          NodeRef ref = roots[k].ref;
          for (int l = Lk - 1; l > cellLevel && ref.code == kRef; --l) {
            const int shift = l - cellLevel - 1;
            ref = levels[size_t(l)].child(ref.index, octant(cx >> shift, cy >> shift, cz >> shift));
          }
          const uint32_t word = ref.code == kRef ? offset[size_t(cellLevel)][ref.index] : 0;
          w[h[k].gridWord + (cz << G | cy) * side + cx] = gridEntry(ref.code, word);
        }
  }
  return w;
}

NodePool parsePackedPool(const std::vector<uint32_t>& words, size_t N) {
  CPVS_CHECK(N >= 1);
  if (words.size() < kPackedHeaderWords * N) invalid(N == 1 ? "shorter than its header" : "shorter than its headers");
  std::vector<PackedHeader> h(N);
  uint64_t at = uint64_t(kPackedHeaderWords) * N;
  int L = 0;
  for (size_t k = 0; k < N; ++k) {
    std::memcpy(&h[k], words.data() + kPackedHeaderWords * k, sizeof h[k]);
    const std::string which = N == 1 ? "" : " (DAG " + std::to_string(k) + ")";
    if (h[k].layoutVersion < 1 || h[k].layoutVersion > kPackedLayoutVersion)
      invalid("layout version " + std::to_string(h[k].layoutVersion) + " is not supported" + which);
    if (h[k].log2Resolution < uint32_t(kMinLog2Resolution) || h[k].log2Resolution > uint32_t(kMaxLog2Resolution))
      invalid("resolution 2^" + std::to_string(h[k].log2Resolution) + " is out of range" + which);
    const int log2R = int(h[k].log2Resolution), Lk = Dag::internalLevels(log2R);
    if (h[k].internalLevels != uint32_t(Lk) || h[k].gridLevels > uint32_t(packedGridLevels(log2R)) || h[k].gridWord != at)
      invalid("the level counts do not match the resolution" + which);
    const int G = int(h[k].gridLevels);
    at += uint64_t(1) << (3 * G);
    L = std::max(L, Lk);
  }
  const PackedHeader& h0 = h[0];
  if (h0.wordCount != words.size())
    invalid("the header counts " + std::to_string(h0.wordCount) + " words, the section holds " + std::to_string(words.size()));
  if (uint64_t(h0.leafWord) + 2 * uint64_t(h0.leafCount) != h0.wordCount || (h0.leafWord & 1))
    invalid("the leaves do not end the array");
  // The headers' pointer grids must lie in the array: packing again is then bounded by it.
  if (at > h0.leafWord) invalid("the pointer grids run past the nodes");
  if (h0.leafRefs > 1 || (h0.leafRefs == 1 && !compactLeafRefs(h0.leafCount)))
    invalid("leaf references " + std::to_string(h0.leafRefs) + " do not fit " + std::to_string(h0.leafCount) + " leaves");
  if (h0.leafRefs + 1 != h0.layoutVersion)
    invalid("layout version " + std::to_string(h0.layoutVersion) + " does not name leaves as its header says");
  const bool compact = h0.leafRefs == 1;
  for (const PackedHeader& hk : h) {
    if (hk.leafWord != h0.leafWord || hk.leafCount != h0.leafCount || hk.wordCount != h0.wordCount ||
        hk.leafRefs != h0.leafRefs || hk.layoutVersion != h0.layoutVersion)
      invalid("the headers disagree on the shared leaves");
    if (hk.rootCode > kRef) invalid("the root code is invalid");
  }

  // Parse every level's nodes in order, then map each child's word offset to its index
  // in the level below: every offset must be a node that level holds.
  NodePool pool;
  pool.levels.resize(size_t(L));
  std::vector<std::vector<uint32_t>> starts(static_cast<size_t>(L));
  for (int l = L - 1; l >= 0; --l) {
    // Every header whose DAG has level l names the same range.
    const PackedHeader* named = nullptr;
    for (const PackedHeader& hk : h) {
      if (int(hk.internalLevels) <= l) continue;
      if (named && (hk.levelWord[l] != named->levelWord[l] || hk.levelNodes[l] != named->levelNodes[l]))
        invalid("the headers disagree on level " + std::to_string(l));
      named = &hk;
    }
    if (named->levelWord[l] != at) invalid("level " + std::to_string(l) + " does not start where the one above ends");
    if (named->levelNodes[l] > h0.wordCount) invalid("level " + std::to_string(l) + " counts more nodes than words");
    InternalLevel& level = pool.levels[size_t(l)];
    starts[size_t(l)].reserve(named->levelNodes[l]);
    for (uint32_t i = 0; i < named->levelNodes[l]; ++i) {
      if (at >= h0.leafWord) invalid("level " + std::to_string(l) + " runs into the leaves");
      const bool halves = l == 0 && compact;
      const uint32_t codes = halves ? words[at] & kCodeWordMask : words[at];
      if (codes > kCodeWordMask || !validCodes(codes)) invalid("a node holds an invalid child code");
      const int refs = refCount(codes);
      const uint32_t size = packedNodeWords(l, uint32_t(refs), compact);
      if (at + uint64_t(size) > h0.leafWord) invalid("a node runs into the leaves");
      starts[size_t(l)].push_back(uint32_t(at));
      level.codes.push_back(uint16_t(codes));
      for (int k = 0; k < refs; ++k)
        level.children.push_back(halves ? compactLeafWord(words.data(), uint32_t(at), uint32_t(k), h0.leafWord)
                                        : words[at + 1 + k]);
      level.childBegin.push_back(uint32_t(level.children.size()));
      at += size;
    }
  }
  for (const PackedHeader& hk : h)
    for (int l = int(hk.internalLevels); l < kMaxInternalLevels; ++l)
      if (hk.levelWord[l] != 0 || hk.levelNodes[l] != 0) invalid("a level beyond the root is not empty");
  auto indexIn = [&](int l, uint32_t word) -> uint32_t {  // l = -1: the leaves
    if (l < 0) {
      if (word < h0.leafWord || ((word - h0.leafWord) & 1) || (word - h0.leafWord) / 2 >= h0.leafCount)
        invalid("a child offset is not a leaf");
      return (word - h0.leafWord) / 2;
    }
    const auto& s = starts[size_t(l)];
    auto it = std::lower_bound(s.begin(), s.end(), word);
    if (it == s.end() || *it != word) invalid("a child offset is not a node of the level below");
    return uint32_t(it - s.begin());
  };
  for (int l = 0; l < L; ++l)
    for (uint32_t& child : pool.levels[size_t(l)].children) child = indexIn(l - 1, child);
  pool.leaves.resize(h0.leafCount);
  for (size_t i = 0; i < pool.leaves.size(); ++i)
    pool.leaves[i] = uint64_t(words[h0.leafWord + 2 * i]) | uint64_t(words[h0.leafWord + 2 * i + 1]) << 32;
  for (const PackedHeader& hk : h) {
    NodeRef root{hk.rootCode, 0};
    if (root.code == kRef) root.index = indexIn(int(hk.internalLevels) - 1, hk.rootWord);
    pool.roots.push_back({int(hk.log2Resolution), root, int(hk.gridLevels)});
  }

  // The grids, the padding and every field not parsed above: packing the pool again must
  // give exactly these words.
  if (packPool(pool.leaves, pool.levels, pool.roots, compact) != words)
    invalid("the pointer grid or the padding does not match the nodes");
  return pool;
}

PackedDag::PackedDag(std::shared_ptr<const std::vector<uint32_t>> pool, size_t root, uint64_t nodeBytes)
    : words_(std::move(pool)), nodeBytes_(nodeBytes) {
  CPVS_CHECK(words_->size() >= kPackedHeaderWords * (root + 1));
  w_ = words_->data();
  headerWord_ = uint32_t(kPackedHeaderWords * root);
  std::memcpy(&header_, w_ + headerWord_, sizeof header_);
}

PackedDag::PackedDag(const Dag& dag) {
  if (dag.roots.size() != 1 || dag.log2RootSize != dag.log2Resolution)
    throw InputError("packing a DAG for lookups: it is not complete (" + std::to_string(dag.roots.size()) + " roots)");
  CPVS_CHECK(int(dag.levels.size()) == Dag::internalLevels(dag.log2Resolution));
  *this = PackedDag(std::make_shared<const std::vector<uint32_t>>(
                        packPool(dag.leaves, dag.levels, {{dag.log2Resolution, dag.roots.front().ref}})),
                    0, dag.bytes());
}

PackedDag PackedDag::fromWords(std::vector<uint32_t> words, Dag& dag) {
  // A single DAG is packed with the deepest grid (PackedDag(const Dag&) gives these words).
  PackedHeader h{};
  if (words.size() >= kPackedHeaderWords) std::memcpy(&h, words.data(), sizeof h);
  if (words.size() >= kPackedHeaderWords && h.log2Resolution >= uint32_t(kMinLog2Resolution) &&
      h.log2Resolution <= uint32_t(kMaxLog2Resolution) && h.gridLevels != uint32_t(packedGridLevels(int(h.log2Resolution))))
    invalid("the level counts do not match the resolution");
  NodePool pool = parsePackedPool(words, 1);
  const int log2R = pool.roots.front().log2Resolution;
  dag.reset(log2R, log2R);
  dag.leaves = std::move(pool.leaves);
  dag.levels = std::move(pool.levels);
  dag.roots.push_back({0, pool.roots.front().ref});
  const uint64_t bytes = dag.bytes(h.leafRefs == 1);  // an older array names level 0's leaves by word offset
  return PackedDag(std::make_shared<const std::vector<uint32_t>>(std::move(words)), 0, bytes);
}

}  // namespace cpvs
