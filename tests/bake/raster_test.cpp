// The rasterizer against its references: the double-precision brute force (every ray
// against every triangle) on every texel it does not mark ambiguous, the Embree renderer,
// the exact one-texel coverage test, and its own fused masks against the unfused path.
#include <gtest/gtest.h>
#include <hwy/targets.h>

#include <algorithm>
#include <random>

#include "cpvs/bake/column_masks.h"
#include "cpvs/bake/raster_scene.h"
#include "cpvs/bake/raster_slices.h"
#include "cpvs/bake/texel_slices.h"
#include "cpvs/scene/boxes.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

using testing::bruteForceDepths;

struct Case {
  std::string name;
  std::string relative;  // under shared/scenes, or a generator ("city:4:7")
  Vec3 sun;
};

Scene openCase(const Case& c) {
  if (c.relative.find(':') != std::string::npos) return openScene(c.relative);
  return openScene(testing::sharedScenesDir() + "/" + c.relative);
}

struct Comparison {
  uint64_t mismatches = 0, ambiguous = 0, hit = 0, interior = 0;
};

// Compares rasterized slices with the brute force over the whole grid.
Comparison compareWithBruteForce(const Scene& scene, const OrthoGrid& grid, ClosedMode closed, ExitMode exit,
                                 const std::string& what) {
  RasterScene raster(scene, grid);
  const uint64_t R = grid.resolution();
  TexelSlices got, want;
  std::vector<uint8_t> ambiguous;
  rasterTexelSlices(raster, closed, exit, 0, 0, uint32_t(R), uint32_t(R), got);
  bruteForceDepths(scene, grid, closed, exit, want, ambiguous);
  Comparison c;
  for (uint64_t i = 0; i < R * R; ++i) {
    c.hit += want.firstUndefined[i] < R;
    c.interior += want.firstShadowed[i] > want.firstUndefined[i];
    if (ambiguous[i]) {
      ++c.ambiguous;
      continue;
    }
    if (got.firstUndefined[i] != want.firstUndefined[i] || got.firstShadowed[i] != want.firstShadowed[i]) {
      if (++c.mismatches <= 5)
        ADD_FAILURE() << what << " texel " << i % R << "," << i / R << ": raster " << got.firstUndefined[i] << "/"
                      << got.firstShadowed[i] << ", brute force " << want.firstUndefined[i] << "/"
                      << want.firstShadowed[i];
    }
  }
  return c;
}

class RasterScenes : public ::testing::TestWithParam<Case> {
 protected:
  void SetUp() override {
    if (GetParam().relative.find(':') == std::string::npos && testing::sharedScenesDir().empty())
      GTEST_SKIP() << "shared/scenes is not beside the project: skipping " << GetParam().relative;
    scene_ = openCase(GetParam());
  }
  Scene scene_;
};

TEST_P(RasterScenes, MatchesBruteForceOnEveryUnambiguousTexel) {
  for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
    const OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 6);
    const Comparison c = compareWithBruteForce(scene_, grid, ClosedMode::Auto, exit, optionName(exit));
    EXPECT_EQ(c.mismatches, 0u);
    EXPECT_LT(c.ambiguous, 64u * 64u / 50u);
    EXPECT_GT(c.hit, 64u * 64u / 10u);
  }
}

// Raster and Embree agree at a resolution the brute force can't cover whole, except on
// texels where float rays and exact coverage may legitimately differ: every texel where
// they differ is one the brute force marks ambiguous (a ray within a hair of an edge or
// a slice boundary), or one where the rasterizer equals the brute force.
TEST_P(RasterScenes, DiffersFromTheRayTracerOnlyWhereTheOracleIsAmbiguous) {
  const OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 9);
  RasterScene raster(scene_, grid);
  RayScene rays(scene_, grid.origin);
  const uint64_t R = grid.resolution();
  for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
    TexelSlices a, b;
    rasterTexelSlices(raster, ClosedMode::Auto, exit, 0, 0, uint32_t(R), uint32_t(R), a);
    renderTexelSlices(rays, grid, ClosedMode::Auto, exit, 0, 0, uint32_t(R), uint32_t(R), b);
    uint64_t differ = 0, hit = 0, rasterWrong = 0;
    for (uint64_t i = 0; i < R * R; ++i) {
      hit += b.firstUndefined[i] < R;
      if (a.firstUndefined[i] == b.firstUndefined[i] && a.firstShadowed[i] == b.firstShadowed[i]) continue;
      ++differ;
      uint32_t lo = 0, hi = 0;
      bool ambiguous = false;
      testing::bruteForceTexel(scene_, grid, ClosedMode::Auto, exit, i % R, i / R, lo, hi, ambiguous);
      if (!ambiguous && (lo != a.firstUndefined[i] || hi != a.firstShadowed[i])) {
        if (++rasterWrong <= 5)
          ADD_FAILURE() << optionName(exit) << " texel " << i % R << "," << i / R << ": raster " << a.firstUndefined[i]
                        << "/" << a.firstShadowed[i] << ", embree " << b.firstUndefined[i] << "/" << b.firstShadowed[i]
                        << ", brute force " << lo << "/" << hi;
      }
    }
    EXPECT_GT(hit, R * R / 10);
    EXPECT_EQ(rasterWrong, 0u);
    EXPECT_LE(differ, R * R / 1000) << optionName(exit) << ": " << differ << " of " << R * R << " texels differ";
  }
}

// The fused path (masks built per block) gives the masks of the unfused one, on tiles
// that cut through bins.
TEST_P(RasterScenes, FusedMasksEqualMasksOfSlices) {
  const OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 8);
  RasterScene raster(scene_, grid);
  for (UndefinedRule rule : {UndefinedRule::New, UndefinedRule::Old})
    for (auto [x0, y0, w, h] : {std::array<uint32_t, 4>{0, 0, 256, 256}, {72, 16, 120, 200}}) {
      TexelSlices slices;
      rasterTexelSlices(raster, ClosedMode::Auto, ExitMode::Exact, x0, y0, w, h, slices);
      ColumnMasks want, got;
      buildColumnMasks(slices, w, h, uint32_t(grid.resolution()), rule, want);
      rasterColumnMasks(raster, ClosedMode::Auto, ExitMode::Exact, rule, x0, y0, w, h, got);
      EXPECT_EQ(got.begin, want.begin);
      EXPECT_EQ(got.slice, want.slice);
      EXPECT_EQ(got.mask, want.mask);
      EXPECT_EQ(got.firstShadow, want.firstShadow);
      EXPECT_EQ(got.fullShadow, want.fullShadow);
      EXPECT_FALSE(want.slice.empty());
    }
}

// A texel's result does not depend on the tile that rendered it.
TEST_P(RasterScenes, TilesAgreeWithTheWholeGrid) {
  const OrthoGrid grid = makeGrid(scene_, LightFrame::fromDirection(GetParam().sun), 8);
  RasterScene raster(scene_, grid);
  TexelSlices whole, part;
  rasterTexelSlices(raster, ClosedMode::Auto, ExitMode::Exact, 0, 0, 256, 256, whole);
  for (uint32_t y0 = 0; y0 < 256; y0 += 96)
    for (uint32_t x0 = 0; x0 < 256; x0 += 56) {
      const uint32_t w = std::min(56u, 256 - x0), h = std::min(96u, 256 - y0);
      rasterTexelSlices(raster, ClosedMode::Auto, ExitMode::Exact, x0, y0, w, h, part);
      for (uint32_t y = 0; y < h; ++y)
        for (uint32_t x = 0; x < w; ++x) {
          ASSERT_EQ(part.firstUndefined[y * w + x], whole.firstUndefined[(y0 + y) * 256 + x0 + x]);
          ASSERT_EQ(part.firstShadowed[y * w + x], whole.firstShadowed[(y0 + y) * 256 + x0 + x]);
        }
    }
}

INSTANTIATE_TEST_SUITE_P(
    Scenes, RasterScenes,
    ::testing::Values(Case{"city", "city:4:7", {0.35, -1, 0.25}}, Case{"city_straight_down", "city:4:7", {0, -1, 0}},
                      Case{"bunny", "stanford-bunny/bunny.obj", {0.3, -0.8, -0.5}},
                      Case{"duck", "assimp-testmodels/duck.dae", {-1, -0.4, 0.2}},
                      Case{"teapots_open", "assimp-testmodels/teapots.DAE", {0.2, -1, 0.6}},
                      Case{"spider_mixed", "assimp-testmodels/spider.obj", {0.5, -1, 0.1}},
                      Case{"shouse_open", "openarena/oa_shouse.obj", {0.4, -1, 0.3}},
                      Case{"loinesg_city", "loinesg-city/city.obj", {0.505259, -0.379456, 0.775066}}),
    [](const auto& info) { return info.param.name; });

// The crossing order both renderers share, against its plain statement: std::sort, then
// std::stable_partition of each tie run, then the same-kind duplicates dropped.
TEST(CrossingRules, OrderEqualsThePlainStatement) {
  std::mt19937 rng(5);
  for (int trial = 0; trial < 20000; ++trial) {
    const int n = int(rng() % (trial % 50 == 0 ? 60 : 8));
    std::vector<RayHit> hits(static_cast<size_t>(n));
    for (int i = 0; i < n; ++i) {
      // Few distinct depths, so that ties and near-ties are common.
      const double t = double(rng() % 6) + (rng() % 3 == 0 ? 1e-9 * double(rng() % 3) : 0.0);
      hits[size_t(i)] = RayHit{t, uint32_t(rng() % 1000), rng() % 2 == 0, rng() % 3 != 0};
    }
    std::vector<RayHit> want = hits;
    std::sort(want.begin(), want.end(), [](const RayHit& a, const RayHit& b) {
      if (a.t != b.t) return a.t < b.t;
      if (a.front != b.front) return a.front;
      return a.triangle < b.triangle;
    });
    const double tie = 1e-8;
    for (size_t i = 0; i < want.size();) {
      size_t j = i + 1;
      while (j < want.size() && want[j].t - want[j - 1].t <= tie) ++j;
      std::stable_partition(want.begin() + ptrdiff_t(i), want.begin() + ptrdiff_t(j), [](const RayHit& h) { return h.front; });
      i = j;
    }
    std::vector<RayHit> kept;
    for (const RayHit& h : want) {
      bool dup = false;
      for (size_t j = kept.size(); j-- > 0 && std::abs(h.t - kept[j].t) <= tie;)
        dup = dup || (kept[j].front == h.front && kept[j].closed == h.closed);
      if (!dup) kept.push_back(h);
    }
    const int got = orderCrossings(hits.data(), n, tie);
    ASSERT_EQ(size_t(got), kept.size());
    for (size_t i = 0; i < kept.size(); ++i) {
      ASSERT_EQ(hits[i].t, kept[i].t);
      ASSERT_EQ(hits[i].triangle, kept[i].triangle);
      ASSERT_EQ(hits[i].front, kept[i].front);
      ASSERT_EQ(hits[i].closed, kept[i].closed);
    }
  }
}

// The column transitions (SIMD) against their plain statement, one texel at a time.
TEST(ColumnTransitions, EqualThePlainStatement) {
  std::mt19937 rng(9);
  for (int trial = 0; trial < 3000; ++trial) {
    const uint32_t R = 1u << (3 + rng() % 16);
    uint32_t lo[64], hi[64];
    const uint32_t spread = trial % 3 == 0 ? 4 : R;  // few distinct slices, or any
    for (int t = 0; t < 64; ++t) {
      lo[t] = rng() % 5 == 0 ? R : uint32_t(rng() % spread) % R;
      hi[t] = lo[t] == R ? R : std::min(R, lo[t] + (rng() % 2 ? 0 : uint32_t(rng() % spread)));
    }
    for (UndefinedRule rule : {UndefinedRule::New, UndefinedRule::Old}) {
      std::vector<uint32_t> slices, wantSlices;
      std::vector<uint64_t> masks, wantMasks;
      uint32_t first = 0, full = 0, wantFirst = R, wantFull = R;
      columnTransitions(lo, hi, R, rule, slices, masks, first, full);
      uint64_t mask = 0;
      uint32_t k = *std::min_element(hi, hi + 64);
      while (k < R) {
        uint64_t m = 0;
        for (int t = 0; t < 64; ++t) m |= uint64_t(lo[t] <= k) << t;
        if (m != mask) {
          if (mask == 0) wantFirst = k;
          wantSlices.push_back(k);
          wantMasks.push_back(m);
          mask = m;
        }
        if (mask == ~uint64_t(0)) {
          wantFull = k;
          break;
        }
        uint32_t next = R;
        for (int t = 0; t < 64; ++t)
          if (!(mask >> t & 1)) next = std::min(next, rule == UndefinedRule::New ? hi[t] : lo[t]);
        k = next;
      }
      ASSERT_EQ(slices, wantSlices);
      ASSERT_EQ(masks, wantMasks);
      ASSERT_EQ(first, wantFirst);
      ASSERT_EQ(full, wantFull);
    }
  }
}

// A column read in place from a block's rows (any stride, hi below lo read as lo) against
// the same column gathered into 64 texels, each rule, on every SIMD target compiled: and
// the aligned rule against the new rule on alignedRanges' narrowing, the scalar statement.
TEST(ColumnTransitions, AColumnOfRowsIsTheGatheredColumn) {
  for (int64_t target : hwy::SupportedAndGeneratedTargets()) {
    SCOPED_TRACE(hwy::TargetName(target));
    hwy::SetSupportedTargetsForTest(target);
    std::mt19937 rng(23);
    for (int trial = 0; trial < 3000; ++trial) {
      const uint32_t R = 1u << (3 + rng() % 16);
      const size_t stride = 8 * (1 + rng() % 6) + (trial % 2 ? 0 : 8 * (rng() % 3));
      const uint32_t base = rng() % R, spread = trial % 3 == 0 ? 12 : R;
      std::vector<uint32_t> lo(8 * stride), hi(8 * stride);
      for (size_t i = 0; i < lo.size(); ++i) {
        lo[i] = rng() % 7 == 0 ? R : std::min(R, base + uint32_t(rng() % spread)) % (R + 1);
        hi[i] = rng() % 4 == 0 ? uint32_t(rng() % (R + 1)) : std::min(R, lo[i] + uint32_t(rng() % spread));
      }
      const size_t x = 8 * (rng() % (stride / 8));
      uint32_t glo[64], ghi[64];
      for (size_t ty = 0; ty < 8; ++ty)
        for (size_t tx = 0; tx < 8; ++tx) {
          glo[ty * 8 + tx] = lo[ty * stride + x + tx];
          ghi[ty * 8 + tx] = std::max(glo[ty * 8 + tx], hi[ty * stride + x + tx]);
        }
      for (UndefinedRule rule : {UndefinedRule::New, UndefinedRule::Old, UndefinedRule::Aligned}) {
        std::vector<uint32_t> slices, wantSlices;
        std::vector<uint64_t> masks, wantMasks;
        uint32_t first = 0, full = 0, wantFirst = 1, wantFull = 1;
        columnTransitionsOfRows(lo.data() + x, hi.data() + x, stride, R, rule, slices, masks, first, full);
        if (rule == UndefinedRule::Aligned) {
          uint32_t nlo[64], nhi[64];
          alignedRanges(glo, ghi, R, nlo, nhi);
          columnTransitions(nlo, nhi, R, UndefinedRule::New, wantSlices, wantMasks, wantFirst, wantFull);
        } else {
          columnTransitions(glo, ghi, R, rule, wantSlices, wantMasks, wantFirst, wantFull);
        }
        ASSERT_EQ(slices, wantSlices) << "trial " << trial;
        ASSERT_EQ(masks, wantMasks) << "trial " << trial;
        ASSERT_EQ(first, wantFirst) << "trial " << trial;
        ASSERT_EQ(full, wantFull) << "trial " << trial;
      }
    }
  }
  hwy::SetSupportedTargetsForTest(0);
}

// The aligned rule: the new rule's plain statement on the narrowed ranges, every narrowed
// range inside its texel's own, and every 8-slice slab that all 64 texels allow lit (or
// shadowed) wholly lit (or shadowed), voxel by voxel.
TEST(ColumnTransitions, TheAlignedRuleFillsWholeSlabsInsideEachTexelsRange) {
  std::mt19937 rng(17);
  for (int trial = 0; trial < 3000; ++trial) {
    const uint32_t R = 1u << (3 + rng() % 12);
    uint32_t lo[64], hi[64];
    const uint32_t base = rng() % R, spread = trial % 3 == 0 ? 12 : R;
    for (int t = 0; t < 64; ++t) {
      lo[t] = rng() % 7 == 0 ? R : std::min(R, base + uint32_t(rng() % spread)) % (R + 1);
      hi[t] = std::min(R, lo[t] + (rng() % 3 == 0 ? 0 : uint32_t(rng() % spread)));
      if (trial % 5 == 0) hi[t] = rng() % 2 ? R : hi[t];
    }
    uint32_t nlo[64], nhi[64];
    alignedRanges(lo, hi, R, nlo, nhi);
    uint32_t maxLo = 0, minHi = R;
    for (int t = 0; t < 64; ++t) {
      ASSERT_LE(lo[t], nlo[t]);
      ASSERT_LE(nlo[t], nhi[t]);
      ASSERT_LE(nhi[t], hi[t]);
      maxLo = std::max(maxLo, lo[t]);
      minHi = std::min(minHi, hi[t]);
    }
    std::vector<uint32_t> slices, wantSlices;
    std::vector<uint64_t> masks, wantMasks;
    uint32_t first = 0, full = 0, wantFirst = 0, wantFull = 0;
    columnTransitions(lo, hi, R, UndefinedRule::Aligned, slices, masks, first, full);
    columnTransitions(nlo, nhi, R, UndefinedRule::New, wantSlices, wantMasks, wantFirst, wantFull);
    ASSERT_EQ(slices, wantSlices);
    ASSERT_EQ(masks, wantMasks);
    ASSERT_EQ(first, wantFirst);
    ASSERT_EQ(full, wantFull);
    // Voxel by voxel: each texel's constraint, and the whole slabs.
    for (uint32_t slab = 0; slab < R; slab += 8) {
      const bool allLit = slab + 8 <= minHi, allShadowed = slab >= maxLo;
      for (uint32_t k = slab; k < slab + 8; ++k) {
        uint64_t m = 0;
        for (size_t i = 0; i < slices.size() && slices[i] <= k; ++i) m = masks[i];
        for (int t = 0; t < 64; ++t) {
          const bool shadowed = m >> t & 1;
          if (k < lo[t]) ASSERT_FALSE(shadowed) << "texel " << t << " slice " << k;
          if (k >= hi[t]) ASSERT_TRUE(shadowed) << "texel " << t << " slice " << k;
        }
        if (allLit) ASSERT_EQ(m, 0u) << "slab " << slab;
        if (allShadowed && !allLit) ASSERT_EQ(m, ~uint64_t(0)) << "slab " << slab;
      }
    }
  }
}

Scene translated(Scene scene, const Vec3& by) {
  for (Vec3& p : scene.positions) p = p + by;
  return scene;
}

// Far from the world origin (1e7), with grazing and axis-aligned suns, the projection in
// double keeps the rasterizer on the brute force.
TEST(Raster, FarFromTheOriginGrazingAndAxisAlignedSuns) {
  const Scene city = translated(openScene("city:3:5"), {1e7, -3e6, 2e7});
  for (Vec3 sun : {Vec3{0, -1, 0}, Vec3{1, 0, 0}, Vec3{0.999, -0.04, 0.02}, Vec3{0.3, -0.02, -1}, Vec3{1e-9, -1, 1e-9}}) {
    const OrthoGrid grid = makeGrid(city, LightFrame::fromDirection(sun), 6);
    for (ExitMode exit : {ExitMode::Exact, ExitMode::Approx}) {
      const Comparison c = compareWithBruteForce(city, grid, ClosedMode::Auto, exit, "far city");
      EXPECT_EQ(c.mismatches, 0u) << sun.x << "," << sun.y << "," << sun.z;
      EXPECT_GT(c.hit, 64u * 64u / 20u);
      EXPECT_LT(c.ambiguous, 64u * 64u / 10u);
    }
  }
}

// A grid that shows only part of the scene: triangles reaching far outside it are
// clipped to the guard band, and what the grid shows is unchanged.
TEST(Raster, TrianglesFarOutsideTheGridAreClipped) {
  const Scene city = openScene("city:4:7");
  OrthoGrid grid = makeGrid(city, LightFrame::fromDirection({0.35, -1, 0.25}), 6);
  // Zoom into the middle: the ground and many buildings now span several grid widths.
  grid.u0 += grid.extent * 0.45;
  grid.v0 += grid.extent * 0.45;
  grid.extent *= 0.01;
  const Comparison c = compareWithBruteForce(city, grid, ClosedMode::Auto, ExitMode::Exact, "zoomed city");
  EXPECT_EQ(c.mismatches, 0u);
  EXPECT_EQ(c.hit, 64u * 64u) << "the ground covers the whole zoomed grid";
}

// Exactly once: on a mesh whose vertices lie on texel centres (so centres fall on edges
// and vertices everywhere), every covered centre belongs to exactly one triangle.
TEST(Raster, SharedEdgesAndVerticesCoverACentreExactlyOnce) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 4; ++trial) {
    // A height field seen from above: an 8 x 8 grid of quads, split along random diagonals,
    // its vertices jittered only in height, so they project onto texel centres.
    Scene s;
    const int n = 8;
    std::uniform_real_distribution<double> height(0, 0.3);
    for (int j = 0; j <= n; ++j)
      for (int i = 0; i <= n; ++i) s.positions.push_back({double(i), height(rng), double(j)});
    for (int j = 0; j < n; ++j)
      for (int i = 0; i < n; ++i) {
        const uint32_t a = uint32_t(j * (n + 1) + i), b = a + 1, c = a + uint32_t(n + 1), d = c + 1;
        if (rng() % 2) {
          s.indices.insert(s.indices.end(), {a, c, b, b, c, d});
        } else {
          s.indices.insert(s.indices.end(), {a, c, d, a, d, b});
        }
      }
    finalizeScene(s);
    OrthoGrid grid = makeGrid(s, LightFrame::fromDirection({0, -1, 0}), 6);
    // Put texel centres exactly on the mesh's vertices: 4 texels per quad, offset by half.
    grid.extent = 16.0;
    grid.u0 = std::floor(grid.u0) - 0.125 - 4;
    grid.v0 = std::floor(grid.v0) - 0.125 - 4;
    RasterScene raster(s, grid);
    uint64_t once = 0, twice = 0;
    for (uint64_t y = 0; y < 64; ++y)
      for (uint64_t x = 0; x < 64; ++x) {
        int count = 0;
        for (uint32_t t = 0; t < raster.triangles().size(); ++t) count += raster.covers(t, x, y);
        once += count == 1;
        twice += count > 1;
      }
    EXPECT_EQ(twice, 0u);
    EXPECT_GT(once, 500u);
    // And the block kernel covers exactly the texels the one-texel test does.
    TexelSlices got;
    rasterTexelSlices(raster, ClosedMode::Off, ExitMode::Exact, 0, 0, 64, 64, got);
    for (uint64_t y = 0; y < 64; ++y)
      for (uint64_t x = 0; x < 64; ++x) {
        bool covered = false;
        for (uint32_t t = 0; t < raster.triangles().size(); ++t) covered = covered || raster.covers(t, x, y);
        ASSERT_EQ(got.firstUndefined[y * 64 + x] < 64, covered) << x << "," << y;
      }
  }
}

// The empty-tile test is conservative: a tile it calls untouched renders to no hit in
// both renderers, and on a scene with empty corners it finds some.
TEST(Raster, UntouchedTilesHaveNoHit) {
  Scene s;
  appendBox(s, {0, 0, 0}, {1, 1, 1});
  appendBox(s, {3, 0, 3}, {4, 2, 4});
  finalizeScene(s);
  const OrthoGrid grid = makeGrid(s, LightFrame::fromDirection({0.2, -1, 0.1}), 8);
  RasterScene raster(s, grid);
  RayScene rays(s, grid.origin);
  uint64_t untouched = 0, touched = 0;
  for (uint32_t ty = 0; ty < 256; ty += 32)
    for (uint32_t tx = 0; tx < 256; tx += 32) {
      TexelSlices a, b;
      rasterTexelSlices(raster, ClosedMode::Auto, ExitMode::Exact, tx, ty, 32, 32, a);
      renderTexelSlices(rays, grid, ClosedMode::Auto, ExitMode::Exact, tx, ty, 32, 32, b);
      const bool anyHit = std::any_of(a.firstUndefined.begin(), a.firstUndefined.end(), [](uint32_t v) { return v < 256; }) ||
                          std::any_of(b.firstUndefined.begin(), b.firstUndefined.end(), [](uint32_t v) { return v < 256; });
      if (raster.touchesRectangle(tx, ty, 32, 32)) {
        ++touched;
      } else {
        ++untouched;
        EXPECT_FALSE(anyHit) << "tile " << tx << "," << ty;
      }
    }
  EXPECT_GT(untouched, 10u);
  EXPECT_GT(touched, 10u);
}

}  // namespace
}  // namespace cpvs
