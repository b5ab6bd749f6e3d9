// DAG-MH against brute force: every texel's depth inside its interval (seed 001's
// "lossless"), the structure's value index against the plain MH, chunks against their
// intervals, merged shapes unique, corrupt structures refused.
#include <gtest/gtest.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <tuple>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstring>
#include <random>
#include <set>

#include "cpvs/base/error.h"
#include "cpvs/dagmh/dag_mh.h"
#include "cpvs/io/dmh_tile_file.h"

namespace cpvs {
namespace {

// A dual-depth map like a scene's seen from the sun: boxes of constant depth on a sloped
// ground, a gap to the next surface that is zero (open geometry), small or large, and
// texels nothing covers.
TexelIntervals sceneLikeIntervals(uint32_t side, uint64_t seed) {
  std::mt19937_64 rng(seed);
  TexelIntervals t;
  t.side = side;
  t.lo.resize(t.texels());
  t.hi.resize(t.texels());
  const float R = float(side);
  for (uint32_t y = 0; y < side; ++y)
    for (uint32_t x = 0; x < side; ++x) {
      const size_t i = size_t(y) * side + x;
      t.lo[i] = 0.7f * R + 0.05f * float(x) + 0.02f * float(y);  // the ground
      t.hi[i] = t.lo[i];
    }
  std::uniform_int_distribution<uint32_t> pos(0, side - 1);
  std::uniform_real_distribution<float> unit(0, 1);
  const int boxes = int(side / 2 + 3);
  for (int b = 0; b < boxes; ++b) {
    const uint32_t x0 = pos(rng), y0 = pos(rng);
    const uint32_t w = 1 + pos(rng) / 4, h = 1 + pos(rng) / 4;
    const float top = unit(rng) * 0.6f * R;
    const float gap = unit(rng) < 0.3f ? 0.0f : unit(rng) * 0.2f * R;
    for (uint32_t y = y0; y < std::min(side, y0 + h); ++y)
      for (uint32_t x = x0; x < std::min(side, x0 + w); ++x) {
        const size_t i = size_t(y) * side + x;
        if (top < t.lo[i]) {
          t.hi[i] = std::min(t.lo[i], top + gap);
          t.lo[i] = top;
        }
      }
  }
  for (int hole = 0; hole < 3; ++hole) {
    const uint32_t x0 = pos(rng), y0 = pos(rng);
    for (uint32_t y = y0; y < std::min(side, y0 + side / 8 + 1); ++y)
      for (uint32_t x = x0; x < std::min(side, x0 + side / 8 + 1); ++x) {
        t.lo[size_t(y) * side + x] = R;
        t.hi[size_t(y) * side + x] = kNoCasterDepth;
      }
  }
  return t;
}

// Intervals with no structure at all: the worst case for merging.
TexelIntervals randomIntervals(uint32_t side, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<float> depth(0, float(side)), width(0, 4);
  TexelIntervals t;
  t.side = side;
  for (size_t i = 0; i < t.texels(); ++i) {
    const float a = depth(rng);
    t.lo.push_back(a);
    t.hi.push_back(rng() % 4 == 0 ? a : a + width(rng));
  }
  return t;
}

void expectLossless(const TexelIntervals& texels) {
  SCOPED_TRACE("side " + std::to_string(texels.side));
  const Mh mh(texels);
  const DagMh dag = encodeDagMh(mh);
  ASSERT_NO_THROW(validateDagMh(dag, "test"));
  std::vector<float> lo, hi;
  mhValueIntervals(mh, lo, hi);
  ASSERT_EQ(lo.size(), dag.values.count);
  uint64_t wrong = 0;
  for (uint32_t y = 0; y < texels.side; ++y)
    for (uint32_t x = 0; x < texels.side; ++x) {
      const size_t i = size_t(y) * texels.side + x;
      const float a = texels.lo[i], b = texels.hi[i];
      // The plain MH is lossless, the DAG finds the same node, its stored value is in
      // the node's interval and so in the texel's.
      const float m = mh.lookup(x, y);
      const uint32_t index = dag.valueIndex(x, y);
      const float z = dag.depth(x, y);
      if (!(a <= m && m <= b) || index >= lo.size() || 0.5f * lo[index] + 0.5f * hi[index] != m || !(a <= z && z <= b))
        if (++wrong < 5)
          ADD_FAILURE() << "texel " << x << "," << y << " [" << a << ", " << b << "]: MH " << m << ", DAG-MH " << z
                        << " (value " << index << ")";
    }
  EXPECT_EQ(wrong, 0u);
}

TEST(ValueChunks, EveryDecodedValueLiesInItsInterval) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<float> depth(0, 4096);
  for (const size_t count : {size_t(0), size_t(1), size_t(31), size_t(32), size_t(33), size_t(5000)}) {
    std::vector<float> lo, hi;
    for (size_t k = 0; k < count; ++k) {
      const float a = depth(rng);
      const int kind = int(rng() % 5);
      lo.push_back(a);
      hi.push_back(kind == 0 ? a : kind == 1 ? std::nextafter(a, 1e9f) : kind == 2 ? kNoCasterDepth : a + float(rng() % 100));
    }
    const ValueChunks v = encodeValueChunks(lo.data(), hi.data(), count);
    ASSERT_EQ(v.count, count);
    ASSERT_EQ(v.chunks.size(), (count + 31) / 32);
    for (size_t k = 0; k < count; ++k) {
      const float z = v.value(k);
      ASSERT_TRUE(lo[k] <= z && z <= hi[k]) << "value " << k << " " << z << " outside [" << lo[k] << ", " << hi[k] << "]";
    }
    const ValueChunks again = encodeValueChunks(lo.data(), hi.data(), count);
    EXPECT_EQ(again.factors, v.factors);
    if (!v.chunks.empty()) {
      EXPECT_EQ(std::memcmp(again.chunks.data(), v.chunks.data(), v.chunks.size() * sizeof(ValueChunk)), 0);
    }
  }
}

TEST(ValueChunks, AChunkThatOneDepthSuitsStoresNoFactor) {
  std::vector<float> lo(32), hi(32);
  for (int k = 0; k < 32; ++k) {
    lo[size_t(k)] = float(k);
    hi[size_t(k)] = 100.0f;
  }
  const ValueChunks v = encodeValueChunks(lo.data(), hi.data(), 32);
  EXPECT_EQ(v.chunks[0].bitmap, 0u);
  EXPECT_EQ(v.chunks[0].factorBits(), 1u);
  EXPECT_EQ(v.factors.size(), kFactorStreamPadding);
  for (int k = 0; k < 32; ++k) EXPECT_TRUE(v.value(size_t(k)) >= 31.0f);
}

TEST(ValueChunks, FactorsOnAGridUseFewBits) {
  // Two clusters no single depth suits: the second is a grid of width-2 intervals.
  std::vector<float> lo, hi;
  for (int k = 0; k < 20; ++k) {
    lo.push_back(1000);
    hi.push_back(1001);
  }
  for (int k = 0; k < 12; ++k) {
    lo.push_back(float(10 * k));
    hi.push_back(float(10 * k + 2));
  }
  const ValueChunks v = encodeValueChunks(lo.data(), hi.data(), 32);
  EXPECT_EQ(std::popcount(v.chunks[0].bitmap), 12);
  EXPECT_LE(v.chunks[0].factorBits(), 6u);
  for (size_t k = 0; k < 32; ++k) EXPECT_TRUE(lo[k] <= v.value(k) && v.value(k) <= hi[k]);
}

TEST(ValueChunks, BadIntervalsAreRefused) {
  const float lo[2] = {1, NAN}, hi[2] = {0, 1};
  EXPECT_THROW(encodeValueChunks(lo, hi, 1), InputError);
  EXPECT_THROW(encodeValueChunks(lo + 1, hi + 1, 1), InputError);
}

TEST(Mh, EveryTexelFindsADepthInItsIntervalExhaustively) {
  for (uint32_t side = 1; side <= 512; side *= 2) {
    expectLossless(sceneLikeIntervals(side, side));
    if (side <= 128) expectLossless(randomIntervals(side, side + 1));
  }
}

TEST(Mh, AMapOfFourKTexelsIsLosslessEverywhere) { expectLossless(sceneLikeIntervals(4096, 11)); }

// Beyond 4K: a 16K map of scene-like intervals (a sloped ground, boxes on a grid of cells
// with gaps of none, a little or much, empty cells), built tile by tile as a bake builds
// it, and 10^7 random texels, each decoded inside its interval.
TEST(DagMh, TenMillionRandomTexelsOfASixteenKMapLieInTheirIntervals) {
  constexpr uint32_t kSide = 16384, kTile = 1024;
  auto interval = [](uint32_t x, uint32_t y) {
    const float ground = 0.7f * float(kSide) + float((x >> 3) % 512) + 0.5f * float((y >> 3) % 512);
    const uint64_t cell = (uint64_t(y >> 5) << 20 | (x >> 5)) * 0x9E3779B97F4A7C15ull;
    const uint32_t kind = uint32_t(cell >> 60);
    if (kind == 0) return std::pair<float, float>{float(kSide), kNoCasterDepth};  // nothing here
    if (kind < 6) return std::pair<float, float>{ground, ground + float(kind - 1)};
    const float top = float((cell >> 20) % (kSide / 2));
    const float gap = kind < 9 ? 0.0f : kind < 13 ? float((cell >> 8) % 8) : float((cell >> 8) % 2000);
    return std::pair<float, float>{top, std::min(ground, top + gap)};
  };
  DagMhBuilder builder(std::countr_zero(kSide), std::countr_zero(kTile));
  TexelIntervals tile;
  tile.side = kTile;
  tile.lo.resize(tile.texels());
  tile.hi.resize(tile.texels());
  Mh mh;
  for (uint32_t ty = 0; ty < kSide / kTile; ++ty)
    for (uint32_t tx = 0; tx < kSide / kTile; ++tx) {
      for (uint32_t y = 0; y < kTile; ++y)
        for (uint32_t x = 0; x < kTile; ++x)
          std::tie(tile.lo[size_t(y) * kTile + x], tile.hi[size_t(y) * kTile + x]) = interval(tx * kTile + x, ty * kTile + y);
      mh.rebuild(tile);
      builder.addTile(tx, ty, mh);
    }
  const DagMh dag = builder.finish();
  ASSERT_NO_THROW(validateDagMh(dag, "16K"));
  std::atomic<uint64_t> wrong{0};
  tbb::parallel_for(tbb::blocked_range<uint32_t>(0, 1000), [&](const auto& chunks) {
    for (uint32_t chunk = chunks.begin(); chunk != chunks.end(); ++chunk) {
      std::mt19937_64 rng(chunk);
      for (int i = 0; i < 10000; ++i) {
        const uint32_t x = uint32_t(rng() % kSide), y = uint32_t(rng() % kSide);
        const auto [a, b] = interval(x, y);
        const float z = dag.depth(x, y);
        if (!(a <= z && z <= b) && wrong++ < 5)
          ADD_FAILURE() << "texel " << x << "," << y << " [" << a << ", " << b << "]: " << z;
      }
    }
  });
  EXPECT_EQ(wrong.load(), 0u);
  EXPECT_GT(dag.values.count, 100000u);
}

TEST(Mh, TheRuleOfTheFourChildren) {
  // Two of four children share a depth range, two others another: the node covers the
  // lower ends' best (ties: the lowest child) and the others are full.
  TexelIntervals t;
  t.side = 2;
  t.lo = {0, 5, 0.5f, 5.5f};
  t.hi = {1, 6, 1.5f, 7};
  const Mh mh(t);
  EXPECT_EQ(mh.covered(0, 0, 0), 0b0101);
  EXPECT_FLOAT_EQ(mh.lo(0, 0, 0), 0.5f);
  EXPECT_FLOAT_EQ(mh.hi(0, 0, 0), 1.0f);
  EXPECT_EQ(mh.state(1, 1, 0), MhState::Full);
  EXPECT_EQ(mh.state(1, 0, 0), MhState::Absent);
  EXPECT_FLOAT_EQ(mh.lookup(0, 0), 0.75f);
  EXPECT_FLOAT_EQ(mh.lookup(1, 1), 6.25f);
  t.lo = {0, 0, 0, NAN};
  EXPECT_THROW(Mh{t}, InputError);
}

TEST(DagMh, TreeletBitsArePreorder) {
  EXPECT_EQ(treeletBit(0, 3, 3, 3), 0u);
  EXPECT_EQ(treeletBit(1, 2, 3, 3), 1u + 21 * 2);
  EXPECT_EQ(treeletBit(2, 1, 3, 0), 2u + 21 + 15);
  EXPECT_EQ(treeletBit(3, 3, 3, 3), 84u);
}

TEST(DagMh, EqualShapesAreStoredOnce) {
  const TexelIntervals texels = sceneLikeIntervals(1024, 5);
  const DagMh dag = encodeDagMh(Mh(texels));
  std::set<std::vector<uint32_t>> treelets, nodes;
  for (size_t i = 0; i < dag.treelets.size(); i += kTreeletWords)
    EXPECT_TRUE(treelets.insert({dag.treelets.begin() + long(i), dag.treelets.begin() + long(i + kTreeletWords)}).second);
  // Nodes by content, pointers included: the layout makes equal children equal pointers.
  // The node with no child (a value its whole subtree inherits) is merged within a level,
  // not across: pointers lead from a level to the next.
  std::vector<uint32_t> node;
  uint64_t childless = 0;
  for (size_t at = 0; at < dag.nodes.size();) {
    uint32_t present = 0;
    for (int c = 0; c < 4; ++c) present += ((dag.nodes[at] >> (2 * c)) & 3) != kDagMhAbsent;
    const size_t size = present == 0 ? 2 : 2 * present + 1;
    if (present == 0)
      ++childless;
    else
      EXPECT_TRUE(nodes.insert({dag.nodes.begin() + long(at), dag.nodes.begin() + long(at + size)}).second) << "node " << at;
    at += size;
  }
  EXPECT_LE(childless, 10u - 3u);  // one per inner level at most
  EXPECT_EQ(nodes.size() + childless, dag.innerNodeCount());
  EXPECT_GT(dag.innerNodeCount(), 0u);
  EXPECT_EQ(dag.skipLevel, 3);
  // Merging pays: fewer treelets than the 128^2 places they stand.
  EXPECT_LT(dag.treeletCount(), 128u * 128u / 2);
}

TEST(DagMh, TheSameIntervalsGiveTheSameBytes) {
  const TexelIntervals texels = sceneLikeIntervals(256, 9);
  const DagMh a = encodeDagMh(Mh(texels)), b = encodeDagMh(Mh(texels));
  EXPECT_EQ(a.nodes, b.nodes);
  EXPECT_EQ(a.treelets, b.treelets);
  EXPECT_EQ(a.values.factors, b.values.factors);
}

TEST(DagMh, ARectangleReadsAsItsTexels) {
  std::mt19937_64 rng(8);
  for (const uint32_t side : {8u, 64u, 1024u}) {
    const DagMh dag = encodeDagMh(Mh(sceneLikeIntervals(side, side + 7)));
    for (int trial = 0; trial < 2000; ++trial) {
      const uint32_t w = 1 + uint32_t(rng() % std::min(side, 9u)), h = 1 + uint32_t(rng() % std::min(side, 9u));
      const uint64_t x0 = rng() % (side - w + 1), y0 = rng() % (side - h + 1);
      float got[81];
      dag.depths(x0, y0, w, h, got);
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x)
          ASSERT_EQ(got[y * w + x], dag.depth(x0 + x, y0 + y)) << side << ": " << x0 + x << "," << y0 + y;
    }
  }
}

// The texels of one tile, as a map of its own.
TexelIntervals tileOf(const TexelIntervals& map, uint32_t tileSide, uint32_t tx, uint32_t ty) {
  TexelIntervals t;
  t.side = tileSide;
  for (uint32_t y = 0; y < tileSide; ++y)
    for (uint32_t x = 0; x < tileSide; ++x) {
      const size_t i = size_t(ty * tileSide + y) * map.side + tx * tileSide + x;
      t.lo.push_back(map.lo[i]);
      t.hi.push_back(map.hi[i]);
    }
  return t;
}

TEST(DagMh, TilesInAnyOrderGiveTheWholeMapsBytes) {
  std::mt19937_64 rng(21);
  for (const uint32_t side : {64u, 256u, 1024u}) {
    const TexelIntervals map = side == 256 ? randomIntervals(side, 4) : sceneLikeIntervals(side, side);
    const DagMh whole = encodeDagMh(Mh(map));
    for (const uint32_t tileSide : {16u, 64u, 256u}) {
      if (tileSide >= side) continue;
      SCOPED_TRACE("side " + std::to_string(side) + ", tiles of " + std::to_string(tileSide));
      const uint32_t n = side / tileSide;
      std::vector<uint32_t> order(n * n);
      for (uint32_t i = 0; i < n * n; ++i) order[i] = i;
      std::shuffle(order.begin(), order.end(), rng);
      DagMhBuilder builder(std::countr_zero(side), std::countr_zero(tileSide));
      for (const uint32_t i : order) builder.addTile(i % n, i / n, Mh(tileOf(map, tileSide, i % n, i / n)));
      const DagMh tiled = builder.finish();
      EXPECT_EQ(tiled.nodes, whole.nodes);
      EXPECT_EQ(tiled.treelets, whole.treelets);
      EXPECT_EQ(tiled.values.count, whole.values.count);
      EXPECT_EQ(tiled.values.factors, whole.values.factors);
      EXPECT_EQ(std::memcmp(tiled.values.chunks.data(), whole.values.chunks.data(), whole.values.chunks.size() * 20), 0);
      EXPECT_EQ(tiled.skip.size(), whole.skip.size());
      EXPECT_NO_THROW(validateDagMh(tiled, "tiled"));
    }
  }
  DagMhBuilder missing(6, 4);
  EXPECT_THROW(missing.finish(), InputError);
  EXPECT_THROW(DagMhBuilder(10, 3), InputError);
}

// A tile's part sent as bytes (what a farm worker sends) and merged at the other end in
// any order: the whole map's bytes.
TEST(DagMh, TilePartsTravelAndKeepTheBytes) {
  std::mt19937_64 rng(23);
  for (const uint32_t side : {8u, 256u, 1024u}) {
    const TexelIntervals map = side == 256 ? randomIntervals(side, 4) : sceneLikeIntervals(side, side);
    const DagMh whole = encodeDagMh(Mh(map));
    const uint32_t tileSide = side == 8 ? 8 : side / 4, n = side / tileSide;
    std::vector<DagMhTile> parts;
    for (uint32_t i = 0; i < n * n; ++i)
      parts.push_back(dagMhTile(std::countr_zero(side), i % n, i / n, Mh(tileOf(map, tileSide, i % n, i / n))));
    std::shuffle(parts.begin(), parts.end(), rng);
    for (const bool zstd : {false, true}) {
      const std::vector<uint8_t> bytes = encodeDagMhTiles(parts, zstd);
      std::vector<DagMhTile> back = decodeDagMhTiles(bytes.data(), bytes.size(), "parts");
      ASSERT_EQ(back.size(), parts.size());
      DagMhBuilder builder(std::countr_zero(side), std::countr_zero(tileSide));
      for (DagMhTile& p : back) builder.addTile(std::move(p));
      EXPECT_THROW(builder.addTile(dagMhTile(std::countr_zero(side), 0, 0, Mh(tileOf(map, tileSide, 0, 0)))), InputError)
          << "a tile twice";
      const DagMh tiled = builder.finish();
      EXPECT_EQ(tiled.nodes, whole.nodes);
      EXPECT_EQ(tiled.treelets, whole.treelets);
      EXPECT_EQ(tiled.values.factors, whole.values.factors);
      EXPECT_EQ(std::memcmp(tiled.values.chunks.data(), whole.values.chunks.data(), whole.values.chunks.size() * 20), 0);
    }
  }
}

// What a hostile or broken worker could send behind a valid checksum: refused by name
// before the builder trusts it, or (random words) refused or merged without harm.
TEST(DagMh, HostilePartsAreRefused) {
  const TexelIntervals map = randomIntervals(256, 4);
  const DagMhTile good = dagMhTile(8, 1, 2, Mh(tileOf(map, 64, 1, 2)));
  ASSERT_NO_THROW(validateDagMhTile(good, "good"));
  ASSERT_EQ(good.innerLevels(), 3);
  ASSERT_GT(good.valuesBelow, 10u);
  auto refused = [](const DagMhTile& t, const std::string& words) {
    try {
      validateDagMhTile(t, "part");
      return ::testing::AssertionFailure() << "accepted";
    } catch (const FormatError& e) {
      if (std::string(e.what()).find(words) == std::string::npos) return ::testing::AssertionFailure() << e.what();
      return ::testing::AssertionSuccess();
    }
  };
  DagMhTile t = good;
  t.tileX = 4;
  EXPECT_TRUE(refused(t, "outside the map"));
  t = good;
  t.levels.pop_back();
  EXPECT_TRUE(refused(t, "inner levels"));
  t = good;
  t.levels[2][2] = uint32_t(t.treelets.size());  // the first node's first child: no such treelet
  EXPECT_TRUE(refused(t, "not there"));
  t = good;
  t.levels[1][1] += 1;
  EXPECT_TRUE(refused(t, "value count"));
  t = good;
  t.treelets[2] |= 1u << 30;
  EXPECT_TRUE(refused(t, "padding"));
  t = good;
  t.root = 1000000;
  EXPECT_TRUE(refused(t, "root"));
  t = good;
  t.valueLo.pop_back();
  EXPECT_TRUE(refused(t, "value intervals"));
  t = good;
  t.valueHi[3] = std::nanf("");
  EXPECT_TRUE(refused(t, "interval"));
  t = good;
  t.valueLo[4] = t.valueHi[4] + 1;
  EXPECT_TRUE(refused(t, "interval"));
  t = good;
  t.log2TileSide = 3;
  EXPECT_TRUE(refused(t, "too small"));
  t = good;
  std::fill(t.treelets.end() - 3, t.treelets.end(), 0u);
  EXPECT_TRUE(refused(t, "stores nothing"));
  // A part that passed: merged with the map's other tiles into a DAG-MH that validates.
  auto expectMergesWithTheRest = [&](DagMhTile&& part) {
    DagMhBuilder builder(8, 6);
    builder.addTile(std::move(part));
    for (uint32_t i = 0; i < 16; ++i)
      if (!builder.hasTile(i % 4, i / 4)) builder.addTile(i % 4, i / 4, Mh(tileOf(map, 64, i % 4, i / 4)));
    EXPECT_NO_THROW(validateDagMh(builder.finish(), "merged"));
  };
  // Random words: refused, or merged and finished into a DAG-MH that validates.
  std::mt19937_64 rng(29);
  int refusals = 0;
  for (int trial = 0; trial < 400; ++trial) {
    t = good;
    std::vector<uint32_t>& words = trial % 2 ? t.treelets : t.levels[size_t(rng() % 3)];
    words[rng() % words.size()] ^= 1u << (rng() % 32);
    try {
      validateDagMhTile(t, "part");
    } catch (const FormatError&) {
      ++refusals;
      continue;
    }
    expectMergesWithTheRest(std::move(t));
  }
  EXPECT_GT(refusals, 100);
  // A pointer to another treelet of as many values: a valid part of another shape, merged
  // without harm.
  t = good;
  auto count = [&](uint32_t i) { return std::popcount(t.treelets[3 * i]) + std::popcount(t.treelets[3 * i + 1]) + std::popcount(t.treelets[3 * i + 2]); };
  bool swapped = false;
  for (uint32_t q = 1; q < t.treelets.size() / 3 && !swapped; ++q)
    if (count(q) == count(t.levels[2][2]) && q != t.levels[2][2]) {
      t.levels[2][2] = q;
      swapped = true;
    }
  ASSERT_TRUE(swapped);
  ASSERT_NO_THROW(validateDagMhTile(t, "part"));
  expectMergesWithTheRest(std::move(t));
  // A reader that knows what to expect refuses other sides or counts before it reads a
  // section; no reader decompresses more words than a part's geometry holds.
  const std::vector<uint8_t> one = encodeDagMhTiles({good});
  DagMhTileShape shape{8, 6, 1};
  EXPECT_EQ(decodeDagMhTiles(one.data(), one.size(), "parts", &shape).size(), 1u);
  for (const DagMhTileShape other : {DagMhTileShape{9, 6, 1}, DagMhTileShape{8, 5, 1}, DagMhTileShape{8, 6, 4}})
    EXPECT_THROW(decodeDagMhTiles(one.data(), one.size(), "parts", &other), FormatError);
  DagMhTile padded = good;
  padded.levels[0].resize(10, 0);  // more words than a level of one node can hold
  const std::vector<uint8_t> big = encodeDagMhTiles({padded});
  try {
    decodeDagMhTiles(big.data(), big.size(), "parts");
    ADD_FAILURE() << "accepted";
  } catch (const FormatError& e) {
    EXPECT_NE(std::string(e.what()).find("word count 10 is invalid"), std::string::npos) << e.what();
  }
  // Damaged bytes: the checksum, a truncation.
  std::vector<uint8_t> bytes = encodeDagMhTiles({good});
  bytes[bytes.size() / 2] ^= 4;
  EXPECT_THROW(decodeDagMhTiles(bytes.data(), bytes.size(), "parts"), FormatError);
  bytes = encodeDagMhTiles({good});
  EXPECT_THROW(decodeDagMhTiles(bytes.data(), bytes.size() - 9, "parts"), FormatError);
}

TEST(DagMh, CorruptWordsAreRefusedOrStayInBounds) {
  const TexelIntervals texels = sceneLikeIntervals(1024, 3);
  const DagMh good = encodeDagMh(Mh(texels));
  ASSERT_FALSE(good.skip.empty());
  std::mt19937_64 rng(13);
  int refused = 0;
  for (int trial = 0; trial < 600; ++trial) {
    DagMh bad = good;
    const int part = trial % 4;
    std::vector<uint32_t>& words = part == 0 ? bad.nodes : part == 1 ? bad.treelets : bad.nodes;
    if (part == 2) {
      bad.values.chunks[rng() % bad.values.chunks.size()].meta ^= uint32_t(1) << (rng() % 32);
    } else if (part == 3) {
      bad.skip[rng() % bad.skip.size()].typePtr ^= uint32_t(1) << (rng() % 32);
    } else {
      words[rng() % words.size()] ^= uint32_t(1) << (rng() % 32);
    }
    try {
      validateDagMh(bad, "bad");
    } catch (const FormatError& e) {
      EXPECT_NE(std::string(e.what()).find("bad: invalid DAG-MH"), std::string::npos);
      ++refused;
      continue;
    }
    // Accepted: a change lookups may read (a treelet bit, a count they skip), never out
    // of bounds (the sanitizer run checks).
    for (uint32_t y = 0; y < 1024; y += 7)
      for (uint32_t x = 0; x < 1024; x += 7) (void)bad.depth(x, y);
  }
  EXPECT_GT(refused, 300);
}

}  // namespace
}  // namespace cpvs
