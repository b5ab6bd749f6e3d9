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

Dag PackedDag::emptyDag() {
  Dag dag;
  dag.reset(kMinLog2Resolution, kMinLog2Resolution);
  dag.roots.push_back({0, {kLit, 0}});
  return dag;
}

PackedDag::PackedDag(std::vector<uint32_t> words, uint64_t nodeBytes)
    : words_(std::move(words)), nodeBytes_(nodeBytes) {
  std::memcpy(&header_, words_.data(), sizeof header_);
}

PackedDag::PackedDag(const Dag& dag) {
  if (dag.roots.size() != 1 || dag.log2RootSize != dag.log2Resolution)
    throw InputError("packing a DAG for lookups: it is not complete (" + std::to_string(dag.roots.size()) + " roots)");
  const int L = int(dag.levels.size()), G = packedGridLevels(dag.log2Resolution);
  CPVS_CHECK(L == Dag::internalLevels(dag.log2Resolution) && L <= kMaxInternalLevels);
  PackedHeader h{};
  h.layoutVersion = kPackedLayoutVersion;
  h.log2Resolution = uint32_t(dag.log2Resolution);
  h.internalLevels = uint32_t(L);
  h.gridLevels = uint32_t(G);
  h.gridWord = kPackedHeaderWords;
  // Word offset of every node, level by level from the top, so that a walk moves forward.
  std::vector<std::vector<uint32_t>> offset(static_cast<size_t>(L));
  uint64_t total = uint64_t(h.gridWord) + (uint64_t(1) << (3 * G));
  auto fits = [&] {
    if (total > UINT32_MAX - 2)
      throw InputError("packing a DAG for lookups: more than 2^32 words (" + std::to_string(dag.bytes()) + " bytes)");
  };
  for (int l = L - 1; l >= 0; --l) {
    const InternalLevel& level = dag.levels[size_t(l)];
    h.levelWord[l] = uint32_t(total);
    h.levelNodes[l] = uint32_t(level.size());
    offset[size_t(l)].resize(level.size());
    for (size_t i = 0; i < level.size(); ++i) {
      offset[size_t(l)][i] = uint32_t(total);
      total += 1 + level.refCount(i);
      fits();
    }
  }
  total += total & 1;
  h.leafWord = uint32_t(total);
  h.leafCount = uint32_t(dag.leaves.size());
  total += 2 * uint64_t(dag.leaves.size());
  fits();
  h.wordCount = uint32_t(total);
  const NodeRef root = dag.roots.front().ref;
  h.rootCode = root.code;
  h.rootWord = root.code != kRef ? 0 : offset.back()[root.index];

  std::vector<uint32_t> w(total, 0);
  std::memcpy(w.data(), &h, sizeof h);
  for (int l = L - 1; l >= 0; --l) {
    const InternalLevel& level = dag.levels[size_t(l)];
    uint32_t at = h.levelWord[l];
    for (size_t i = 0; i < level.size(); ++i) {
      w[at++] = level.codes[i];
      for (uint32_t k = level.childBegin[i]; k < level.childBegin[i + 1]; ++k)
        w[at++] = l == 0 ? h.leafWord + 2 * level.children[k] : offset[size_t(l) - 1][level.children[k]];
    }
  }
  for (size_t i = 0; i < dag.leaves.size(); ++i) {
    w[h.leafWord + 2 * i] = uint32_t(dag.leaves[i]);
    w[h.leafWord + 2 * i + 1] = uint32_t(dag.leaves[i] >> 32);
  }
  // The grid: descend from the root to the cell level, one octant per level.
  const int cellLevel = L - 1 - G;
  const uint32_t side = 1u << G;
  for (uint32_t cz = 0; cz < side; ++cz)
    for (uint32_t cy = 0; cy < side; ++cy)
      for (uint32_t cx = 0; cx < side; ++cx) {
        NodeRef ref = root;
        for (int l = L - 1; l > cellLevel && ref.code == kRef; --l) {
          const int shift = l - cellLevel - 1;
          ref = dag.levels[size_t(l)].child(ref.index, octant(cx >> shift, cy >> shift, cz >> shift));
        }
        const uint32_t word = ref.code == kRef ? offset[size_t(cellLevel)][ref.index] : 0;
        w[h.gridWord + (cz << G | cy) * side + cx] = gridEntry(ref.code, word);
      }
  *this = PackedDag(std::move(w), dag.bytes());
}

PackedDag PackedDag::fromWords(std::vector<uint32_t> words, Dag& dag) {
  if (words.size() < kPackedHeaderWords) invalid("shorter than its header");
  PackedHeader h;
  std::memcpy(&h, words.data(), sizeof h);
  if (h.layoutVersion != kPackedLayoutVersion)
    invalid("layout version " + std::to_string(h.layoutVersion) + " is not supported");
  if (h.log2Resolution < uint32_t(kMinLog2Resolution) || h.log2Resolution > uint32_t(kMaxLog2Resolution))
    invalid("resolution 2^" + std::to_string(h.log2Resolution) + " is out of range");
  const int log2R = int(h.log2Resolution), L = Dag::internalLevels(log2R), G = packedGridLevels(log2R);
  if (h.internalLevels != uint32_t(L) || h.gridLevels != uint32_t(G) || h.gridWord != kPackedHeaderWords)
    invalid("the level counts do not match the resolution");
  if (h.wordCount != words.size()) invalid("the header counts " + std::to_string(h.wordCount) + " words, the section holds " + std::to_string(words.size()));
  if (uint64_t(h.leafWord) + 2 * uint64_t(h.leafCount) != h.wordCount || (h.leafWord & 1))
    invalid("the leaves do not end the array");
  if (h.rootCode > kRef) invalid("the root code is invalid");

  // Parse every level's nodes in order, then map each child's word offset to its index
  // in the level below: every offset must be a node that level holds.
  dag.reset(log2R, log2R);
  std::vector<std::vector<uint32_t>> starts(static_cast<size_t>(L));
  uint64_t at = uint64_t(h.gridWord) + (uint64_t(1) << (3 * G));
  for (int l = L - 1; l >= 0; --l) {
    if (h.levelWord[l] != at) invalid("level " + std::to_string(l) + " does not start where the one above ends");
    if (h.levelNodes[l] > h.wordCount) invalid("level " + std::to_string(l) + " counts more nodes than words");
    InternalLevel& level = dag.levels[size_t(l)];
    starts[size_t(l)].reserve(h.levelNodes[l]);
    for (uint32_t i = 0; i < h.levelNodes[l]; ++i) {
      if (at >= h.leafWord) invalid("level " + std::to_string(l) + " runs into the leaves");
      const uint32_t codes = words[at];
      if (codes > kCodeWordMask || !validCodes(codes)) invalid("a node holds an invalid child code");
      const int refs = refCount(codes);
      if (at + 1 + uint64_t(refs) > h.leafWord) invalid("a node runs into the leaves");
      starts[size_t(l)].push_back(uint32_t(at));
      level.codes.push_back(uint16_t(codes));
      for (int k = 0; k < refs; ++k) level.children.push_back(words[at + 1 + k]);
      level.childBegin.push_back(uint32_t(level.children.size()));
      at += 1 + uint64_t(refs);
    }
  }
  for (int l = L; l < kMaxInternalLevels; ++l)
    if (h.levelWord[l] != 0 || h.levelNodes[l] != 0) invalid("a level beyond the root is not empty");
  auto indexIn = [&](int l, uint32_t word) -> uint32_t {  // l = -1: the leaves
    if (l < 0) {
      if (word < h.leafWord || ((word - h.leafWord) & 1) || (word - h.leafWord) / 2 >= h.leafCount)
        invalid("a child offset is not a leaf");
      return (word - h.leafWord) / 2;
    }
    const auto& s = starts[size_t(l)];
    auto it = std::lower_bound(s.begin(), s.end(), word);
    if (it == s.end() || *it != word) invalid("a child offset is not a node of the level below");
    return uint32_t(it - s.begin());
  };
  for (int l = 0; l < L; ++l)
    for (uint32_t& child : dag.levels[size_t(l)].children) child = indexIn(l - 1, child);
  dag.leaves.resize(h.leafCount);
  for (size_t i = 0; i < dag.leaves.size(); ++i)
    dag.leaves[i] = uint64_t(words[h.leafWord + 2 * i]) | uint64_t(words[h.leafWord + 2 * i + 1]) << 32;
  NodeRef root{h.rootCode, 0};
  if (root.code == kRef) root.index = indexIn(L - 1, h.rootWord);
  dag.roots.push_back({0, root});

  // The grid, the padding and every field not parsed above: packing the DAG again must
  // give exactly these words.
  PackedDag packed(dag);
  if (packed.words_ != words) invalid("the pointer grid or the padding does not match the nodes");
  return packed;
}

}  // namespace cpvs
