// DAG construction, compression and merging against a dense brute-force voxel reference.
#include <gtest/gtest.h>

#include <algorithm>
#include <random>
#include <set>

#include "cpvs/base/error.h"
#include "cpvs/io/cpvs_file.h"
#include "cpvs/dag/packed_dag.h"
#include "cpvs/dag/symmetry.h"
#include "dag_testing.h"

namespace cpvs {
namespace {

using testing::buildTiled;
using testing::countReferenceMismatches;
using testing::expectOptimal;
using testing::expectSameDag;
using testing::syntheticSlices;

struct Case {
  int log2R;
  bool closed;
  UndefinedRule rule;
  uint32_t seed;
};

class DagReference : public ::testing::TestWithParam<Case> {};

// Every defined voxel answers as the dense reference, for every construction variant,
// and the variants agree to the byte (they compute the optimal DAG of the same voxels).
TEST_P(DagReference, EveryDefinedVoxelMatchesAndVariantsAgree) {
  const Case c = GetParam();
  const uint32_t R = 1u << c.log2R;
  TexelSlices d = syntheticSlices(R, c.closed, c.seed);
  Dag culledTopDown = buildTiled(d, c.log2R, c.log2R, c.rule, true, CompressMode::TopDown, HashKind::Xxh3);
  EXPECT_EQ(countReferenceMismatches(culledTopDown, d, R), 0u);
  expectOptimal(culledTopDown);

  Dag unculledBottomUp = buildTiled(d, c.log2R, c.log2R, c.rule, false, CompressMode::BottomUp, HashKind::Xxh3);
  expectSameDag(culledTopDown, unculledBottomUp);
  Dag culledBottomUp = buildTiled(d, c.log2R, c.log2R, c.rule, true, CompressMode::BottomUp, HashKind::Xxh3);
  expectSameDag(culledTopDown, culledBottomUp);
  Dag unculledTopDown = buildTiled(d, c.log2R, c.log2R, c.rule, false, CompressMode::TopDown, HashKind::Xxh3);
  expectSameDag(culledTopDown, unculledTopDown);

  // Uncompressed DAGs (as inserted) hold the same voxels.
  Dag raw = buildTiled(d, c.log2R, c.log2R, c.rule, true, CompressMode::None, HashKind::Xxh3);
  EXPECT_EQ(countReferenceMismatches(raw, d, R), 0u);
  Dag rawUnculled = buildTiled(d, c.log2R, c.log2R, c.rule, false, CompressMode::None, HashKind::Xxh3);
  EXPECT_GE(rawUnculled.nodeCount(), raw.nodeCount());
  EXPECT_GE(raw.nodeCount(), culledTopDown.nodeCount());
}

// Tiles of any size, merged in any order, give the same bytes as one untiled build: the
// resolved voxels depend only on each 8x8 column, and homogeneity above the tiles is
// decided from the children exactly as an untiled build decides it.
TEST_P(DagReference, TiledBuildsMatchUntiledInAnyMergeOrder) {
  const Case c = GetParam();
  const uint32_t R = 1u << c.log2R;
  TexelSlices d = syntheticSlices(R, c.closed, c.seed);
  Dag whole = buildTiled(d, c.log2R, c.log2R, c.rule, true, CompressMode::TopDown, HashKind::Xxh3);
  for (int log2T : {3, 4, 5}) {
    uint32_t n = 1u << (c.log2R - log2T);
    std::vector<uint32_t> order(n * n);
    for (uint32_t i = 0; i < order.size(); ++i) order[i] = i;
    std::mt19937 rng(c.seed + log2T);
    for (int shuffle = 0; shuffle < 2; ++shuffle) {
      std::shuffle(order.begin(), order.end(), rng);
      Dag tiled = buildTiled(d, c.log2R, log2T, c.rule, true, CompressMode::TopDown, HashKind::Xxh3, &order);
      SCOPED_TRACE("tile 2^" + std::to_string(log2T));
      expectSameDag(whole, tiled);
    }
  }
}

// A hash with 8 values makes different subtrees collide all the time: the DAG must still
// hold exactly the reference voxels, stay optimal, and have the same node counts.
TEST_P(DagReference, ForcedHashCollisionsStayCorrect) {
  const Case c = GetParam();
  const uint32_t R = 1u << c.log2R;
  TexelSlices d = syntheticSlices(R, c.closed, c.seed);
  Dag strong = buildTiled(d, c.log2R, c.log2R, c.rule, true, CompressMode::TopDown, HashKind::Xxh3);
  for (CompressMode mode : {CompressMode::TopDown, CompressMode::BottomUp}) {
    Dag weak = buildTiled(d, c.log2R, 4, c.rule, true, mode, HashKind::WeakForTests);
    EXPECT_EQ(countReferenceMismatches(weak, d, R), 0u);
    expectOptimal(weak);
    EXPECT_EQ(weak.leaves.size(), strong.leaves.size());
    for (size_t l = 0; l < weak.levels.size(); ++l) EXPECT_EQ(weak.levels[l].size(), strong.levels[l].size());
  }
  // Top-down and bottom-up still agree to the byte under collisions.
  expectSameDag(buildTiled(d, c.log2R, 4, c.rule, true, CompressMode::TopDown, HashKind::WeakForTests),
                buildTiled(d, c.log2R, 4, c.rule, false, CompressMode::BottomUp, HashKind::WeakForTests));
}

// The packed layout the queries walk answers every voxel, and every 8x8 slice, as the
// reference walk over Dag's levels does.
TEST_P(DagReference, PackedLayoutAnswersAsTheLevels) {
  const Case c = GetParam();
  const uint32_t R = 1u << c.log2R;
  TexelSlices d = syntheticSlices(R, c.closed, c.seed);
  const Dag dag = buildTiled(d, c.log2R, c.log2R, c.rule, true, CompressMode::TopDown, HashKind::Xxh3);
  const PackedDag packed(dag);
  EXPECT_EQ(packed.bytes(), dag.bytes());
  uint64_t differ = 0;
  for (uint64_t z = 0; z < R; ++z)
    for (uint64_t y = 0; y < R; ++y)
      for (uint64_t x = 0; x < R; ++x) differ += dagVoxelShadowed(dag, x, y, z) != packed.voxelShadowed(x, y, z);
  EXPECT_EQ(differ, 0u);
  for (uint64_t z = 0; z < R; ++z)
    for (uint64_t y = 0; y < R; y += 8)
      for (uint64_t x = 0; x < R; x += 8) {
        uint64_t want = 0;  // the slice assembled voxel by voxel from the reference walk
        for (uint64_t b = 0; b < 64; ++b) want |= uint64_t(dagVoxelShadowed(dag, x + b % 8, y + b / 8, z)) << b;
        differ += want != packed.leafSliceMask(x, y, z);
      }
  EXPECT_EQ(differ, 0u);
}

INSTANTIATE_TEST_SUITE_P(Scenes, DagReference,
                         ::testing::Values(Case{6, false, UndefinedRule::New, 1}, Case{6, true, UndefinedRule::New, 2},
                                           Case{6, true, UndefinedRule::Old, 3}, Case{7, true, UndefinedRule::New, 4},
                                           Case{7, false, UndefinedRule::Old, 5}, Case{7, true, UndefinedRule::Old, 6}));

// The new rule wins where closed objects share their exit depth while their enter depths
// vary (sloped roofs standing on one ground) and something thin above them forces an early
// first transition (wires): from there it holds one mask down to the common exit, where
// the old rule follows every enter depth. It is a local heuristic,
// not a theorem: with random exits (syntheticSlices) either rule can be smaller, so the
// benchmark measures both on real scenes.
TEST(DagRules, NewRuleFollowsSharedExitsOldRuleFollowsEnters) {
  const uint32_t R = 128;
  TexelSlices d;
  d.firstUndefined.resize(R * R);
  d.firstShadowed.assign(R * R, R - 8);
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      d.firstUndefined[y * R + x] = (3 * x + 5 * y + (x * y) % 7) % (R - 16);
      if (x % 16 == 5) d.firstUndefined[y * R + x] = d.firstShadowed[y * R + x] = 2;  // thin open wires above the roofs
    }
  Dag fresh = buildTiled(d, 7, 7, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  Dag old = buildTiled(d, 7, 7, UndefinedRule::Old, true, CompressMode::TopDown, HashKind::Xxh3);
  EXPECT_EQ(countReferenceMismatches(fresh, d, R), 0u);
  EXPECT_EQ(countReferenceMismatches(old, d, R), 0u);
  EXPECT_LT(fresh.bytes() * 4, old.bytes()) << "new " << fresh.bytes() << " old " << old.bytes();
}

// Merging the same sub-DAGs in either argument order gives the same bytes.
TEST(DagMerge, IsSymmetric) {
  TexelSlices d = syntheticSlices(64, true, 7);
  Dag a = testing::buildTile(d, 6, 5, 0, 0, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  Dag b = testing::buildTile(d, 6, 5, 1, 1, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  expectSameDag(mergeDags(a, b), mergeDags(b, a));
  EXPECT_THROW(mergeDags(a, a), std::invalid_argument);
}

// A large merge cut into parts, each merged on its own core, gives the bytes of one sweep
// and of compressing the two DAGs laid end to end (the reference: compression alone), for
// parts of every size down to one node.
TEST(DagMerge, PartsOfAnySizeGiveTheOneSweepsBytes) {
  // Noisy ramps that repeat every 48 texels: many distinct nodes, many shared by the tiles.
  const uint32_t R = 128;
  TexelSlices d = syntheticSlices(R, false, 11);
  for (uint32_t y = 0; y < R; ++y)
    for (uint32_t x = 0; x < R; ++x) {
      const uint32_t px = x % 48, py = y % 48;
      const uint32_t z = (px + py / 2 + ((px * 73856093u) ^ (py * 19349663u)) % 11) % (R - 8);
      d.firstUndefined[y * R + x] = d.firstShadowed[y * R + x] = std::min(d.firstUndefined[y * R + x], z);
    }
  Dag a = testing::buildTile(d, 7, 6, 0, 0, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  Dag b = testing::buildTile(d, 7, 6, 1, 0, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  Dag c = testing::buildTile(d, 7, 6, 0, 1, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  const Dag ab = mergeDags(a, b, CompressMode::TopDown, SIZE_MAX);
  ASSERT_GT(ab.leaves.size(), 500u);
  ASSERT_LT(ab.leaves.size(), a.leaves.size() + b.leaves.size());  // some collapse
  Dag concatenated = mergeDags(a, b, CompressMode::None);
  computeHashes(concatenated, HashKind::Xxh3);
  expectSameDag(ab, compressDag(std::move(concatenated), CompressMode::TopDown));
  const Dag abc = mergeDags(ab, c, CompressMode::TopDown, SIZE_MAX);
  for (size_t part : {size_t(1), size_t(2), size_t(7), size_t(100), size_t(5000)}) {
    SCOPED_TRACE(part);
    expectSameDag(mergeDags(a, b, CompressMode::TopDown, part), ab);
    expectSameDag(mergeDags(c, ab, CompressMode::TopDown, part), abc);
  }
}

// The voxels of node `ref` of `level` (-1: a leaf, 8x8x1), x fastest; side^2 * depth.
std::vector<uint8_t> nodeVoxels(const Dag& dag, int level, NodeRef ref) {
  const uint32_t side = level < 0 ? 8 : 8u << level, depth = level < 0 ? 1 : side;
  std::vector<uint8_t> v(size_t(side) * side * depth);
  if (ref.code != kRef) {
    std::fill(v.begin(), v.end(), uint8_t(ref.code == kShadowed));
  } else if (level < 0) {
    for (uint32_t i = 0; i < 64; ++i) v[i] = uint8_t((dag.leaves[ref.index] >> i) & 1);
  } else {
    const uint32_t half = side / 2;
    for (int c = 0; c < kChildren; ++c) {
      const std::vector<uint8_t> child = nodeVoxels(dag, level - 1, dag.levels[size_t(level)].child(ref.index, c));
      // Level 0's children are its depth slices; above, octants of half the side.
      const uint32_t cs = level == 0 ? 8 : half, cd = level == 0 ? 1 : half;
      const uint32_t x0 = level == 0 ? 0 : (c & 1) * half, y0 = level == 0 ? 0 : (c >> 1 & 1) * half;
      const uint32_t z0 = level == 0 ? uint32_t(c) : (c >> 2 & 1) * half;
      for (uint32_t z = 0; z < cd; ++z)
        for (uint32_t y = 0; y < cs; ++y)
          for (uint32_t x = 0; x < cs; ++x)
            v[(size_t(z0 + z) * side + y0 + y) * side + x0 + x] = child[(size_t(z) * cs + y) * cs + x];
    }
  }
  return v;
}

// The voxels reflected and inverted as transform t says, voxel by voxel.
std::vector<uint8_t> transformVoxels(const std::vector<uint8_t>& v, uint32_t side, uint32_t depth, uint32_t t) {
  std::vector<uint8_t> out(v.size());
  for (uint32_t z = 0; z < depth; ++z)
    for (uint32_t y = 0; y < side; ++y)
      for (uint32_t x = 0; x < side; ++x) {
        const uint32_t sx = t & kReflectX ? side - 1 - x : x, sy = t & kReflectY ? side - 1 - y : y;
        const uint32_t sz = t & kReflectZ ? depth - 1 - z : z;
        out[(size_t(z) * side + y) * side + x] = uint8_t(v[(size_t(sz) * side + sy) * side + sx] ^ (t & kInvert ? 1 : 0));
      }
  return out;
}

// The census counts, per level, the classes that the voxels themselves fall into when
// subtrees equal under a reflection or inversion are one (the brute-force reference: every
// node expanded, transformed voxel by voxel, the least of its images kept).
TEST(DagSymmetry, CensusCountsTheClassesOfTheVoxels) {
  for (const uint32_t seed : {3u, 8u}) {
    TexelSlices d = syntheticSlices(64, seed == 8, seed);
    const Dag dag = buildTiled(d, 6, 6, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
    for (const uint32_t generators : {0u, uint32_t(kReflectX), uint32_t(kReflectX | kReflectY), uint32_t(kInvert),
                                      uint32_t(kReflectZ | kInvert), kAllSymmetries}) {
      SCOPED_TRACE(::testing::Message() << "seed " << seed << " generators " << generators);
      const SymmetryCensus census = symmetryCensus(dag, generators);
      ASSERT_EQ(census.classes.size(), dag.levels.size() + 1);
      EXPECT_EQ(census.plainBytes, dag.bytes());
      for (int level = -1; level < int(dag.levels.size()); ++level) {
        const size_t n = level < 0 ? dag.leaves.size() : dag.levels[size_t(level)].size();
        const uint32_t side = level < 0 ? 8 : 8u << level, depth = level < 0 ? 1 : side;
        std::set<std::vector<uint8_t>> classes;
        for (size_t i = 0; i < n; ++i) {
          const std::vector<uint8_t> v = nodeVoxels(dag, level, {kRef, uint32_t(i)});
          std::vector<uint8_t> least = v;
          for (uint32_t t = 1; t < 16; ++t)
            if ((t & ~generators) == 0) least = std::min(least, transformVoxels(v, side, depth, t));
          classes.insert(least);
        }
        EXPECT_EQ(census.nodes[size_t(level + 1)], n);
        EXPECT_EQ(census.classes[size_t(level + 1)], classes.size()) << "level " << level;
        if (generators == 0) {
          EXPECT_EQ(classes.size(), n);
        }
      }
      if (generators == 0) {
        EXPECT_EQ(census.symmetricBytes, dag.bytes());
      }
      if (generators == kAllSymmetries) {
        EXPECT_LT(census.classes[1], census.nodes[1]);  // the boxes mirror
      }
    }
  }
  // A leaf's transforms, bit by bit.
  const uint64_t m = 0x8000000000000001ull | (uint64_t{1} << (2 * 8 + 1));  // (0,0), (7,7), (1,2)
  EXPECT_EQ(transformLeaf(m, kReflectX), 0x0100000000000080ull | (uint64_t{1} << (2 * 8 + 6)));
  EXPECT_EQ(transformLeaf(m, kReflectY), 0x0100000000000080ull | (uint64_t{1} << (5 * 8 + 1)));
  EXPECT_EQ(transformLeaf(m, kReflectZ), m);
  EXPECT_EQ(transformLeaf(m, kInvert | kReflectX | kReflectY), ~(0x8000000000000001ull | (uint64_t{1} << (5 * 8 + 6))));
}

CpvsArtifact sampleArtifact() {
  TexelSlices d = syntheticSlices(64, true, 9);
  CpvsArtifact art;
  art.dag = buildTiled(d, 6, 6, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
  art.grid.frame = LightFrame::fromDirection({0.3, -1, 0.2});
  art.grid.log2Resolution = 6;
  art.grid.extent = 10;
  art.grid.depthExtent = 5;
  art.sceneHash = Hash128{1, 2};
  return art;
}

// Every depth of the pointer grid (none at 8^3, 1 to 5 levels above): the packed walk
// answers every voxel as the levels do, and the words read back through the validating
// reader as the same DAG, which repacks to the same words.
TEST(PackedDag, PointerGridOfEveryDepthAnswersAsTheLevels) {
  for (int log2R = 3; log2R <= 8; ++log2R) {
    const uint32_t R = 1u << log2R;
    TexelSlices d = syntheticSlices(R, log2R % 2 == 0, 40 + log2R);
    const Dag dag = buildTiled(d, log2R, log2R, UndefinedRule::New, true, CompressMode::TopDown, HashKind::Xxh3);
    const PackedDag packed(dag);
    EXPECT_EQ(int(packed.header().gridLevels), std::min(5, log2R - 3));
    EXPECT_EQ(packed.arrayBytes() % 8, 0u);
    uint64_t differ = 0;
    for (uint64_t z = 0; z < R; ++z)
      for (uint64_t y = 0; y < R; ++y)
        for (uint64_t x = 0; x < R; ++x) differ += dagVoxelShadowed(dag, x, y, z) != packed.voxelShadowed(x, y, z);
    EXPECT_EQ(differ, 0u) << "2^" << log2R;
    Dag back;
    const PackedDag again = PackedDag::fromWords(packed.words(), back);
    EXPECT_EQ(again.words(), packed.words());
    expectSameDag(dag, back);
  }
}

// A DAG of 256^3 whose nodes and 8x8 slices are nearly all different (seven of eight
// children a node of their own): more than 65,536 leaves and a level 0 of more than 65,536
// half-words, so levels 0 and 1 name their children by two half-words, at even and odd
// half-words alike, and the levels above by one.
Dag distinctNodesDag(uint64_t seed) {
  std::mt19937_64 rng(seed);
  Dag dag;
  dag.reset(8, 8);
  const int L = int(dag.levels.size());
  uint32_t nodes = 1;  // of the level being made; its children are made below in order
  for (int l = L - 1; l >= 0; --l) {
    uint32_t next = 0;
    for (uint32_t i = 0; i < nodes; ++i) {
      uint16_t codes = 0;
      uint32_t refs[8];
      int n = 0;
      for (int c = 0; c < 8; ++c) {
        const uint64_t r = rng() % 16;
        const uint32_t code = r == 0 ? kLit : r == 1 ? kShadowed : kRef;
        codes |= uint16_t(code << (2 * c));
        if (code == kRef) refs[n++] = next++;
      }
      dag.levels[size_t(l)].append(codes, refs);
    }
    nodes = next;
  }
  for (uint32_t i = 0; i < nodes; ++i) dag.leaves.push_back(rng());
  dag.roots.push_back({0, {kRef, 0}});
  return dag;
}

TEST(PackedDag, ReferencesOfOneAndTwoHalfWordsAnswerAsTheLevels) {
  const Dag dag = distinctNodesDag(17);
  ASSERT_GT(dag.leaves.size(), kMaxNarrowRefTargets);
  const PackedDag packed(dag);
  EXPECT_EQ(packed.header().wideRefs, 3u) << "levels 0 and 1 wide, the rest narrow";
  EXPECT_EQ(packed.bytes(), dag.bytes());
  // Levels 0 and 1: a code half-word and two per reference; above: one each.
  const std::vector<PackedLevelForm> forms = packedLevelForms(dag.levels, dag.leaves.size());
  for (size_t l = 0; l < dag.levels.size(); ++l) {
    const InternalLevel& level = dag.levels[l];
    EXPECT_EQ(dag.levelBytes(int(l)), 2 * (level.size() + (l < 2 ? 2 : 1) * level.children.size())) << l;
    EXPECT_EQ(forms[l].refHalves, l < 2 ? 2u : 1u);
  }
  EXPECT_LT(dag.bytes(), dag.bytes(1));
  const uint64_t R = 256;
  uint64_t differ = 0;
  for (uint64_t z = 0; z < R; ++z)
    for (uint64_t y = 0; y < R; ++y)
      for (uint64_t x = 0; x < R; ++x) differ += dagVoxelShadowed(dag, x, y, z) != packed.voxelShadowed(x, y, z);
  EXPECT_EQ(differ, 0u);
  // The words read back through the validating reader; layout 1 (a word each) too.
  for (uint32_t version : {1u, kPackedLayoutVersion}) {
    Dag back;
    const PackedDag again = PackedDag::fromWords(packPool(dag.leaves, dag.levels, {{8, dag.roots.front().ref}}, version), back);
    EXPECT_EQ(again.words(), packed.words()) << "layout " << version;
    for (size_t l = 0; l < dag.levels.size(); ++l) {
      EXPECT_EQ(back.levels[l].codes, dag.levels[l].codes);
      EXPECT_EQ(back.levels[l].children, dag.levels[l].children);
    }
    EXPECT_EQ(back.leaves, dag.leaves);
  }
  // A reference beyond what its level names, in a wide and in a narrow level, is refused.
  for (int l : {0, 1, 3}) {
    std::vector<uint32_t> words = packed.words();
    const PackedHeader& h = packed.header();
    ASSERT_NE(words[h.levelWord[l]] & 0xAAAA, 0u) << "the level's first node has a kRef child";
    if (l < 2)
      words[h.levelWord[l] + 1] |= 0x8000u;  // its first reference (half-words 1 and 2): beyond 2^31
    else
      words[h.levelWord[l]] |= 0xFFFF0000u;  // its first reference (half-word 1)
    Dag back;
    EXPECT_THROW(PackedDag::fromWords(words, back), InputError) << "level " << l;
  }
}

// A DAG whose root is a whole-lit or whole-shadowed code, and one that is not complete.
TEST(PackedDag, HomogeneousRootsAndIncompleteDags) {
  for (uint32_t code : {uint32_t(kLit), uint32_t(kShadowed)}) {
    Dag dag;
    dag.reset(6, 6);
    dag.roots.push_back({0, {code, 0}});
    const PackedDag packed(dag);
    EXPECT_EQ(packed.voxelShadowed(5, 63, 17), code == kShadowed);
    EXPECT_EQ(packed.leafSliceMask(0, 0, 0), code == kShadowed ? ~uint64_t{0} : 0);
  }
  Dag tile;
  tile.reset(8, 6);  // 2^6 roots of a 2^8 grid: a tile's sub-DAG
  EXPECT_THROW(PackedDag{tile}, InputError);
}

TEST(CpvsFile, RoundTripsWithAndWithoutZstd) {
  CpvsArtifact art = sampleArtifact();
  for (bool zstd : {false, true}) {
    auto bytes = encodeCpvs(art, zstd);
    CpvsArtifact back = decodeCpvs(bytes.data(), bytes.size(), "mem");
    expectSameDag(art.dag, back.dag);
    EXPECT_EQ(back.grid.log2Resolution, 6);
    EXPECT_EQ(back.grid.frame.dir, art.grid.frame.dir);
    EXPECT_EQ(back.sceneHash, art.sceneHash);
    EXPECT_EQ(encodeCpvs(back, zstd), bytes);
  }
}

// Every truncation and every single-byte corruption is an InputError, never a crash.
TEST(CpvsFile, RejectsTruncatedAndCorruptedFiles) {
  CpvsArtifact art = sampleArtifact();
  for (bool zstd : {false, true}) {
    auto bytes = encodeCpvs(art, zstd);
    for (size_t n = 0; n < bytes.size(); n += (n < 300 ? 1 : 97)) {
      EXPECT_THROW(decodeCpvs(bytes.data(), n, "cut.cpvs"), InputError) << "length " << n;
    }
    for (size_t i = 0; i < bytes.size(); i += (i < 300 ? 1 : 53)) {
      auto bad = bytes;
      bad[i] ^= 0x5A;
      EXPECT_THROW(decodeCpvs(bad.data(), bad.size(), "bad.cpvs"), InputError) << "byte " << i;
    }
  }
  std::vector<uint8_t> junk{'n', 'o', 'p', 'e'};
  try {
    decodeCpvs(junk.data(), junk.size(), "junk.bin");
    FAIL();
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("junk.bin"), std::string::npos);
  }
}

}  // namespace
}  // namespace cpvs
