// The bake's ETA: TileEta fits a tile's seconds to a fixed part and a part per triangle
// and predicts the tiles left exactly when costs follow that law; noise that would make
// either part negative is clamped; tiles no triangle reaches cost nothing; tileWork
// counts a real scene's triangles per tile; bakeGrid reports the estimate; the plan's
// estimate samples the bake's own tiles.
#include <gtest/gtest.h>

#include <algorithm>
#include <numeric>
#include <random>

#include "cpvs/bake/bake.h"
#include "cpvs/bake/bake_estimate.h"
#include "cpvs/bake/bake_scene.h"
#include "cpvs/bake/tile_eta.h"
#include "cpvs/light/ortho_grid.h"
#include "cpvs/scene/procedural_city.h"
#include "scene_testing.h"

namespace cpvs {
namespace {

TEST(TileEta, PredictsTheTilesLeftWhenCostsFollowTheLaw) {
  std::mt19937 rng(3);
  std::uniform_int_distribution<uint32_t> triangles(0, 5000);
  std::vector<uint32_t> work(400);
  for (uint32_t& w : work) w = rng() % 4 == 0 ? 0 : triangles(rng);  // a quarter untouched
  auto cost = [](uint32_t w) { return w == 0 ? 0.0 : 0.02 + 3e-5 * w; };
  TileEta eta(work);
  EXPECT_LT(eta.secondsLeft(), 0) << "nothing to fit yet";
  double left = 0;
  for (uint32_t w : work) left += cost(w);
  std::vector<size_t> order(work.size());
  std::iota(order.begin(), order.end(), 0);
  std::shuffle(order.begin(), order.end(), rng);
  size_t withWork = 0;
  for (size_t k = 0; k < order.size(); ++k) {
    const size_t tile = order[k];
    eta.finished(tile, cost(work[tile]));
    left -= cost(work[tile]);
    withWork += work[tile] > 0;
    if (withWork < 2) {
      EXPECT_LT(eta.secondsLeft(), 0);
      continue;
    }
    // Two distinct triangle counts pin the law down.
    EXPECT_NEAR(eta.secondsLeft(), std::max(left, 0.0), 1e-9 * (1 + left)) << "after " << k + 1 << " tiles";
  }
  EXPECT_NEAR(eta.fixedSeconds(), 0.02, 1e-12);
  EXPECT_NEAR(eta.secondsPerTriangle(), 3e-5, 1e-15);
  EXPECT_EQ(eta.secondsLeft(), 0);
}

// The case the count of tiles gets wrong: the first tiles hold few triangles, the last
// many. Counting tiles, half the tiles done says half the time is left; weighing them,
// nearly all of it.
TEST(TileEta, WeighsTheExpensiveTilesStillToCome) {
  std::vector<uint32_t> work;
  for (int i = 0; i < 50; ++i) work.push_back(10 + i);
  for (int i = 0; i < 50; ++i) work.push_back(10000 + i);
  auto cost = [](uint32_t w) { return 0.001 + 1e-4 * w; };
  TileEta eta(work);
  double spent = 0, left = 0;
  for (int i = 0; i < 50; ++i) {
    eta.finished(size_t(i), cost(work[size_t(i)]));
    spent += cost(work[size_t(i)]);
  }
  for (int i = 50; i < 100; ++i) left += cost(work[size_t(i)]);
  const double byCount = spent;  // half the tiles done: as long again
  EXPECT_NEAR(eta.secondsLeft(), left, 1e-9 * left);
  EXPECT_GT(left, 50 * byCount);
}

TEST(TileEta, ClampsANegativePart) {
  // More triangles, less time (noise): no part per triangle, the mean as the fixed part.
  TileEta slower({1, 10, 7});
  slower.finished(0, 2.0);
  slower.finished(1, 1.0);
  EXPECT_EQ(slower.secondsPerTriangle(), 0);
  EXPECT_DOUBLE_EQ(slower.fixedSeconds(), 1.5);
  EXPECT_DOUBLE_EQ(slower.secondsLeft(), 1.5);
  // A line through below zero: no fixed part, the slope through the origin.
  TileEta steep({10, 20, 30});
  steep.finished(0, 0.5);
  steep.finished(1, 2.0);
  EXPECT_EQ(steep.fixedSeconds(), 0);
  EXPECT_DOUBLE_EQ(steep.secondsPerTriangle(), (10 * 0.5 + 20 * 2.0) / (100.0 + 400.0));
  EXPECT_DOUBLE_EQ(steep.secondsLeft(), 30 * steep.secondsPerTriangle());
  // Equal triangle counts: a fixed cost, their mean.
  TileEta flat({5, 5, 5, 5, 0});
  flat.finished(0, 1.0);
  flat.finished(4, 99.0);  // a tile without work is no sample
  flat.finished(1, 3.0);
  EXPECT_DOUBLE_EQ(flat.secondsLeft(), 2 * 2.0);
}

// Against a brute count: a tile's work is the triangles whose projection reaches it (at
// least 1 when it is rendered), 0 where nothing is.
TEST(TileEta, TileWorkCountsTheTrianglesOfEachTile) {
  const Scene city = makeProceduralCity(4, 2);
  const OrthoGrid grid = makeGrid(city, LightFrame::fromDirection({0.3, -1, 0.2}), 10);
  const BakeScene scene(city, grid, Renderer::Raster);
  const TilePlan plan(10, 7);
  const std::vector<uint32_t> work = tileWork(scene, plan);
  ASSERT_EQ(work.size(), plan.count());
  size_t rendered = 0;
  const uint64_t T = 128;
  for (uint64_t i = 0; i < plan.count(); ++i) {
    const TileCoord tile = plan.tile(i);
    const bool touched = scene.touchesTile(tile.x, tile.y, 7);
    EXPECT_EQ(work[i] > 0, touched) << i;
    rendered += touched;
    if (!touched) continue;
    // Every triangle that covers a texel centre of the tile is among those counted.
    std::vector<uint32_t> listed;
    scene.raster().trianglesTouching(tile.x * T, tile.y * T, T, T, listed);
    EXPECT_EQ(work[i], std::max<uint32_t>(uint32_t(listed.size()), 1));
    for (uint32_t t = 0; t < scene.raster().triangles().size(); ++t) {
      bool covers = false;
      for (uint64_t y = tile.y * T; y < (tile.y + 1) * T && !covers; y += 3)
        for (uint64_t x = tile.x * T; x < (tile.x + 1) * T && !covers; x += 3) covers = scene.raster().covers(t, x, y);
      if (covers) EXPECT_TRUE(std::binary_search(listed.begin(), listed.end(), t)) << "tile " << i << ", triangle " << t;
    }
  }
  EXPECT_GT(rendered, 0u);
  EXPECT_LT(rendered, plan.count()) << "the city leaves some tiles untouched";
}

/// The procedural city on a 512³ grid in 64 tiles of 64².
struct SmallCity {
  Scene city = makeProceduralCity(4, 2);
  OrthoGrid grid = makeGrid(city, LightFrame::fromDirection({0.3, -1, 0.2}), 9);
  BakeScene scene{city, grid, Renderer::Raster};
  BakeOptions options = [] {
    BakeOptions o;
    o.log2TileSize = 6;
    return o;
  }();
};

// bakeGrid reports the estimate: unknown at first, then known, and nothing left at the end.
TEST(TileEta, TheBakeReportsSecondsLeft) {
  const SmallCity city;
  const BakeScene& scene = city.scene;
  const BakeOptions& options = city.options;
  std::vector<Progress> reports;
  (void)bakeGrid(scene, options, nullptr, [&](const Progress& p) {
    reports.push_back(p);
    return true;
  });
  ASSERT_EQ(reports.size(), TilePlan(9, 6).count() + 1);
  EXPECT_LT(reports.front().secondsLeft, 0);
  EXPECT_GE(reports[reports.size() / 2].secondsLeft, 0);
  EXPECT_EQ(reports.back().secondsLeft, 0);
  EXPECT_EQ(reports.back().done, reports.back().total);
}

// The plan's estimate bakes a quarter of the tiles to render (3 to 8) and prices every
// tile; asked to sample every tile, its bytes are exactly the sub-DAGs' sum.
TEST(BakeEstimate, SamplesTheBakesOwnTilesAndPricesEveryTile) {
  const SmallCity city;
  const BakeScene& scene = city.scene;
  const BakeOptions& options = city.options;
  const TilePlan plan(9, 6);
  const std::vector<uint32_t> work = tileWork(scene, plan);
  const uint64_t rendered = uint64_t(std::count_if(work.begin(), work.end(), [](uint32_t w) { return w > 0; }));
  ASSERT_GT(rendered, 12u);
  ASSERT_LT(rendered, plan.count());
  const BakeEstimate e = estimateBake(scene, options);
  EXPECT_EQ(e.tiles, plan.count());
  EXPECT_EQ(e.renderedTiles, rendered);
  EXPECT_EQ(e.sampledTiles, std::clamp<uint64_t>(rendered / 4, 3, 8));
  EXPECT_GT(e.tileSeconds, 0);
  const Dag dag = bakeGrid(scene, options);
  EXPECT_GT(e.dagBytes, 0.3 * double(dag.bytes()));
  EXPECT_LT(e.dagBytes, 3.0 * double(dag.bytes()));

  const BakeEstimate all = estimateBake(scene, options, 1000);
  EXPECT_EQ(all.sampledTiles, rendered);
  double sum = 0;
  for (uint64_t i = 0; i < plan.count(); ++i)
    if (work[i] > 0) sum += double(bakeTile(scene, plan.tile(i).x, plan.tile(i).y, options).bytes());
  EXPECT_NEAR(all.dagBytes, sum, 1e-9 * sum);
}

}  // namespace
}  // namespace cpvs
