#include "cpvs/dag/packed_dag.h"

#include <algorithm>
#include <string>

namespace cpvs {

namespace {

[[noreturn]] void invalid(const std::string& what) { throw InputError("packed DAG: " + what); }

// The reference a cell holds in the array: kGridLit / kGridShadowed for a homogeneous
// one, else where its node is.
uint32_t gridEntry(uint32_t code, uint32_t at) {
  return code == kRef ? at : code == kShadowed ? kGridShadowed : kGridLit;
}

// Writes 16-bit values at half-word positions of an array of words (zeroed first).
struct HalfWriter {
  std::vector<uint32_t>& w;
  void put(uint64_t p, uint32_t v) { w[p >> 1] |= (v & 0xFFFFu) << (16 * (p & 1)); }
  void putRef(uint64_t p, uint32_t v, uint32_t halves) {
    put(p, v);
    if (halves == 2) put(p + 1, v >> 16);
  }
};

}  // namespace

uint32_t packedLayoutVersion(const std::vector<uint32_t>& words) { return words.size() >= kPackedHeaderWords ? words[0] : 0; }

Dag PackedDag::emptyDag() {
  Dag dag;
  dag.reset(kMinLog2Resolution, kMinLog2Resolution);
  dag.roots.push_back({0, {kLit, 0}});
  return dag;
}

std::vector<uint32_t> packPool(const std::vector<uint64_t>& leaves, const std::vector<InternalLevel>& levels,
                               const std::vector<NodePool::Root>& roots, uint32_t version) {
  CPVS_CHECK(!roots.empty());
  CPVS_CHECK(version >= 1 && version <= kPackedLayoutVersion);
  CPVS_CHECK(version != 2 || leaves.size() <= kMaxNarrowRefTargets);
  const bool halves = version >= 3;  // offsets in half-words of their level, leaves by index
  const int L = int(levels.size());
  CPVS_CHECK(L <= kMaxInternalLevels);
  const std::vector<PackedLevelForm> forms = packedLevelForms(levels, leaves.size(), version);
  const size_t N = roots.size();
  std::vector<PackedHeader> h(N, PackedHeader{});
  uint64_t total = uint64_t(kPackedHeaderWords) * N;
  auto fits = [&] {
    if (total > UINT32_MAX - 2) {
      uint64_t bytes = 8 * uint64_t(leaves.size());
      for (int l = 0; l < L; ++l) bytes += 2 * packedLevelHalves(levels[size_t(l)], forms[size_t(l)]);
      throw InputError("packing a DAG for lookups: more than 2^32 words (" + std::to_string(bytes) + " bytes of nodes)");
    }
  };
  for (size_t k = 0; k < N; ++k) {
    const int log2R = roots[k].log2Resolution, Lk = Dag::internalLevels(log2R);
    CPVS_CHECK(Lk >= 1 && Lk <= L);
    h[k].layoutVersion = version;
    h[k].log2Resolution = uint32_t(log2R);
    h[k].internalLevels = uint32_t(Lk);
    const int G = roots[k].gridLevels < 0 ? packedGridLevels(log2R) : roots[k].gridLevels;
    CPVS_CHECK(G <= packedGridLevels(log2R));
    h[k].gridLevels = uint32_t(G);
    h[k].gridWord = uint32_t(total);
    total += uint64_t(1) << (3 * h[k].gridLevels);
    fits();
  }
  // Where every node starts, in half-words from its level's start, level by level from the
  // top, so that a walk moves forward; each level starts at a word.
  std::vector<std::vector<uint32_t>> start(static_cast<size_t>(L));
  std::vector<uint32_t> levelWord(static_cast<size_t>(L));
  for (int l = L - 1; l >= 0; --l) {
    const InternalLevel& level = levels[size_t(l)];
    levelWord[size_t(l)] = uint32_t(total);
    start[size_t(l)].resize(level.size());
    uint64_t at = 0;
    for (size_t i = 0; i < level.size(); ++i) {
      start[size_t(l)][i] = uint32_t(at);
      at += forms[size_t(l)].nodeHalves(level.refCount(i));
      // Every half-word of a node, not only its start, lies below the grid's sentinels, so
      // the walks' 32-bit half-word arithmetic within a node never wraps.
      if (at > kGridShadowed)
        throw InputError("packing a DAG for lookups: level " + std::to_string(l) + " holds more than 2^32 half-words");
      total = levelWord[size_t(l)] + (at + 1) / 2;
      fits();
    }
  }
  total += total & 1;
  const uint32_t leafWord = uint32_t(total);
  total += 2 * uint64_t(leaves.size());
  fits();
  // What a reference to node i of level l holds: its half-word offset in the level, or
  // before version 3 its word offset in the array.
  auto nodeAt = [&](int l, uint32_t i) { return halves ? start[size_t(l)][i] : levelWord[size_t(l)] + start[size_t(l)][i] / 2; };
  std::vector<uint32_t> w(total, 0);
  uint32_t wideRefs = 0;
  for (int l = 0; l < L; ++l) wideRefs |= uint32_t(forms[size_t(l)].refHalves == 2) << l;
  for (size_t k = 0; k < N; ++k) {
    const int Lk = int(h[k].internalLevels);
    for (int l = 0; l < (halves ? L : Lk); ++l) {
      h[k].levelWord[l] = levelWord[size_t(l)];
      h[k].levelNodes[l] = uint32_t(levels[size_t(l)].size());
    }
    h[k].leafWord = leafWord;
    h[k].leafCount = uint32_t(leaves.size());
    h[k].wideRefs = halves ? wideRefs : version == 2 ? 1 : 0;
    h[k].wordCount = uint32_t(total);
    const NodeRef root = roots[k].ref;
    h[k].rootCode = root.code;
    h[k].rootWord = root.code != kRef ? 0 : nodeAt(Lk - 1, root.index);
    std::memcpy(w.data() + kPackedHeaderWords * k, &h[k], sizeof h[k]);
  }
  HalfWriter out{w};
  for (int l = L - 1; l >= 0; --l) {
    const InternalLevel& level = levels[size_t(l)];
    const PackedLevelForm form = forms[size_t(l)];
    const uint64_t base = 2 * uint64_t(levelWord[size_t(l)]);
    for (size_t i = 0; i < level.size(); ++i) {
      uint64_t p = base + start[size_t(l)][i];
      out.put(p, level.codes[i]);
      p += form.codeHalves;
      for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k, p += form.refHalves) {
        const uint32_t child = level.children[k];
        // Below level 0 a leaf: its index (from version 2), or its word.
        const uint32_t ref = l > 0 ? nodeAt(l - 1, child) : version >= 2 ? child : leafWord + 2 * child;
        out.putRef(p, ref, form.refHalves);
      }
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
          const uint32_t at = ref.code == kRef ? nodeAt(cellLevel, ref.index) : 0;
          w[h[k].gridWord + (cz << G | cy) * side + cx] = gridEntry(ref.code, at);
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
  const uint32_t version = h0.layoutVersion;
  const bool halves = version >= 3;
  if (h0.wordCount != words.size())
    invalid("the header counts " + std::to_string(h0.wordCount) + " words, the section holds " + std::to_string(words.size()));
  if (uint64_t(h0.leafWord) + 2 * uint64_t(h0.leafCount) != h0.wordCount || (h0.leafWord & 1))
    invalid("the leaves do not end the array");
  // The headers' pointer grids must lie in the array: packing again is then bounded by it.
  if (at > h0.leafWord) invalid("the pointer grids run past the nodes");
  if (version == 2 && !(h0.wideRefs == 1 && h0.leafCount <= kMaxNarrowRefTargets))
    invalid("leaf references " + std::to_string(h0.wideRefs) + " do not fit " + std::to_string(h0.leafCount) + " leaves");
  if ((version == 1 && h0.wideRefs != 0) || (halves && (h0.wideRefs >> L) != 0))
    invalid("layout version " + std::to_string(version) + " does not name children as its header says");
  for (const PackedHeader& hk : h) {
    if (hk.leafWord != h0.leafWord || hk.leafCount != h0.leafCount || hk.wordCount != h0.wordCount ||
        hk.wideRefs != h0.wideRefs || hk.layoutVersion != h0.layoutVersion)
      invalid("the headers disagree on the shared leaves");
    if (hk.rootCode > kRef) invalid("the root code is invalid");
  }
  // How each level holds its nodes, as the header says (packing again checks that it is
  // what the pool's sizes give).
  std::vector<PackedLevelForm> forms(static_cast<size_t>(L));
  for (int l = 0; l < L; ++l)
    forms[size_t(l)] = halves ? PackedLevelForm{1, 1 + ((h0.wideRefs >> l) & 1), false}
                              : l == 0 && version == 2 ? PackedLevelForm{1, 1, true} : PackedLevelForm{2, 2, true};

  // Parse every level's nodes in order, then map each child's reference to its index in
  // the level below: every reference must name a node that level holds.
  NodePool pool;
  pool.levels.resize(size_t(L));
  std::vector<std::vector<uint64_t>> starts(static_cast<size_t>(L));  // half-words from the array's start
  const uint64_t leafHalf = 2 * uint64_t(h0.leafWord);
  auto half = [&](uint64_t q) { return (words[q >> 1] >> (16 * (q & 1))) & 0xFFFFu; };
  for (int l = L - 1; l >= 0; --l) {
    // Every header whose DAG has level l (from version 3: every header) names the same range.
    const PackedHeader* named = nullptr;
    for (const PackedHeader& hk : h) {
      if (!halves && int(hk.internalLevels) <= l) continue;
      if (named && (hk.levelWord[l] != named->levelWord[l] || hk.levelNodes[l] != named->levelNodes[l]))
        invalid("the headers disagree on level " + std::to_string(l));
      named = &hk;
    }
    if (named->levelWord[l] != at) invalid("level " + std::to_string(l) + " does not start where the one above ends");
    if (named->levelNodes[l] > leafHalf - 2 * at)  // a node holds at least a half-word
      invalid("level " + std::to_string(l) + " counts more nodes than the half-words before the leaves");
    const PackedLevelForm form = forms[size_t(l)];
    InternalLevel& level = pool.levels[size_t(l)];
    starts[size_t(l)].reserve(named->levelNodes[l]);
    uint64_t p = 2 * at;
    for (uint32_t i = 0; i < named->levelNodes[l]; ++i) {
      if (p >= leafHalf) invalid("level " + std::to_string(l) + " runs into the leaves");
      const uint32_t codes = form.codeHalves == 2 ? words[p / 2] : half(p);
      if (codes > kCodeWordMask || !validCodes(codes)) invalid("a node holds an invalid child code");
      const int refs = refCount(codes);
      const uint64_t size = form.nodeHalves(uint64_t(refs));
      if (p + size > leafHalf) invalid("a node runs into the leaves");
      starts[size_t(l)].push_back(p);
      level.codes.push_back(uint16_t(codes));
      for (int k = 0; k < refs; ++k) {
        const uint64_t r = p + form.codeHalves + uint64_t(k) * form.refHalves;
        level.children.push_back(form.refHalves == 2 ? half(r) | half(r + 1) << 16 : half(r));
      }
      level.childBegin.push_back(uint32_t(level.children.size()));
      p += size;
    }
    at = (p + 1) / 2;
  }
  for (const PackedHeader& hk : h)
    for (int l = halves ? L : int(hk.internalLevels); l < kMaxInternalLevels; ++l)
      if (hk.levelWord[l] != 0 || hk.levelNodes[l] != 0) invalid("a level beyond the root is not empty");
  // The node of level l (-1: the leaf) a reference names.
  auto indexIn = [&](int l, uint32_t ref) -> uint32_t {
    if (l < 0) {
      if (version >= 2) {
        if (ref >= h0.leafCount) invalid("a child offset is not a leaf");
        return ref;
      }
      if (ref < h0.leafWord || ((ref - h0.leafWord) & 1) || (ref - h0.leafWord) / 2 >= h0.leafCount)
        invalid("a child offset is not a leaf");
      return (ref - h0.leafWord) / 2;
    }
    const uint64_t half = halves ? 2 * uint64_t(h0.levelWord[l]) + ref : 2 * uint64_t(ref);
    const auto& s = starts[size_t(l)];
    auto it = std::lower_bound(s.begin(), s.end(), half);
    if (it == s.end() || *it != half) invalid("a child offset is not a node of the level below");
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

  // The grids, the padding, the reference widths and every field not parsed above:
  // packing the pool again must give exactly these words.
  if (packPool(pool.leaves, pool.levels, pool.roots, version) != words)
    invalid("the pointer grid, the reference widths or the padding do not match the nodes");
  return pool;
}

PackedDag::PackedDag(std::shared_ptr<const std::vector<uint32_t>> pool, size_t root, uint64_t nodeBytes)
    : words_(std::move(pool)), nodeBytes_(nodeBytes) {
  CPVS_CHECK(words_->size() >= kPackedHeaderWords * (root + 1));
  w_ = words_->data();
  headerWord_ = uint32_t(kPackedHeaderWords * root);
  std::memcpy(&header_, w_ + headerWord_, sizeof header_);
  CPVS_CHECK(header_.layoutVersion == kPackedLayoutVersion);
  for (int l = 0; l < int(header_.internalLevels); ++l) {
    const uint32_t wide = (header_.wideRefs >> l) & 1;
    levels_[l] = {w_ + header_.levelWord[l], wide, wide ? 0xFFFFFFFFu : 0xFFFFu};
  }
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
  if (h.layoutVersion < kPackedLayoutVersion) return PackedDag(dag);  // an older layout: today's is walked
  return PackedDag(std::make_shared<const std::vector<uint32_t>>(std::move(words)), 0, dag.bytes());
}

}  // namespace cpvs
