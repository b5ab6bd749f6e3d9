#include "dag_testing.h"

namespace cpvs::testing {

TexelSlices syntheticSlices(uint32_t R, bool closed, uint32_t seed) {
  std::mt19937 rng(seed);
  TexelSlices d;
  size_t n = size_t(R) * R;
  uint32_t floor = R - R / 8;
  d.firstUndefined.assign(n, floor);
  d.firstShadowed.assign(n, closed ? R - 2 : floor);
  int boxes = 6 + int(rng() % 10);
  for (int b = 0; b < boxes; ++b) {
    uint32_t w = 1 + rng() % (R / 3), h = 1 + rng() % (R / 3);
    uint32_t x0 = rng() % (R - w), y0 = rng() % (R - h);
    uint32_t top = rng() % floor, bottom = top + 1 + rng() % (floor - top);
    for (uint32_t y = y0; y < y0 + h; ++y)
      for (uint32_t x = x0; x < x0 + w; ++x) {
        size_t at = size_t(y) * R + x;
        if (top < d.firstUndefined[at]) {
          d.firstUndefined[at] = top;
          d.firstShadowed[at] = closed ? std::max(top, bottom) : top;
        }
      }
  }
  // A few texels with no geometry at all, and a sloped ramp.
  for (int i = 0; i < 20; ++i) {
    size_t at = rng() % n;
    d.firstUndefined[at] = d.firstShadowed[at] = R;
  }
  for (uint32_t y = 0; y < R / 4; ++y)
    for (uint32_t x = R / 2; x < R / 2 + R / 4; ++x) {
      size_t at = size_t(y) * R + x;
      uint32_t z = (x + y) % R;
      if (z < d.firstUndefined[at]) d.firstUndefined[at] = d.firstShadowed[at] = z;
    }
  return d;
}

TexelSlices cropSlices(const TexelSlices& d, uint32_t R, uint32_t x0, uint32_t y0, uint32_t T) {
  TexelSlices out;
  out.firstUndefined.resize(size_t(T) * T);
  out.firstShadowed.resize(size_t(T) * T);
  for (uint32_t y = 0; y < T; ++y)
    for (uint32_t x = 0; x < T; ++x) {
      out.firstUndefined[size_t(y) * T + x] = d.firstUndefined[size_t(y0 + y) * R + x0 + x];
      out.firstShadowed[size_t(y) * T + x] = d.firstShadowed[size_t(y0 + y) * R + x0 + x];
    }
  return out;
}

Dag buildTile(const TexelSlices& all, int log2R, int log2T, uint32_t tx, uint32_t ty,
                     UndefinedRule rule, bool cull, CompressMode mode, HashKind hash) {
  uint32_t R = 1u << log2R, T = 1u << std::min(log2T, log2R);
  TexelSlices tile = cropSlices(all, R, tx * T, ty * T, T);
  ColumnMasks masks;
  buildColumnMasks(tile, T, T, R, rule, masks);
  MinMaxPyramid pyramid;
  buildMinMaxPyramid(masks, pyramid);
  Dag dag;
  insertTile(masks, pyramid, log2R, std::min(log2T, log2R), tx, ty, cull, dag);
  if (mode != CompressMode::None) {
    computeHashes(dag, hash);
    dag = compressDag(std::move(dag), mode);
  }
  return dag;
}

Dag buildTiled(const TexelSlices& all, int log2R, int log2T, UndefinedRule rule, bool cull,
                      CompressMode mode, HashKind hash, const std::vector<uint32_t>* order) {
  uint32_t n = log2T >= log2R ? 1 : 1u << (log2R - log2T);
  StreamingMerger merger(mode);
  for (uint32_t i = 0; i < n * n; ++i) {
    uint32_t k = order ? (*order)[i] : i;
    merger.add(buildTile(all, log2R, log2T, k % n, k / n, rule, cull, mode, hash));
  }
  return assembleRoots(*merger.finish(), hash, mode);
}

uint64_t countReferenceMismatches(const Dag& dag, const TexelSlices& d, uint32_t R,
                                         uint64_t* undefinedShadowed) {
  uint64_t bad = 0;
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      size_t at = size_t(y) * R + x;
      for (uint32_t z = 0; z < R; ++z) {
        bool shadowed = dagVoxelShadowed(dag, x, y, z);
        if (z < d.firstUndefined[at]) {
          bad += shadowed;
        } else if (z >= std::max(d.firstUndefined[at], d.firstShadowed[at])) {
          bad += !shadowed;
        } else if (undefinedShadowed) {
          *undefinedShadowed += shadowed;
        }
      }
    }
  return bad;
}

void expectSameDag(const Dag& a, const Dag& b) {
  ASSERT_EQ(a.log2Resolution, b.log2Resolution);
  ASSERT_EQ(a.levels.size(), b.levels.size());
  EXPECT_EQ(a.leaves, b.leaves);
  for (size_t l = 0; l < a.levels.size(); ++l) {
    EXPECT_EQ(a.levels[l].codes, b.levels[l].codes) << "level " << l;
    EXPECT_EQ(a.levels[l].children, b.levels[l].children) << "level " << l;
  }
  EXPECT_EQ(a.roots, b.roots);
}

void expectOptimal(const Dag& dag) {
  std::vector<uint64_t> leaves = dag.leaves;
  std::sort(leaves.begin(), leaves.end());
  EXPECT_EQ(std::adjacent_find(leaves.begin(), leaves.end()), leaves.end()) << "duplicate leaves";
  for (size_t l = 0; l < dag.levels.size(); ++l) {
    const InternalLevel& lv = dag.levels[l];
    std::vector<std::vector<uint32_t>> nodes;
    for (size_t i = 0; i < lv.size(); ++i) {
      std::vector<uint32_t> v{lv.codes[i]};
      for (uint32_t k = lv.childBegin[i]; k < lv.childBegin[i + 1]; ++k) v.push_back(lv.children[k]);
      nodes.push_back(std::move(v));
    }
    std::sort(nodes.begin(), nodes.end());
    EXPECT_EQ(std::adjacent_find(nodes.begin(), nodes.end()), nodes.end()) << "duplicate nodes in level " << l;
  }
}

std::optional<bool> subDagVoxelShadowed(const Dag& dag, uint64_t x, uint64_t y, uint64_t z) {
  const int s = dag.log2RootSize;
  const uint64_t key = rootKey(x >> s, y >> s, z >> s);
  auto it = std::lower_bound(dag.roots.begin(), dag.roots.end(), key,
                             [](const Dag::Root& r, uint64_t k) { return r.key < k; });
  if (it == dag.roots.end() || it->key != key) return std::nullopt;
  NodeRef ref = it->ref;
  for (int level = Dag::internalLevels(s) - 1; level >= 0 && ref.code == kRef; --level)
    ref = dag.levels[size_t(level)].child(ref.index, childOfVoxel(level, x, y, z));
  if (ref.code != kRef) return ref.code == kShadowed;
  return ((dag.leaves[ref.index] >> leafBit(x, y)) & 1) != 0;
}

}  // namespace cpvs::testing
